"""Every Python code block in the README and the docs runs (blocks of one file share a
namespace, in order)."""

import pathlib
import re
import warnings

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
FILES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


# Pages whose blocks start a Dask cluster (worker processes that each compile the simulator
# on a cold cache: 16 s of the default tier) run in the slow tier; tests/test_distributed.py
# runs a cluster in the default one. So do the pages whose examples take 7-12 s each from an
# empty cache (the estimator, the models, fitting and model choice: what they call is tested
# in the default tier by their own test files); the README's run in the default tier. And
# (5-7 s each cold) extending.md and goodness.md: tests/test_plugin_package.py and
# tests/test_goodness.py run what they show in the default tier.
SLOW = {"distributed.md", "estimator.md", "models.md", "compare.md", "fit.md", "extending.md",
        "goodness.md"}  # fmt: skip


@pytest.mark.parametrize(
    "path",
    [pytest.param(p, marks=pytest.mark.slow) if p.name in SLOW else p for p in FILES],
    ids=[p.name for p in FILES],
)
def test_code_blocks_run(path, tmp_path, monkeypatch):
    """Run in a scratch folder (a block may write, e.g. `cycles.to_csv("cycles.csv")`), with
    the repository's folders linked in for the paths the docs use (`examples/data/...`)."""
    for name in ("examples", "docs", "tests"):
        (tmp_path / name).symlink_to(ROOT / name, target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    blocks = BLOCK.findall(path.read_text())
    namespace: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # approximation warnings are documented in the text
        for block in blocks:
            exec(compile(block, f"{path.name}", "exec"), namespace)
