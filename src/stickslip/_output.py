"""Where results may be written: outputs never touch the inputs or a folder of the user's.

Every command that writes (`run`, `sweep`, `fit`, `cycles`) asks here first, before any
work is done. A results folder is recognised by the marker file `.stickslip-results` that
the project writes into each one (with the rest of the results, atomically); `force`
replaces such a folder and nothing else. Paths are compared resolved (links, `..`, a
relative path) and, for files, with `os.path.samefile` (hard links).
"""

from __future__ import annotations

import json
import os
import pathlib
import sys
import tempfile
import time
from collections.abc import Iterable

from ._errors import OutputError

MARKER = ".stickslip-results"
_MARKER_MAX_BYTES = 1 << 20  # the marker is a small JSON object; a larger file is not ours


def real_number(path: str | os.PathLike) -> pathlib.Path:
    return pathlib.Path(os.path.realpath(os.path.abspath(os.fspath(path))))


def _inside(path: pathlib.Path, folder: pathlib.Path) -> bool:
    """True if `path` is `folder` or lies under it (both resolved)."""
    return path == folder or folder in path.parents


def _input_paths(inputs: Iterable) -> list[tuple[str, pathlib.Path]]:
    return [(os.fspath(p), real_number(p)) for p in inputs if p is not None]


def is_results_folder(path: str | os.PathLike) -> bool:
    """True if `path` is a folder this project wrote: it holds the marker file, a small
    regular file (not a link) whose JSON names stickslip."""
    marker = pathlib.Path(path) / MARKER
    try:
        if not marker.is_file() or marker.is_symlink():
            return False
        with open(marker, "rb") as f:
            text = f.read(_MARKER_MAX_BYTES + 1)
        if len(text) > _MARKER_MAX_BYTES:
            return False
        return json.loads(text.decode("utf-8")).get("written_by") == "stickslip"
    except (OSError, UnicodeDecodeError, ValueError, AttributeError):
        return False


# What a results folder held before its marker listed its files (an earlier version's):
# the names stickslip writes there.
_EARLIER_NAMES = ("results.nc", "summary.md", "study.yaml", "fit.json", "cycles.csv")


def _listing(folder: pathlib.Path) -> list[str]:
    """Every file and folder under `folder` but the marker, as relative POSIX paths."""
    found = []
    for root, dirs, files in os.walk(folder):
        here = pathlib.Path(root).relative_to(folder)
        found += [(here / name).as_posix() for name in dirs + files]
    return sorted(f for f in found if f != MARKER)


def _written(folder: pathlib.Path) -> set[str] | None:
    """The paths the marker of the results folder `folder` lists (`None`: an earlier
    marker that lists none)."""
    try:
        with open(pathlib.Path(folder) / MARKER, "rb") as f:
            record = json.loads(f.read(_MARKER_MAX_BYTES).decode("utf-8"))
        files = record.get("files")
    except (OSError, UnicodeDecodeError, ValueError, AttributeError):
        return set()
    if files is None:
        return None
    return {str(f) for f in files} if isinstance(files, list) else set()


def foreign_files(folder: str | os.PathLike) -> list[str]:
    """What the results folder `folder` holds that stickslip did not write there: every path
    its marker does not list (for an earlier marker that lists none, every path but the
    names stickslip writes and its figures)."""
    folder = pathlib.Path(folder)
    listed = _written(folder)
    present = _listing(folder)
    if listed is None:
        return [f for f in present if "/" in f or not (f in _EARLIER_NAMES or f.endswith(".png"))]
    return [f for f in present if f not in listed]


def _name_them(files: list[str]) -> str:
    shown = ", ".join(files[:5]) + (f" and {len(files) - 5} more" if len(files) > 5 else "")
    return shown


def write_marker(folder: pathlib.Path, contents: str):
    """Write the marker into `folder` (a results folder being made, complete): what wrote
    it, when, and the files it holds (`--force` replaces those and nothing else)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        v = version("stickslip")
    except PackageNotFoundError:  # a source tree that is not installed
        v = "unknown"
    record = {
        "written_by": "stickslip",
        "version": v,
        "contents": contents,
        "command": " ".join(["stickslip", *sys.argv[1:]])[:1000],
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "files": _listing(pathlib.Path(folder)),
    }
    (pathlib.Path(folder) / MARKER).write_text(json.dumps(record, indent=1) + "\n")


def _refuse(what: str, reason: str):
    raise OutputError(f"{what}: {reason}")


def _check_parent(out: pathlib.Path, real: pathlib.Path, what: str):
    """The folder that will hold `out` exists and a file can be made there (tried, not
    guessed from permission bits: a read-only mount or root's rights fool `os.access`)."""
    parent = real.parent
    if not parent.is_dir():
        _refuse(what, f"parent directory {out.absolute().parent} does not exist")
    try:
        probe = tempfile.mkdtemp(prefix=f".{real.name}.check-", dir=parent)
    except OSError as err:
        _refuse(what, f"parent directory {parent} is not writable ({err.strerror})")
    os.rmdir(probe)


def _check_not_inputs(out: str, real: pathlib.Path, inputs, what: str):
    cwd = real_number(os.getcwd())
    if _inside(cwd, real):
        where = "is the current directory" if real == cwd else "holds the current directory"
        _refuse(what, f"{out} {where}: refusing to write results there")
    for name, path in _input_paths(inputs):
        if _inside(path, real):
            where = "is" if path == real else "holds"
            _refuse(what, f"{out} {where} the input {name}: refusing to write results there")
        if path.is_dir() and _inside(real, path):
            _refuse(what, f"{out} lies inside the input folder {name}")


def check_output_dir(
    out: str | os.PathLike, *, inputs: Iterable = (), force: bool = False, what: str = "--out"
) -> pathlib.Path:
    """Check that results may be written to the folder `out`; return it resolved.

    Refused (an `OutputError` naming `what` and the reason): `out` is, or holds, one of
    `inputs` (files or folders) or lies inside an input folder; `out` is the current
    directory or one of its ancestors; `out` is a file; `out` is a non-empty folder and
    either `force` is not given or it is not a stickslip results folder (it lacks the
    marker file); its parent folder is missing or not writable. An empty folder is fine.
    """
    name = os.fspath(out)
    real = real_number(out)
    _check_not_inputs(name, real, inputs, what)
    if os.path.lexists(real) and not real.is_dir():
        _refuse(what, f"{name} exists and is not a directory")
    if real.is_dir():
        try:
            full = any(real.iterdir())
        except OSError as err:
            _refuse(what, f"{name} cannot be listed ({err.strerror})")
        if full:
            if not is_results_folder(real):
                _refuse(
                    what,
                    f"{name} exists and is not empty, and is not a stickslip results folder "
                    f"(no {MARKER} file): refusing to replace it, with or without --force",
                )
            if not force:
                _refuse(
                    what,
                    f"{name} exists and is not empty (results of an earlier run: use --force "
                    "to replace it)",
                )
            _refuse_foreign(name, real, what)
    _check_parent(pathlib.Path(name), real, what)
    return real


def check_replace_dir(out: pathlib.Path, force: bool):
    """At the moment of replacing: `out` may be replaced only if it is empty or, with
    `force`, a results folder (it may have changed since `check_output_dir`)."""
    if out.is_dir() and any(out.iterdir()):
        if not is_results_folder(out):
            _refuse("--out", f"{out} is not a stickslip results folder: refusing to replace it")
        if not force:
            _refuse("--out", f"{out} exists and is not empty (use --force to replace it)")
        _refuse_foreign(str(out), out, "--out")


def _refuse_foreign(name: str, folder: pathlib.Path, what: str):
    """A results folder that also holds files stickslip did not write is not replaced."""
    foreign = foreign_files(folder)
    if foreign:
        _refuse(
            what,
            f"{name} holds files stickslip did not write ({_name_them(foreign)}): refusing "
            "to replace it, with or without --force (move them out first)",
        )


def check_output_file(
    out: str | os.PathLike, *, inputs: Iterable = (), force: bool = False, what: str = "--out"
) -> pathlib.Path:
    """Check that the file `out` may be written; return it resolved.

    Refused (an `OutputError`): `out` is one of `inputs` (the same file by any path: links,
    a relative path, a hard link); `out` is a folder or not a regular file; `out` exists
    and `force` is not given; its parent folder is missing or not writable.
    """
    name = os.fspath(out)
    real = real_number(out)
    for input_name, path in _input_paths(inputs):
        same = path == real
        if not same and real.exists() and path.exists():
            try:
                same = os.path.samefile(real, path)
            except OSError:
                same = False
        if same:
            _refuse(what, f"{name} is the input {input_name}: refusing to overwrite it")
    if real.is_dir():
        _refuse(what, f"{name} is a directory, not a file")
    if os.path.lexists(real):
        if not real.is_file():
            _refuse(what, f"{name} exists and is not a regular file")
        if not force:
            _refuse(what, f"{name} exists (use --force to replace it)")
    _check_parent(pathlib.Path(name), real, what)
    return real


# -- writing a results folder --------------------------------------------------------------
def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (OSError, ValueError):  # another user's process (or no such check here)
        return True
    return True


def _leftover_pid(name: str, prefix: str) -> int | None:
    """The process id in a leftover's name `prefix` + digits, or `None`."""
    tail = name[len(prefix) :] if name.startswith(prefix) else ""
    return int(tail) if tail.isdigit() else None


def _siblings(out: pathlib.Path) -> list[pathlib.Path]:
    """What lies beside `out` (nothing where its folder cannot be listed)."""
    try:
        return list(out.parent.iterdir())
    except OSError:
        return []


def clean_leftovers(out: pathlib.Path) -> None:
    """Tidy what runs killed while writing the results folder `out` left beside it (their
    process is gone): a half-written `.NAME.partial-PID` is removed; an earlier result moved
    aside as `.NAME.old-PID` is put back where the new one never arrived, else removed."""
    import shutil

    out = pathlib.Path(out)
    for path in _siblings(out):
        for kind in ("partial", "old"):
            pid = _leftover_pid(path.name, f".{out.name}.{kind}-")
            if pid is None or pid == os.getpid() or _alive(pid) or not path.is_dir():
                continue
            if kind == "old" and not os.path.lexists(out):
                with _quiet():
                    path.rename(out)
            else:
                shutil.rmtree(path, ignore_errors=True)


def clean_file_leftovers(out: pathlib.Path) -> None:
    """Remove `NAME.tmpPID` files beside the file `out` that a killed command left."""
    out = pathlib.Path(out)
    for path in _siblings(out):
        pid = _leftover_pid(path.name, f"{out.name}.tmp")
        if pid is not None and pid != os.getpid() and not _alive(pid) and path.is_file():
            with _quiet():
                path.unlink()


def _quiet():
    import contextlib

    return contextlib.suppress(OSError)


def partial_dir(out: pathlib.Path) -> pathlib.Path:
    """A new, empty folder beside `out` to write its results into (`.NAME.partial-PID`),
    after tidying what killed runs left there (`clean_leftovers`)."""
    import shutil

    out = pathlib.Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    clean_leftovers(out)
    tmp = out.parent / f".{out.name}.partial-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    return tmp


# -- interrupts ------------------------------------------------------------------------------
_interrupted = [False]


def interrupted() -> bool:
    """Whether an interrupt (SIGINT) came since `catch_interrupts` (even one that a library
    callback swallowed: JAX's garbage-collection callback prints `Exception ignored` for an
    interrupt raised inside it, and the run would go on)."""
    return _interrupted[0]


def check_interrupted() -> None:
    """Raise `KeyboardInterrupt` if an interrupt came (see `interrupted`)."""
    if _interrupted[0]:
        raise KeyboardInterrupt


class catch_interrupts:
    """For a command's length, an interrupt is remembered (`interrupted`) as well as raised,
    so that a command whose interrupt was swallowed still writes nothing and exits 130;
    `caught` says afterwards whether one came. (Only in the main thread, where Python runs
    signal handlers.)"""

    def __enter__(self):
        import signal
        import threading

        self.before = None
        _interrupted[0] = False
        if threading.current_thread() is threading.main_thread():

            def on_interrupt(signum, frame):
                _interrupted[0] = True
                raise KeyboardInterrupt

            self.before = signal.signal(signal.SIGINT, on_interrupt)
        self.hook = sys.unraisablehook

        def unraisable(info):  # an interrupt a callback swallowed: remembered, not printed
            if isinstance(info.exc_value, KeyboardInterrupt):
                _interrupted[0] = True
            else:
                self.hook(info)

        sys.unraisablehook = unraisable
        return self

    def __exit__(self, *exc):
        import signal

        self.caught, _interrupted[0] = _interrupted[0], False
        sys.unraisablehook = self.hook
        if self.before is not None:
            signal.signal(signal.SIGINT, self.before)
        return False


class no_interrupts:
    """Hold interrupts back (SIGINT blocked) while results are swapped into place, so that the
    swap happens whole or not at all; on leaving, one that came is raised. `pending()` says,
    inside, whether one came (before the swap: give it up)."""

    def __enter__(self):
        import signal
        import threading

        self.blocked = hasattr(signal, "pthread_sigmask") and (
            threading.current_thread() is threading.main_thread()
        )
        if self.blocked:
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        return self

    def pending(self) -> bool:
        import signal

        if _interrupted[0]:
            return True
        return self.blocked and signal.SIGINT in signal.sigpending()

    def __exit__(self, *exc):
        import signal

        if self.blocked:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        return False
