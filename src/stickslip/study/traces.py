"""Reading a measured trace's columns from a CSV (with a header) or a MATLAB .mat file (version
7 or before), for `stickslip cycles` and campaigns: anything unreadable is one `StudyError`
naming the file and the problem, never the file's content."""

from __future__ import annotations

import os
import warnings

from .load import StudyError

_CHUNK = 1 << 20  # bytes read at a time while a CSV is checked


def read_trace(path: str, wanted) -> dict:
    """The columns `wanted` (those present) of a CSV or .mat trace; anything unreadable is
    a `StudyError` naming the problem, never the file's content."""
    if not os.path.lexists(path):
        raise StudyError(path, None, "no such file")
    if not os.path.isfile(path):
        raise StudyError(path, None, "is not a regular file (a folder, a FIFO or a device): "
                         "give a CSV or a .mat file")  # fmt: skip
    kind = _sniff(path)
    if kind == "hdf5":
        raise StudyError(path, None, "is a MATLAB v7.3 (HDF5) file, which cannot be read: save "
                         "it with save(..., '-v7') in MATLAB, or as CSV")  # fmt: skip
    if kind == "mat" or path.lower().endswith(".mat"):
        return _read_mat(path, wanted)
    import numpy as np

    skip, names, rows = _scan_csv(path)
    _check_columns(path, names, wanted)
    # (the parser holds the array and about as much again while it grows it)
    nbytes = 2.0 * 8 * rows * len(names)
    if nbytes > 1e8:
        from .._memory import check_memory

        check_memory(path, f"its {rows} rows of {len(names)} values", nbytes,
                     "read a part of the trace")  # fmt: skip
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # (no data rows: said below)
            data = np.loadtxt(path, delimiter=",", comments="#", skiprows=skip, ndmin=2,
                              encoding="utf-8-sig", dtype=float)  # fmt: skip
    except ValueError as err:
        if "could not convert" in str(err):
            import re

            at = re.search(r"row (\d+), column (\d+)", str(err))  # (numpy's rows from 0)
            where = f" (data row {int(at[1]) + 1}, column {at[2]})" if at else ""
            raise StudyError(path, None, f"holds a value that is not a number{where}") from None
        raise StudyError(
            path, None, f"rows must have {len(names)} values, like the header"
        ) from None
    if data.size == 0:
        raise StudyError(path, None, "has a header but no data rows")
    if data.shape[1] != len(names):
        raise StudyError(path, None, f"rows must have {len(names)} values, like the header")
    return {n: data[:, k] for k, n in enumerate(names) if n in wanted}


def _sniff(path: str) -> str | None:
    """`"mat"` for a MATLAB file of version 7 or before, `"hdf5"` for version 7.3 (an HDF5
    file, whatever its name), else `None`: a trace is read by what it holds, not its name."""
    try:
        with open(path, "rb") as f:
            head = f.read(520)
    except OSError:
        return None
    hdf5 = b"\x89HDF\r\n\x1a\n"
    if head.startswith(hdf5) or head[512:520] == hdf5:
        return "hdf5"
    return "mat" if head.startswith(b"MATLAB 5.0 MAT-file") else None


def _scan_csv(path: str) -> tuple[int, list[str], int]:
    """(the lines up to and with the header, the header's names, about how many lines follow)
    of a CSV, read in chunks: refused if it is not UTF-8 text or has no usable header."""
    import codecs

    decoder = codecs.getincrementaldecoder("utf-8-sig")()
    skip, names, rows, offset, pending, last = 0, None, 0, 0, "", b"\n"

    def decode(chunk: bytes, final: bool = False) -> str:
        try:
            return decoder.decode(chunk, final=final)
        except UnicodeDecodeError as err:
            at = offset + max(err.start, 0)
            why = f"is not a UTF-8 text CSV (undecodable byte at offset {at})"
            why += "; give a CSV or a .mat file"
            raise StudyError(path, None, why) from None

    try:
        with open(path, "rb") as f:
            while chunk := f.read(_CHUNK):
                text = decode(chunk)
                offset, last = offset + len(chunk), chunk[-1:]
                if names is not None:
                    rows += text.count("\n")
                    continue
                *whole, pending = (pending + text).split("\n")
                for k, line in enumerate(whole):
                    if line.strip() and not line.startswith("#"):
                        names, skip = [n.strip() for n in line.split(",")], skip + k + 1
                        rows += len(whole) - k - 1
                        break
                else:
                    skip += len(whole)
            decode(b"", final=True)
    except OSError as err:
        raise StudyError(path, None, f"cannot read the file ({err.strerror})") from None
    if names is None and pending.strip() and not pending.startswith("#"):
        names, skip = [n.strip() for n in pending.split(",")], skip + 1
    if names is None:
        raise StudyError(path, None, "is empty: expected a header with columns t and x and/or v")
    if not all(n.isprintable() and len(n) <= 64 for n in names):
        raise StudyError(path, "columns", "the header holds unprintable or over-long names")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise StudyError(path, "columns", f"name {', '.join(twice)} more than once")
    return skip, names, rows + (last != b"\n")


def _read_mat(path: str, wanted) -> dict:
    import numpy as np

    try:
        from scipy.io import loadmat

        raw = loadmat(path)
    except Exception:  # scipy raises several kinds for a file that is no .mat
        raise StudyError(path, None, "cannot be read as a MATLAB .mat file") from None
    names = [k for k in raw if not k.startswith("__")]
    _check_columns(path, names, wanted)
    out = {}
    for n in wanted:
        if n in raw:
            a = np.asarray(raw[n])
            if a.ndim > 2 or (a.ndim == 2 and min(a.shape) != 1) or a.dtype.kind not in "iuf":
                raise StudyError(path, n, f"must be a real vector (got shape {a.shape})")
            out[n] = a.astype(float).ravel()
    return out


def _check_columns(path, names, wanted) -> None:
    t, *rest = wanted
    if t not in names or not (set(rest) & set(names)):
        need = " and ".join(rest) if len(rest) == 1 else " and/or ".join(rest)
        shown = ", ".join(names[:10]) + (", ..." if len(names) > 10 else "")
        raise StudyError(path, "columns", f"must include {t} and {need} (got {shown})")
