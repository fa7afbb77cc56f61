"""`stickslip cycles`: the bad inputs of issue 42 and the force/.mat path of issue 39."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from conftest import run_cli

import stickslip as ss


def _cli(*args, cwd):
    return run_cli("cycles", *args, cwd=cwd)


def _sine_csv(path, offset=0.0, bom=False):
    t = np.arange(0.0, 10.0, 0.01)
    v = 1.0 - np.maximum(0.0, np.sin(np.pi * t))
    lines = ["t,v"] + [f"{a + offset:.17g},{b:.17g}" for a, b in zip(t, v, strict=True)]
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + ("\n".join(lines) + "\n").encode())


def _one_line(done):
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].isprintable() and len(lines[0]) < 400, lines
    return lines[0]


def test_binary_trace_is_one_line(tmp_path):
    (tmp_path / "bin.csv").write_bytes(bytes(range(256)) * 4 + "t,v\xe9".encode("latin-1"))
    line = _one_line(_cli("bin.csv", "--v-b", "1", cwd=tmp_path))
    assert "UTF-8" in line and "\\x" not in line


def test_two_x_columns_are_refused(tmp_path):
    (tmp_path / "two.csv").write_text("t,x,x\n0,0,0\n1,1,1\n2,2,2\n")
    assert "more than once" in _one_line(_cli("two.csv", "--v-b", "1", cwd=tmp_path))


def test_bom_and_negative_times_are_accepted(tmp_path):
    _sine_csv(tmp_path / "bom.csv", offset=-5.0, bom=True)
    done = _cli("bom.csv", "--v-b", "1", "--out", "c.csv", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    found = ss.Cycles.from_csv(tmp_path / "c.csv")
    assert len(found) == 3 and found["release_time"][0] == pytest.approx(-3.0, abs=0.01)


def test_out_never_overwrites_the_trace_and_needs_force(tmp_path):
    _sine_csv(tmp_path / "trace.csv")
    before = (tmp_path / "trace.csv").read_bytes()
    for extra in ((), ("--force",)):
        line = _one_line(_cli("trace.csv", "--v-b", "1", "--out", "trace.csv", *extra,
                              cwd=tmp_path))  # fmt: skip
        assert "input" in line
    assert (tmp_path / "trace.csv").read_bytes() == before
    (tmp_path / "mine.csv").write_text("keep me\n")
    assert "--force" in _one_line(_cli("trace.csv", "--v-b", "1", "--out", "mine.csv",
                                       cwd=tmp_path))  # fmt: skip
    assert (tmp_path / "mine.csv").read_text() == "keep me\n"
    done = _cli("trace.csv", "--v-b", "1", "--out", "mine.csv", "--force", cwd=tmp_path)
    assert done.returncode == 0 and len(ss.Cycles.from_csv(tmp_path / "mine.csv")) == 3


def test_force_trace_from_mat_with_figure(tmp_path):
    from scipy.io import savemat

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from _force_traces import Rig, make_trace

    rig = Rig()
    t, force, truth = make_trace(21, duration=20.0, rig=rig)
    mg = 0.0307 * 9.81
    savemat(tmp_path / "run.mat", {"t": t[:, None], "Fnorm": (force / mg)[:, None]})
    args = ["run.mat", "--force-column", "Fnorm", "--force-scale", repr(mg), "--stiffness",
            "168", "--v-b", "42e-6", "--out", "c.csv"]  # fmt: skip
    done = _cli(*args, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    found = ss.Cycles.from_csv(tmp_path / "c.csv")
    assert found.info["force_column"] == "Fnorm" and found.info["stiffness"] == 168.0
    assert abs(len(found) - (truth["release"].size - 2)) <= 2
    assert (tmp_path / "c.png").stat().st_size > 1000
    # no stiffness: one line
    assert "--stiffness" in _one_line(_cli(*args[:5], "--out", "d.csv", cwd=tmp_path))
