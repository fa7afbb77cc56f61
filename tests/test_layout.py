"""The code's layout holds: no module reaches into another's private names, and no
function outside the compiled kernels runs past 100 lines of code (`benchmarks/layout.py`
counts both; docs/architecture.md says where things live)."""

from __future__ import annotations

import importlib.util
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("layout", ROOT / "benchmarks" / "layout.py")
layout = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(layout)


def test_no_module_uses_another_modules_private_names():
    uses = layout.private_uses()
    shown = {f"{m}.{n}": sorted(p.name for p in where) for (m, n), where in uses.items()}
    assert not uses, shown


def test_no_long_functions_outside_the_kernels():
    longs = [f"{rel}:{name} ({code} lines)" for code, _, rel, name, kernel
             in layout.long_functions() if not kernel]  # fmt: skip
    assert not longs, longs


def test_the_counter_sees_a_reach_and_a_long_function(tmp_path, monkeypatch):
    """The counts are not vacuous: a module that imports another's private name, and a
    function of 101 lines, are found."""
    pkg = tmp_path / "src" / "stickslip"
    pkg.mkdir(parents=True)
    (tmp_path / "plugins").mkdir()
    (pkg / "a.py").write_text("def _inner():\n    return 1\n")
    body = "\n".join(f"    x{i} = {i}" for i in range(100))
    (pkg / "b.py").write_text(f"from .a import _inner\n\n\ndef long():\n{body}\n")
    monkeypatch.setattr(layout, "SRC", pkg)
    monkeypatch.setattr(layout, "ROOT", tmp_path)
    assert set(layout.private_uses()) == {("a", "_inner")}
    assert [f[3] for f in layout.long_functions()] == ["long"]
