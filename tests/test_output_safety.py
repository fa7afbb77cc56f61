"""Outputs never touch inputs: `run`, `sweep` and `fit` refuse an `--out` that is, or holds,
the study or its data, the current directory or one above it, or a folder of the user's
own files (even with `--force`), before any work, with one line and exit 2; the user's
files stay intact byte for byte. `--force` replaces only an earlier results folder, known
by the marker file the project writes into each one.
"""

from __future__ import annotations

import json
import os
import pathlib
import tempfile

import pytest
import yaml
from click.testing import CliRunner

import stickslip as ss
from stickslip._output import MARKER, check_output_dir, check_output_file, is_results_folder
from stickslip.cli import main

STUDY = {
    "title": "output safety",
    "model": {
        "name": "langevin",
        "params": {"omega0": 1.0, "zeta": 0.1, "D": 0.4, "v_b": 1.0, "x0": 1.0, "tau": 0.1},
    },
    "simulation": {"n_paths": 200, "dt": 0.2, "t_max": 30},
    "outputs": ["slip_time"],
}
FIT = {"data": "cycles.csv", "free": {"D": [0.05, 2.0]}, "n_sim": 1000}


@pytest.fixture
def no_work(monkeypatch):
    """Every refusal must come before any work: a simulation or a fit started fails."""
    import stickslip._inference.fit
    import stickslip.study.run as run_module

    def refuse(*args, **kwargs):
        raise AssertionError("work was started")

    monkeypatch.setattr(run_module, "_compute", refuse)
    monkeypatch.setattr(run_module, "_compute_chain", refuse)
    monkeypatch.setattr(stickslip._inference.fit, "fit", refuse)


@pytest.fixture
def mystudy(tmp_path):
    """A user's study folder: the study, its data, notes; and a sibling folder."""
    home = tmp_path / "mystudy"
    home.mkdir()
    (home / "study.yaml").write_text(yaml.safe_dump({**STUDY, "fit": FIT}))
    (home / "cycles.csv").write_text(
        "slip_time\n" + "\n".join(f"{0.5 + i / 100}" for i in range(50))
    )
    (home / "notes.txt").write_text("my notes\n")
    (tmp_path / "elsewhere").mkdir()
    return home


def snapshot(root: pathlib.Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() if p.is_file() else b"<dir>"
        for p in sorted(root.rglob("*"))
    }


def one_error_line(result) -> str:
    assert "Traceback" not in result.stderr, result.stderr
    assert isinstance(result.exception, SystemExit | None), repr(result.exception)
    assert result.exit_code == 2, (result.exit_code, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    line = lines[0]
    assert line.startswith("error: ") and line.isprintable() and len(line) <= 310, line
    return line


def invoke(argv):
    return CliRunner().invoke(main, [str(a) for a in argv])


# -- the data-loss cases -------------------------------------------------------------
@pytest.mark.parametrize("command", ["run", "sweep", "fit"])
@pytest.mark.parametrize("force", [False, True])
@pytest.mark.parametrize(
    "out, expect",
    [
        ("../mystudy", "is the current directory"),
        (".", "is the current directory"),
        ("..", "holds the current directory"),
        ("/", "holds the current directory"),
    ],
)
def test_out_is_the_working_folder_or_above(
    tmp_path, mystudy, monkeypatch, no_work, command, force, out, expect
):
    """`cd mystudy && stickslip run study.yaml --out ../mystudy --force` deleted the study
    and the notes; `--out .` failed with a raw OSError."""
    monkeypatch.chdir(mystudy)
    before = snapshot(tmp_path)
    argv = [command, "study.yaml", "--out", out, "-q"]
    if command == "sweep":
        argv += ["-p", "model.params.v_b=1,2"]
    line = one_error_line(invoke(argv + (["--force"] if force else [])))
    assert line.startswith(f"error: --out: {out} "), line
    assert expect in line, line
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("command", ["run", "sweep", "fit"])
def test_out_holds_the_study(tmp_path, mystudy, monkeypatch, no_work, command):
    """From another folder: `--out` naming the study's folder (absolute, relative, through
    a link) is refused with or without --force."""
    monkeypatch.chdir(tmp_path / "elsewhere")
    link = tmp_path / "link"
    link.symlink_to(mystudy, target_is_directory=True)
    before = snapshot(mystudy)
    for out in (mystudy, "../mystudy", link):
        for force in ([], ["--force"]):
            argv = [command, mystudy / "study.yaml", "--out", out, "-q", *force]
            if command == "sweep":
                argv += ["-p", "model.params.v_b=1,2"]
            line = one_error_line(invoke(argv))
            assert "holds the input" in line and "study.yaml" in line, line
    assert snapshot(mystudy) == before


def test_fit_out_holds_its_data(tmp_path, mystudy, no_work):
    """`fit`'s data file counts as an input: an --out holding it is refused."""
    data = tmp_path / "data"
    data.mkdir()
    (data / "trace_cycles.csv").write_text((mystudy / "cycles.csv").read_text())
    (data / "other.txt").write_text("other\n")
    study = tmp_path / "fit.yaml"
    study.write_text(yaml.safe_dump({**STUDY, "fit": {**FIT, "data": "data/trace_cycles.csv"}}))
    before = snapshot(tmp_path)
    line = one_error_line(invoke(["fit", study, "--out", data, "--force", "-q"]))
    assert line == (
        f"error: --out: {data} holds the input {data / 'trace_cycles.csv'}: refusing to write "
        "results there"
    ), line
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("command", ["run", "sweep", "fit"])
def test_force_does_not_replace_a_folder_of_other_files(tmp_path, mystudy, no_work, command):
    """A non-empty folder without the marker is never replaced, with or without --force."""
    other = tmp_path / "elsewhere"
    (other / "thesis.tex").write_text("\\documentclass{article}\n")
    before = snapshot(tmp_path)
    for force in ([], ["--force"]):
        argv = [command, mystudy / "study.yaml", "--out", other, "-q", *force]
        if command == "sweep":
            argv += ["-p", "model.params.v_b=1,2"]
        line = one_error_line(invoke(argv))
        assert line.startswith(f"error: --out: {other} exists and is not empty"), line
        assert "not a stickslip results folder" in line, line
    assert snapshot(tmp_path) == before


def test_a_marker_that_is_not_ours_is_not_recognised(tmp_path):
    folder = tmp_path / "f"
    folder.mkdir()
    (folder / "data.txt").write_text("x")
    assert not is_results_folder(folder)
    (folder / MARKER).write_text("not json")
    assert not is_results_folder(folder)
    (folder / MARKER).write_text(json.dumps({"written_by": "someone else"}))
    assert not is_results_folder(folder)
    (folder / MARKER).unlink()
    (folder / MARKER).symlink_to(folder / "data.txt")
    assert not is_results_folder(folder)
    with pytest.raises(ss.OutputError, match="not a stickslip results folder"):
        check_output_dir(folder, force=True)


def test_an_empty_folder_is_fine(tmp_path):
    (tmp_path / "empty").mkdir()
    assert check_output_dir(tmp_path / "empty") == (tmp_path / "empty").resolve()
    assert check_output_dir(tmp_path / "new") == (tmp_path / "new").resolve()


# -- locations that cannot be written: found before the run ------------------------------------
@pytest.mark.parametrize("command", ["run", "fit"])
def test_missing_parent_is_found_before_the_run(tmp_path, mystudy, no_work, command):
    out = tmp_path / "no" / "such" / "out"
    line = one_error_line(invoke([command, mystudy / "study.yaml", "--out", out, "-q"]))
    assert line == f"error: --out: parent directory {out.parent} does not exist", line
    assert not (tmp_path / "no").exists()


def test_out_under_a_file_is_refused(tmp_path, mystudy, no_work):
    out = mystudy / "notes.txt" / "out"
    line = one_error_line(invoke(["run", mystudy / "study.yaml", "--out", out, "-q"]))
    assert "parent directory" in line and "does not exist" in line, line


@pytest.mark.skipif(
    not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root may write anywhere"
)
def test_unwritable_parent_is_found_before_the_run(tmp_path, mystudy, no_work):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        line = one_error_line(
            invoke(["run", mystudy / "study.yaml", "--out", locked / "out", "-q"])
        )
    finally:
        locked.chmod(0o700)
    assert line.startswith(f"error: --out: parent directory {locked} is not writable"), line


@pytest.mark.skipif(not os.path.isdir("/sys/kernel"), reason="needs Linux's sysfs")
def test_a_read_only_file_system_is_found_before_the_run(mystudy, no_work):
    """sysfs refuses new folders even to root, where permission bits say nothing."""
    try:
        os.rmdir(tempfile.mkdtemp(dir="/sys"))
        pytest.skip("/sys is writable here")
    except OSError:
        pass
    line = one_error_line(invoke(["run", mystudy / "study.yaml", "--out", "/sys/results", "-q"]))
    assert line.startswith("error: --out: parent directory /sys is not writable"), line


# -- a real (tiny) run: the marker, --force on results ------------------------------------------
def test_force_replaces_an_earlier_results_folder(tmp_path, mystudy, monkeypatch):
    monkeypatch.chdir(mystudy)
    out = tmp_path / "results"
    first = invoke(["run", "study.yaml", "--out", out, "-q", "--no-figures"])
    assert first.exit_code == 0, first.output
    marker = json.loads((out / MARKER).read_text())
    assert marker["written_by"] == "stickslip" and marker["contents"] == "run"
    assert is_results_folder(out)
    line = one_error_line(invoke(["run", "study.yaml", "--out", out, "-q", "--no-figures"]))
    assert line.startswith(f"error: --out: {out} exists and is not empty"), line
    assert "use --force" in line, line
    (out / "results.nc").write_bytes(b"stale")
    again = invoke(["run", "study.yaml", "--out", out, "-q", "--no-figures", "--force"])
    assert again.exit_code == 0, again.output
    assert (out / "results.nc").read_bytes() != b"stale"
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [MARKER, "results.nc", "study.yaml", "summary.md"]
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["elsewhere", "mystudy", "results"]
    assert (mystudy / "notes.txt").read_text() == "my notes\n"


# -- the Python API ------------------------------------------------------------------------------
def test_api_raises_output_error(tmp_path, mystudy, no_work):
    from stickslip.study import run_fit

    with pytest.raises(ss.OutputError, match="holds the input") as err:
        ss.run_study(mystudy / "study.yaml", tmp_path, force=True)
    assert isinstance(err.value, ss.StickSlipError)
    with pytest.raises(ss.OutputError, match="holds the input"):
        run_fit(str(mystudy / "study.yaml"), mystudy, force=True)


def test_output_file_is_never_an_input(tmp_path):
    """The file variant (for `cycles --out`): never the input, by any path; replacing an
    existing file needs force."""
    trace = tmp_path / "trace.csv"
    trace.write_text("t,x\n0,1\n")
    (tmp_path / "sym.csv").symlink_to(trace)
    os.link(trace, tmp_path / "hard.csv")
    sub = tmp_path / "sub"
    sub.mkdir()
    for out in (trace, tmp_path / "sym.csv", tmp_path / "hard.csv", sub / ".." / "trace.csv"):
        for force in (False, True):
            with pytest.raises(ss.OutputError, match="is the input"):
                check_output_file(out, inputs=[trace], force=force)
    with pytest.raises(ss.OutputError, match="is the input"):
        check_output_file(trace, inputs=[tmp_path / "sym.csv"], force=True)
    other = tmp_path / "cycles.csv"
    other.write_text("old\n")
    with pytest.raises(ss.OutputError, match="exists \\(use --force"):
        check_output_file(other, inputs=[trace])
    assert check_output_file(other, inputs=[trace], force=True) == other.resolve()
    new = check_output_file(tmp_path / "new.csv", inputs=[trace])
    assert new == (tmp_path / "new.csv").resolve()
    with pytest.raises(ss.OutputError, match="is a directory"):
        check_output_file(sub, inputs=[trace], force=True)
    with pytest.raises(ss.OutputError, match="does not exist"):
        check_output_file(tmp_path / "no" / "x.csv", inputs=[trace])
    assert trace.read_text() == "t,x\n0,1\n" and other.read_text() == "old\n"


# -- every bad-input error of the package is one line and exit 2 ---------------------------
@pytest.mark.parametrize(
    "error",
    [
        ss.ParameterError("simulate", "dt", "must be > 0", -1.0),
        ss.DataError("no stick-slip structure"),
        ss.ResourceError("needs 309 GB; the limit is 8 GB"),
        ss.OutputError("--out: cannot be written"),
    ],
    ids=lambda e: type(e).__name__,
)
def test_bad_input_errors_exit_2(tmp_path, mystudy, monkeypatch, error):
    import stickslip.study.run as run_module

    def fail(*args, **kwargs):
        raise error

    monkeypatch.setattr(run_module, "_compute", fail)
    line = one_error_line(invoke(["run", mystudy / "study.yaml", "--out", tmp_path / "o", "-q"]))
    assert line == f"error: {error}", line
    assert not (tmp_path / "o").exists()


def test_a_long_message_is_cut_to_one_printable_line(tmp_path, mystudy, monkeypatch):
    import stickslip.study.run as run_module

    def fail(*args, **kwargs):
        raise ss.DataError("first\nsecond\x00\x1b[31m" + "x" * 5000)

    monkeypatch.setattr(run_module, "_compute", fail)
    line = one_error_line(invoke(["run", mystudy / "study.yaml", "--out", tmp_path / "o", "-q"]))
    assert line.startswith("error: first second\\x00\\x1b[31mxxx") and line.endswith("..."), line


def test_an_unexpected_error_exits_1(tmp_path, mystudy, monkeypatch):
    import stickslip.study.run as run_module

    def fail(*args, **kwargs):
        raise RuntimeError("solver broke\nsecond line")

    monkeypatch.setattr(run_module, "_compute", fail)
    result = invoke(["run", mystudy / "study.yaml", "--out", tmp_path / "o", "-q"])
    assert result.exit_code == 1
    assert result.stderr.strip().splitlines() == [
        "error: run failed: RuntimeError: solver broke second line (--debug shows the traceback)"
    ]


@pytest.mark.parametrize("command", ["run", "sweep"])
def test_out_is_checked_before_a_cluster_starts(mystudy, monkeypatch, no_work, command):
    from stickslip import _distributed

    def refuse(*args, **kwargs):
        raise AssertionError("a cluster was contacted")

    monkeypatch.setattr(_distributed, "connect", refuse)
    monkeypatch.chdir(mystudy)
    argv = [command, "study.yaml", "--out", ".", "--force", "--dask", "tcp://127.0.0.1:9", "-q"]
    if command == "sweep":
        argv += ["-p", "model.params.v_b=1,2"]
    line = one_error_line(invoke(argv))
    assert line == "error: --out: . is the current directory: refusing to write results there"


# -- replacing only what stickslip wrote -------------------------------------------------------
@pytest.fixture
def earlier(tmp_path, mystudy):
    """An earlier run's results folder, `res` beside the study (its marker lists its files)."""
    out = tmp_path / "res"
    done = invoke(["run", mystudy / "study.yaml", "--out", out, "-q", "--no-figures"])
    assert done.exit_code == 0, done.stderr
    return out


def test_force_refuses_a_results_folder_holding_the_users_files(tmp_path, mystudy, earlier):
    """`run --force` over a results folder deleted a file the user had put into it: the
    marker lists what stickslip wrote, and a folder holding anything else is refused."""
    record = json.loads((earlier / MARKER).read_text())
    assert set(record["files"]) == {"results.nc", "summary.md", "study.yaml"}
    (earlier / "my notes.txt").write_text("mine\n")
    (earlier / "plots").mkdir()
    before = snapshot(earlier)
    for command in ("run", "sweep"):
        argv = [command, mystudy / "study.yaml", "--out", earlier, "-q", "--force"]
        if command == "sweep":
            argv += ["-p", "model.params.v_b=1,2"]
        line = one_error_line(invoke(argv))
        assert "holds files stickslip did not write (my notes.txt, plots)" in line, line
    assert snapshot(earlier) == before
    (earlier / "my notes.txt").unlink()
    (earlier / "plots").rmdir()
    done = invoke(["run", mystudy / "study.yaml", "--out", earlier, "-q", "--force"])
    assert done.exit_code == 0, done.stderr


def test_an_earlier_marker_without_a_listing_protects_other_files(tmp_path):
    """A results folder of an earlier version (its marker lists no files): only the names
    stickslip writes, and figures, may be replaced."""
    from stickslip._output import foreign_files

    out = tmp_path / "old"
    out.mkdir()
    (out / MARKER).write_text(json.dumps({"written_by": "stickslip"}))
    for name in ("results.nc", "summary.md", "slip_time.png", "data.csv"):
        (out / name).write_text("x")
    assert foreign_files(out) == ["data.csv"]
    with pytest.raises(ss.OutputError, match="data.csv"):
        check_output_dir(out, force=True)


def test_killed_runs_leftovers_are_tidied_and_an_earlier_result_restored(tmp_path):
    """A killed run left `.NAME.partial-PID` for ever; one killed while swapping left the
    earlier result as `.NAME.old-PID` and nothing under its name: the next write tidies the
    first and puts the second back."""
    from stickslip._output import partial_dir

    dead = 2**22 + 12345  # above Linux's largest process id: no such process
    out = tmp_path / "res"
    (tmp_path / f".res.partial-{dead}").mkdir()
    (tmp_path / f".res.partial-{dead}" / "results.nc").write_text("half")
    (tmp_path / f".res.old-{dead}").mkdir()
    (tmp_path / f".res.old-{dead}" / "results.nc").write_text("earlier")
    tmp = partial_dir(out)
    assert (out / "results.nc").read_text() == "earlier"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["res", tmp.name])
    (tmp_path / f".res.old-{dead}").mkdir()  # the swap was done: the old copy goes
    partial_dir(out)
    assert not (tmp_path / f".res.old-{dead}").exists() and (out / "results.nc").exists()


def test_an_interrupt_a_library_swallowed_still_stops_the_command(tmp_path, mystudy, earlier):
    """JAX's garbage-collection callback swallowed an interrupt now and then (`Exception
    ignored ... KeyboardInterrupt`): the run went on, exited 0 and replaced the earlier
    result. Now the command exits 130 and the earlier result stays as it was."""
    import signal

    import stickslip.study.run as run_module

    before = snapshot(earlier)
    compute = run_module._compute

    class Swallows:
        def __del__(self):  # an interrupt raised here is "ignored" by Python
            os.kill(os.getpid(), signal.SIGINT)

    def interrupted_compute(*args, **kwargs):
        Swallows()
        return compute(*args, **kwargs)

    run_module._compute = interrupted_compute
    try:
        done = invoke(["run", mystudy / "study.yaml", "--out", earlier, "-q", "--force",
                       "--no-figures"])  # fmt: skip
    finally:
        run_module._compute = compute
    assert done.exit_code == 130, (done.exit_code, done.stderr)
    assert "interrupted" in done.stderr and "Traceback" not in done.stderr
    assert snapshot(earlier) == before
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".res")] == []


def test_a_run_logged_to_a_file_says_its_stages(tmp_path, mystudy):
    """A long run whose stderr is not a terminal (a log file) said nothing until its end:
    it now writes a line per stage, and no bars."""
    done = invoke(["run", mystudy / "study.yaml", "--out", tmp_path / "res", "--no-figures"])
    assert done.exit_code == 0, done.stderr
    assert "simulate: 200 paths" in done.stderr and "\r" not in done.stderr


@pytest.mark.slow  # ten runs of a new process, each interrupted (about a minute)
def test_interrupts_at_random_moments_end_in_130_with_the_earlier_result(tmp_path, mystudy):
    """SIGINT during `run --force`: 3 in 20 were swallowed (exit 0, the earlier result
    replaced). Each now ends the command with 130 and the earlier result as it was, or, if
    it came after the swap, with the new result complete; never a traceback."""
    import random
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "res"
    done = invoke(["run", mystudy / "study.yaml", "--out", out, "-q", "--no-figures"])
    assert done.exit_code == 0
    argv = [sys.executable, "-m", "stickslip.cli", "run", str(mystudy / "study.yaml")]
    argv += ["--out", str(out), "--force", "-q", "--no-figures"]
    argv += ["--set", "simulation.n_paths=20000"]
    delays = random.Random(7).sample([0.5 + 0.4 * k for k in range(20)], 10)
    outcomes = []
    for delay in delays:
        before = snapshot(out)
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=300)
        outcomes.append(proc.returncode)
        assert proc.returncode in (0, 130), (delay, proc.returncode, err)
        assert "Traceback" not in err and "Exception ignored" not in err, err
        if proc.returncode == 130:
            assert snapshot(out) == before, delay
        assert is_results_folder(out) and (out / "results.nc").exists()
        assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".res")] == []
    assert 130 in outcomes


def test_an_interrupt_during_the_swap_puts_the_earlier_results_back(tmp_path, monkeypatch):
    """An interrupt that another thread took and Python raised mid-swap (after the earlier
    results were moved aside): they go back in place, and the new ones are not kept."""
    from stickslip.study.write import replace_file

    out, tmp = tmp_path / "res", tmp_path / ".res.partial-1"
    for folder, text in ((out, "earlier"), (tmp, "new")):
        folder.mkdir()
        (folder / "results.nc").write_text(text)
    (out / MARKER).write_text(json.dumps({"written_by": "stickslip", "files": ["results.nc"]}))
    rename = pathlib.Path.rename

    def interrupted(self, target):
        if self == tmp:
            raise KeyboardInterrupt
        return rename(self, target)

    monkeypatch.setattr(pathlib.Path, "rename", interrupted)
    with pytest.raises(KeyboardInterrupt):
        replace_file(tmp, out, force=True)
    assert (out / "results.nc").read_text() == "earlier"
    assert not list(tmp_path.glob(".res.old-*"))


def test_an_interrupt_wrapped_in_another_error_still_ends_in_130():
    """A Ctrl-C that lands in a class body's `__set_name__` (during an import) reaches the
    command as "RuntimeError: Error calling __set_name__ ..." with the interrupt as its
    cause: it ends as an interrupt (130), not as a failed run (1)."""
    import click

    from stickslip.cli._common import EXIT_INTERRUPTED, handle_errors

    @click.command()
    @handle_errors
    def body():
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as interrupt:
            raise RuntimeError("Error calling __set_name__ on 'Field' instance") from interrupt

    result = CliRunner().invoke(body)
    assert result.exit_code == EXIT_INTERRUPTED, result.output

    @click.command()
    @handle_errors
    def failing():
        raise RuntimeError("a real failure")

    assert CliRunner().invoke(failing).exit_code == 1
