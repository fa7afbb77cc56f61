"""Every Python code block in the README and the docs runs (blocks of one file share a
namespace, in order)."""

import pathlib
import re
import warnings

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
# docs/tutorial.md runs in tests/test_tutorial.py, with its command lines between its blocks.
FILES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FILES = [p for p in FILES if p.name != "tutorial.md"]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
BLOCK_BASH = re.compile(r"^```bash\n(.*?)^```", re.S | re.M)


# Pages whose blocks start a Dask cluster (worker processes that each compile the simulator
# on a cold cache: 16 s of the default tier) run in the slow tier; tests/test_distributed.py
# runs a cluster in the default one. So do the pages whose examples take 7-12 s each from an
# empty cache (the estimator, the models, fitting and model choice: what they call is tested
# in the default tier by their own test files); the README's run in the default tier. And
# (5-7 s each cold) extending.md and goodness.md: tests/test_plugin_package.py and
# tests/test_goodness.py run what they show in the default tier; rate_and_state.md (its
# compiled solve, 8 s cold): tests/test_rate_and_state.py runs it. runs.md reads the whole
# public grid (7-13 s): tests/test_analyse_run.py and tests/test_campaign.py run its parts.
SLOW = {"distributed.md", "estimator.md", "models.md", "compare.md", "fit.md", "extending.md",
        "goodness.md", "rate_and_state.md", "runs.md"}  # fmt: skip


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
    if path.name == "README.md":
        blocks = [b for b in blocks if not _from_the_tutorial(b)]
    namespace: dict = {}
    from stickslip import _registry, _trace_kind

    registered = [(r, dict(r.runtime)) for r in (_registry.MODELS, _trace_kind.TRACE_KINDS)]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # approximation warnings are documented in the text
            for block in blocks:
                exec(compile(block, f"{path.name}", "exec"), namespace)
    finally:  # what a page registers for its examples is its own
        for registry, before in registered:
            registry.runtime.clear()
            registry.runtime.update(before)


# The README's trace-to-model block reads the cycles that its `stickslip cycles` line writes
# and fits through the measurement (minutes): it is made of docs/tutorial.md's lines, which
# tests/test_tutorial.py runs (the fit in the slow tier), and is checked to stay so.
def _from_the_tutorial(block: str) -> bool:
    return 'ss.read_cycles("cycles.csv")' in block


def _statements(code: str) -> list[str]:
    """The code's lines, comments and surrounding blanks dropped."""
    lines = (line.split("  #")[0].rstrip() for line in code.splitlines())
    return [line for line in lines if line.strip() and not line.lstrip().startswith("#")]


def test_the_readmes_trace_block_is_the_tutorials():
    readme = [b for b in BLOCK.findall((ROOT / "README.md").read_text()) if _from_the_tutorial(b)]
    assert len(readme) == 1
    tutorial = "\n".join(BLOCK.findall((ROOT / "docs" / "tutorial.md").read_text()))
    ours = set(_statements(tutorial))
    missing = [line for line in _statements(readme[0]) if line not in ours]
    assert not missing, f"README lines that docs/tutorial.md does not run: {missing}"


def test_the_readme_is_a_users_manual():
    """At most 160 lines, no dated measurements or machine names (they live in
    docs/performance.md and the lab notebook), and the install and test commands that
    .ci/run runs."""
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 160
    assert not re.search(r"\b20\d\d-\d\d-\d\d\b", text)
    for machine in ("Zen", "EPYC", "Xeon", "H200"):
        assert machine not in text, machine
    commands = BLOCK_BASH.findall(text)[0].splitlines()
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    for readme_line, ci_line in (('pip install -e ".[test]"', 'pip install -e ".[test]"'),
                                 ("pytest", "pytest")):  # fmt: skip
        assert any(line.startswith(readme_line) for line in commands), readme_line
        assert ci_line in ci, ci_line
