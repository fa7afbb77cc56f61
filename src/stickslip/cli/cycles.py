"""`stickslip cycles`: per-cycle stick-slip statistics from a measured trace (CSV or .mat)."""

from __future__ import annotations

import os
import pathlib
import sys
import warnings

import click

from ._common import handle_errors


@click.command()
@click.argument("trace", type=click.Path(dir_okay=False, path_type=str))
@click.option(
    "--v-b",
    "v_b",
    type=float,
    default=None,
    help="The driving speed, > 0 (required for x/v; with a force, checked against "
    "the sticks' loading slope, or estimated from it when left out).",
)
@click.option(
    "--force-column",
    "force_column",
    default=None,
    metavar="COLUMN",
    help="Read the spring force (N) from this column instead of x/v.",
)
@click.option(
    "--force-scale",
    type=float,
    default=1.0,
    show_default=True,
    help="Newtons per unit of the force column (e.g. m g for a force in units "
    "of the slider's weight).",
)
@click.option("--stiffness", type=float, default=None, help="Spring stiffness (N/m), with a force.")
@click.option(
    "--tol",
    type=float,
    default=None,
    help="x/v only: a sample is stuck when |v - v_b| <= tol (default: 5 robust sd).",
)
@click.option(
    "--out",
    "-o",
    type=click.Path(dir_okay=False, path_type=str),
    default=None,
    help="Write the table (with its settings) here and a figure beside it "
    "(default: the table to stdout).",
)
@click.option("--force", "replace", is_flag=True, help="Replace an existing --out file.")
@handle_errors
def cycles(trace, v_b, force_column, force_scale, stiffness, tol, out, replace):
    """Find the stick-slip cycles in TRACE and write one row per complete cycle.

    TRACE is a CSV file with a header naming the columns (`t` and `x` and/or `v`, or a force
    column named by --force-column) or a MATLAB .mat file holding those variables. The
    table has the columns release_time, slip_time, slip_distance, stick_time and period
    (and peak_force, force_drop with a force), after a `#` block with every setting used
    (see `stickslip.extract_cycles`).
    """
    from .._errors import DataError, ParameterError
    from .._output import check_interrupted, clean_file_leftovers
    from ..extract import extract_cycles
    from ..study import StudyError

    _check_options(force_column, v_b, stiffness, tol, force_scale)
    figure = None
    if out is not None:
        _check_out(out, trace, replace)
        if force_column:  # the figure goes beside the table
            figure = os.path.splitext(out)[0] + ".png"
            _check_figure(figure, out, trace, replace)
    elif sys.stdout is None:
        raise StudyError("--out", None, "is needed: standard output is closed")
    wanted = ("t", force_column) if force_column else ("t", "x", "v")
    columns = _read_trace(trace, wanted)
    try:
        if force_column:
            found = extract_cycles(
                columns["t"], force=columns[force_column] * force_scale,
                stiffness=stiffness, v_b=v_b,
            )  # fmt: skip
        else:
            found = extract_cycles(
                columns["t"], columns.get("x"), columns.get("v"), v_b=v_b, tol=tol
            )
    except ParameterError as err:  # bad data or options: bad input, exit 2
        raise StudyError(trace, err.parameter, err.reason) from None
    except DataError as err:
        raise StudyError(trace, None, str(err).removeprefix("extract_cycles: ")) from None
    if force_column:
        found.info["force_column"] = force_column
        found.info["force_scale"] = force_scale
    text = found.to_csv()
    if out is None:
        click.echo(text, nl=False)
        return
    # Both files are written beside their names first and moved into place together, after
    # the last check for an interrupt: a stopped command leaves the earlier ones as they were.
    clean_file_leftovers(pathlib.Path(out))
    made = []
    try:
        made.append((f"{out}.tmp{os.getpid()}", out))
        with open(made[-1][0], "w", encoding="utf-8") as f:
            f.write(text)
        if figure is not None:
            clean_file_leftovers(pathlib.Path(figure))
            made.append((f"{figure}.tmp{os.getpid()}", figure))
            _figure(columns["t"], columns[force_column] * force_scale, found, made[-1][0])
        check_interrupted()
        for tmp, name in made:
            os.replace(tmp, name)
    finally:
        for tmp, _ in made:
            if os.path.lexists(tmp):
                os.unlink(tmp)
    mean = found.table["slip_time"].mean() if len(found) else float("nan")
    shown = out if figure is None else f"{out} (figure {figure})"
    click.echo(f"{len(found)} cycles (mean slip time {mean:.4g}) in {shown}")


def _check_options(force_column, v_b, stiffness, tol, force_scale) -> None:
    """Each option applies to one kind of trace: one given for the other kind is refused
    (it would be ignored)."""
    from ..study import StudyError

    if force_column:
        if stiffness is None:
            raise StudyError("--stiffness", None, "is required with --force-column (N/m)")
        if tol is not None:
            raise StudyError("--tol", None, "applies to an x/v trace only (with --force-column "
                             "the slips are found from the force's own noise)")  # fmt: skip
        return
    if v_b is None:
        raise StudyError("--v-b", None, "is required with an x/v trace")
    if stiffness is not None:
        raise StudyError("--stiffness", None, "applies with --force-column only (an x/v "
                         "trace needs no stiffness)")  # fmt: skip
    if force_scale != 1.0:
        raise StudyError("--force-scale", None, "applies with --force-column only")


_PNG_SOFTWARE = "stickslip cycles"  # the figure's PNG text chunk `Software`


def _ours(path: str) -> bool:
    """Whether the file `path` is a figure `stickslip cycles` wrote (its PNG text chunk)."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
    except OSError:
        return False
    return head.startswith(b"\x89PNG") and b"Software\x00" + _PNG_SOFTWARE.encode() in head


def _check_figure(figure: str, out: str, trace: str, replace: bool) -> None:
    """The figure beside the table: never the table itself, and an existing file there is
    replaced (with --force) only if it is a figure this command wrote."""
    from .._output import _real
    from ..study import StudyError

    if _real(figure) == _real(out):
        why = "the figure goes beside the table as NAME.png: name the table .csv"
        raise StudyError("--out", None, f"{out} would be both the table and its figure ({why})")
    if os.path.lexists(figure) and not _ours(figure):
        raise StudyError("--out", None, f"the figure's name {figure} is taken by a file "
                         "stickslip did not write: refusing to replace it, with or without "
                         "--force (name the table otherwise)")  # fmt: skip
    _check_out(figure, trace, replace)


def _check_out(out: str, trace: str, replace: bool) -> None:
    """--out never names the trace; an existing file needs --force."""
    from ..study import StudyError

    try:
        from .._output import check_output_file
    except ImportError:
        check_output_file = None
    if check_output_file is not None:
        from .._errors import OutputError

        try:
            check_output_file(out, inputs=[trace], force=replace)
        except OutputError as err:
            raise StudyError(None, None, str(err)) from None
        return
    if os.path.exists(trace) and os.path.exists(out) and os.path.samefile(out, trace):
        raise StudyError("--out", None, f"{out} is the input trace: choose another file")
    if os.path.isdir(out):
        raise StudyError("--out", None, f"{out} is a directory: name a file")
    if os.path.exists(out) and not replace:
        raise StudyError("--out", None, f"{out} exists: pass --force to replace it")
    parent = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(parent) or not os.access(parent, os.W_OK):
        raise StudyError("--out", None, f"cannot write in {parent}")


_CHUNK = 1 << 20  # bytes read at a time while a CSV is checked


def _read_trace(path: str, wanted) -> dict:
    """The columns `wanted` (those present) of a CSV or .mat trace; anything unreadable is
    a `StudyError` naming the problem, never the file's content."""
    from ..study import StudyError

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
        from .._simulate.driver import check_memory

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

    from ..study import StudyError

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

    from ..study import StudyError

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
    from ..study import StudyError

    t, *rest = wanted
    if t not in names or not (set(rest) & set(names)):
        need = " and ".join(rest) if len(rest) == 1 else "x and/or v"
        shown = ", ".join(names[:10]) + (", ..." if len(names) > 10 else "")
        raise StudyError(path, "columns", f"must include t and {need} (got {shown})")


def _figure(t, force, found, path: str) -> None:
    """A window of the trace (about five cycles) with each slip shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    release, slip = found["release_time"], found["slip_time"]
    start = release[0] - 0.5 * np.median(found["period"]) if len(found) else t[0]
    end = release[min(5, len(found) - 1)] + slip[min(5, len(found) - 1)] if len(found) else t[-1]
    sel = (t >= start) & (t <= end + 0.2 * (end - start))
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.plot(t[sel], force[sel], lw=0.6, color="0.3")
    for r, s in zip(release, slip, strict=True):
        if start <= r <= end:
            ax.axvspan(r, r + s, color="tab:red", alpha=0.3, lw=0)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("force (N)")
    ax.set_title(f"{len(found)} cycles; slips shaded")
    fig.tight_layout()
    fig.savefig(path, dpi=100, format="png", metadata={"Software": _PNG_SOFTWARE})
    plt.close(fig)
