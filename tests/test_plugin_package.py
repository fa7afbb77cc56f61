"""docs/extending.md's plugin, copied into a fresh package outside the repository, built and
installed into a temporary directory, is found through its entry point by a new process and
simulates like the shipped `friction-block` plugin.

It is installed with pip (`--target`, no dependencies, no build isolation: the build uses
this environment's setuptools, from the `test` extra) into a directory that the new process
puts on its path, as an installation into a virtual environment would; nothing of the
repository is on that path but the installed stickslip itself.
"""

from __future__ import annotations

import json
import os
import pathlib
import re
import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.early  # (a package build and a new process: 8-10 s)

ROOT = pathlib.Path(__file__).resolve().parents[1]

PYPROJECT = """\
[build-system]
requires = ["setuptools>=70.1"]
build-backend = "setuptools.build_meta"

[project]
name = "docs-friction-block"
version = "0.0.1"
dependencies = ["stickslip"]

[project.entry-points."stickslip.models"]
docs-friction-block = "docs_friction_block:FrictionBlock"

[tool.setuptools]
packages = ["docs_friction_block"]
"""

RUN = """
import json
import numpy as np
import stickslip as ss

Copied = ss.get_model("docs-friction-block")
law = {"F0": 1.0, "alpha": 1.0, "sigma": 0.2}
ours = Copied(1.0, 0.5, 0.01, 0.1, "velocity-weakening", law)
shipped = ss.get_model("friction-block")(1.0, 0.5, 0.01, 0.1, "velocity-weakening", law)
a = ss.simulate(ours, 300, 0.01, 30.0, seed=4)
b = ss.simulate(shipped, 300, 0.01, 30.0, seed=4)
print(json.dumps({
    "module": type(ours).__module__,
    "stuck": float(a.fraction_stuck),
    "slip_time": np.nan_to_num(a.slip_time).tolist(),
    "shipped": np.nan_to_num(b.slip_time).tolist(),
}))
"""


def test_the_documented_plugin_installs_and_runs_as_a_package(tmp_path):
    blocks = re.findall(r"^```python\n(.*?)^```", (ROOT / "docs" / "extending.md").read_text(),
                        re.S | re.M)  # fmt: skip
    source = blocks[0]  # the model class, as the page writes it
    assert "class FrictionBlock(ss.FrictionModel)" in source
    package = tmp_path / "src"
    (package / "docs_friction_block").mkdir(parents=True)
    (package / "docs_friction_block" / "__init__.py").write_text(textwrap.dedent(source))
    (package / "pyproject.toml").write_text(PYPROJECT)
    site = tmp_path / "site"
    built = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
         "--disable-pip-version-check", "--target", str(site), str(package)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert built.returncode == 0, built.stderr[-2000:]
    assert (site / "docs_friction_block" / "__init__.py").exists()
    env = dict(os.environ, PYTHONPATH=str(site))
    out = subprocess.run(
        [sys.executable, "-c", RUN], env=env, cwd=tmp_path, capture_output=True, text=True,
        timeout=600,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["module"] == "docs_friction_block"  # the installed copy, not the shipped one
    assert result["stuck"] == 1.0
    # The page's class and the shipped plugin are the same model: same noise, same slips.
    assert result["slip_time"] == result["shipped"]
