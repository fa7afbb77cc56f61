"""The slips' shape fit is compiled once and kept on disk; a damaged copy there is compiled
again with a warning, never a crash (three processes, each compiling or loading it)."""

import os
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]

SCRIPT = """
import warnings
import numpy as np
from stickslip._extract import _force

rng = np.random.default_rng(0)
y = np.r_[np.zeros(60), -np.ones(60)] + 0.01 * rng.standard_normal(120)
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    fit = _force._fit_slips(y, np.array([55]), np.array([65]), np.array([0]), np.array([119]),
                            5, np.array([1.0]), 0.01)
print("warned" if any("could not be read" in str(w.message) for w in caught) else "quiet")
print(f"{fit[0, 0]:.6f} {fit[0, 0] + fit[0, 1]:.6f} {fit[0, 3]:.6f}")
"""


@pytest.mark.slow
def test_a_damaged_cache_is_compiled_again(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}

    def run():
        out = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True,
                             text=True, cwd=ROOT, timeout=300)  # fmt: skip
        assert out.returncode == 0, out.stderr
        return out.stdout.split("\n")

    first = run()
    # the step from 0 to -1 lies between samples 59 and 60; its drop is 1
    release, stick, drop = map(float, first[1].split())
    assert first[0] == "quiet" and 58.5 <= release < stick <= 60.5 and abs(drop - 1) < 0.01
    cached = list(tmp_path.rglob("*.nbc"))
    assert cached, "nothing was cached"
    for path in cached:
        path.write_bytes(path.read_bytes()[:100])
    assert run()[:2] == ["warned", first[1]]
    assert run()[:2] == ["quiet", first[1]]  # healed
