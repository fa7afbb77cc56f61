"""The code base passes `ruff check` (configured in pyproject.toml)."""

import pathlib
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_ruff_check():
    ruff = shutil.which("ruff") or shutil.which(
        "ruff", path=str(pathlib.Path(sys.executable).parent)
    )
    if ruff is None:
        pytest.skip("ruff is not installed (it comes with the 'test' extra)")
    dirs = [str(ROOT / d) for d in ("src", "plugins", "tests", "benchmarks", "examples")]
    out = subprocess.run(
        [ruff, "check", "--output-format", "concise", *dirs], capture_output=True, text=True
    )
    assert out.returncode == 0, out.stdout + out.stderr
