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
_MARKER_MAX_BYTES = 4096  # the marker is a small JSON object; a larger file is not ours


def _real(path: str | os.PathLike) -> pathlib.Path:
    return pathlib.Path(os.path.realpath(os.path.abspath(os.fspath(path))))


def _inside(path: pathlib.Path, folder: pathlib.Path) -> bool:
    """True if `path` is `folder` or lies under it (both resolved)."""
    return path == folder or folder in path.parents


def _input_paths(inputs: Iterable) -> list[tuple[str, pathlib.Path]]:
    return [(os.fspath(p), _real(p)) for p in inputs if p is not None]


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


def write_marker(folder: pathlib.Path, contents: str):
    """Write the marker into `folder` (a results folder being made): what wrote it, when."""
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
    cwd = _real(os.getcwd())
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
    real = _real(out)
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


def check_output_file(
    out: str | os.PathLike, *, inputs: Iterable = (), force: bool = False, what: str = "--out"
) -> pathlib.Path:
    """Check that the file `out` may be written; return it resolved.

    Refused (an `OutputError`): `out` is one of `inputs` (the same file by any path: links,
    a relative path, a hard link); `out` is a folder or not a regular file; `out` exists
    and `force` is not given; its parent folder is missing or not writable.
    """
    name = os.fspath(out)
    real = _real(out)
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
