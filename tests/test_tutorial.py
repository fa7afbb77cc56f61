"""docs/tutorial.md runs as written: its Python blocks in one namespace and its command lines
(`bash` blocks), in order, in a scratch folder. The steps before the fit (the trace, the
cycles from the command line, the units: a few seconds) run in the default tier; the whole
page, fit and verdict included (a few minutes), in the slow tier."""

from __future__ import annotations

import pathlib
import re
import shlex
import warnings

import pytest
from conftest import run_cli

ROOT = pathlib.Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "tutorial.md"
BLOCK = re.compile(r"^```(python|bash)\n(.*?)^```", re.S | re.M)


def _blocks() -> list[tuple[str, str]]:
    return BLOCK.findall(PAGE.read_text(encoding="utf-8"))


def _run(blocks, tmp_path, monkeypatch) -> dict:
    (tmp_path / "examples").symlink_to(ROOT / "examples", target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for kind, code in blocks:
        if kind == "python":
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the page's warnings are said in its text
                exec(compile(code, PAGE.name, "exec"), namespace)
            continue
        for line in code.splitlines():
            words = shlex.split(line, comments=True)
            if not words:
                continue
            assert words[0] == "stickslip", f"not a stickslip command: {line}"
            done = run_cli(*words[1:], cwd=tmp_path)
            assert done.returncode == 0, f"{line}: {done.stderr}"
    return namespace


def test_the_steps_before_the_fit(tmp_path, monkeypatch):
    blocks = _blocks()
    first_fit = next(i for i, (_, code) in enumerate(blocks) if "ss.fit(" in code)
    assert any(kind == "bash" for kind, _ in blocks[:first_fit])
    ns = _run(blocks[:first_fit], tmp_path, monkeypatch)
    assert (tmp_path / "cycles.csv").is_file() and (tmp_path / "cycles.png").is_file()
    assert len(ns["cycles"]) > 50
    slider = ns["slider"]
    assert slider.stiffness == 168.0 and slider.v_b > 42e-6  # the sticks' measured slope
    assert slider.dimensionless()["x0"] == 1.0


@pytest.mark.slow  # a fit of two parameters through the measurement and its check: minutes
def test_the_whole_page(tmp_path, monkeypatch):
    ns = _run(_blocks(), tmp_path, monkeypatch)
    r = ns["r"]
    assert set(r.estimate) == {"omega0", "D"}
    assert set(r.p_values) >= {"slip_time", "stick_time", "slip_distance", "joint"}
    rows = ns["slider"].si_table(r)
    assert {row["parameter"] for row in rows} == {"omega0", "D"}
