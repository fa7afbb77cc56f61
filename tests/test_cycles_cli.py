"""`stickslip cycles`: the bad inputs of issue 42 and the force/.mat path of issue 39."""

from __future__ import annotations

import os
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


FORCE_ARGS = ["--force-column", "F", "--stiffness", "168", "--v-b", "42e-6"]


def test_the_figure_never_replaces_the_table_or_the_users_file(tmp_path):
    """`--out tbl.png` wrote the figure over the table it had just reported; `--out
    u/trace.txt --force` replaced the user's own `u/trace.png`. Both are refused before
    anything is read, and the files stay as they were."""
    (tmp_path / "trace.csv").write_text("t,F\n0,1\n")
    line = _one_line(_cli("trace.csv", *FORCE_ARGS, "--out", "tbl.png", cwd=tmp_path))
    assert "both the table and its figure" in line
    assert not (tmp_path / "tbl.png").exists()
    (tmp_path / "u").mkdir()
    (tmp_path / "u" / "trace.png").write_bytes(b"\x89PNG my photo")
    for force in ((), ("--force",)):
        line = _one_line(_cli("trace.csv", *FORCE_ARGS, "--out", "u/trace.txt", *force,
                              cwd=tmp_path))  # fmt: skip
        assert "did not write" in line and "u/trace.png" in line
    assert (tmp_path / "u" / "trace.png").read_bytes() == b"\x89PNG my photo"
    assert not (tmp_path / "u" / "trace.txt").exists()


def test_options_for_the_other_kind_of_trace_are_refused(tmp_path):
    """`--tol` with a force column and `--stiffness` with an x/v trace were ignored."""
    _sine_csv(tmp_path / "trace.csv")
    line = _one_line(_cli("trace.csv", *FORCE_ARGS, "--tol", "0.1", cwd=tmp_path))
    assert line.startswith("error: --tol") and "x/v trace only" in line
    line = _one_line(_cli("trace.csv", "--v-b", "1", "--stiffness", "168", cwd=tmp_path))
    assert line.startswith("error: --stiffness") and "--force-column only" in line
    line = _one_line(_cli("trace.csv", "--v-b", "1", "--force-scale", "2", cwd=tmp_path))
    assert line.startswith("error: --force-scale")


def test_a_fifo_and_a_v73_mat_file_are_named_as_such(tmp_path):
    """A FIFO was "no such file"; a MATLAB v7.3 file (HDF5) was not named as such, whatever
    its name."""
    os.mkfifo(tmp_path / "pipe.csv")
    assert "not a regular file" in _one_line(_cli("pipe.csv", "--v-b", "1", cwd=tmp_path))
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64".ljust(512, b" ")
    for name in ("run.mat", "run.csv"):
        (tmp_path / name).write_bytes(header + b"\x89HDF\r\n\x1a\n" + bytes(200))
        assert "MATLAB v7.3 (HDF5)" in _one_line(_cli(name, "--v-b", "1", cwd=tmp_path))


def test_a_csv_past_the_memory_limit_is_refused(tmp_path, monkeypatch):
    """The reader had no memory check (5 M rows peaked at 1.55 GB): the rows are counted
    first and a trace past `STICKSLIP_MEMORY_LIMIT` is one line."""
    rows = 4_000_000
    (tmp_path / "big.csv").write_bytes(b"t,v\n" + b"0,1\n" * rows)
    monkeypatch.setenv("STICKSLIP_MEMORY_LIMIT", "5e7")
    line = _one_line(_cli("big.csv", "--v-b", "1", cwd=tmp_path))
    assert f"{rows} rows of 2 values" in line and "STICKSLIP_MEMORY_LIMIT" in line


def test_csv_errors_name_the_place(tmp_path):
    (tmp_path / "nan.csv").write_text("# note\n\nt,v\n0,1\n1,abc\n")
    assert "not a number (data row 2, column 2)" in _one_line(_cli("nan.csv", "--v-b", "1",
                                                             cwd=tmp_path))  # fmt: skip
    (tmp_path / "ragged.csv").write_text("t,v\n0,1\n1\n")
    assert "rows must have 2 values" in _one_line(_cli("ragged.csv", "--v-b", "1", cwd=tmp_path))
    (tmp_path / "head.csv").write_text("t,v\n")
    assert "no data rows" in _one_line(_cli("head.csv", "--v-b", "1", cwd=tmp_path))


def test_a_closed_stdout_is_one_line_not_a_traceback(tmp_path):
    """Any command with stdout closed ended in `AttributeError` (`quick_exit`); the table
    that would go to stdout is refused instead of lost."""
    import subprocess

    _sine_csv(tmp_path / "trace.csv")
    done = subprocess.run(["stickslip", "cycles", "trace.csv", "--v-b", "1"], cwd=tmp_path,
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                          preexec_fn=lambda: os.close(1))  # fmt: skip
    assert done.returncode == 2 and "standard output is closed" in done.stderr, done.stderr
    closed = dict(stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                  preexec_fn=lambda: os.close(1))  # fmt: skip
    done = subprocess.run(["stickslip", "models"], **closed)
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr


def test_a_killed_commands_temporary_file_is_removed(tmp_path):
    _sine_csv(tmp_path / "trace.csv")
    dead = 2**22 + 12345
    (tmp_path / f"c.csv.tmp{dead}").write_text("half")
    done = _cli("trace.csv", "--v-b", "1", "--out", "c.csv", cwd=tmp_path)
    assert done.returncode == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.csv", "trace.csv"]
