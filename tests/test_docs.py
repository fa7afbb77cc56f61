"""Every Python code block in the README and the docs runs (blocks of one file share a
namespace, in order)."""

import pathlib
import re
import warnings

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
FILES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_code_blocks_run(path):
    blocks = BLOCK.findall(path.read_text())
    namespace: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # approximation warnings are documented in the text
        for block in blocks:
            exec(compile(block, f"{path.name}", "exec"), namespace)
