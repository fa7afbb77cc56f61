"""`stickslip cycles`: per-cycle stick-slip statistics from a measured trace (CSV or .mat)."""

from __future__ import annotations

import os

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
    from ..extract import extract_cycles
    from ..study import StudyError

    if out is not None:
        _check_out(out, trace, replace)
        if force_column:  # the figure goes beside the table
            _check_out(os.path.splitext(out)[0] + ".png", trace, replace)
    wanted = ("t", force_column) if force_column else ("t", "x", "v")
    columns = _read_trace(trace, wanted)
    try:
        if force_column:
            if stiffness is None:
                raise StudyError("--stiffness", None, "is required with --force-column (N/m)")
            found = extract_cycles(
                columns["t"], force=columns[force_column] * force_scale,
                stiffness=stiffness, v_b=v_b,
            )  # fmt: skip
        else:
            if v_b is None:
                raise StudyError("--v-b", None, "is required with an x/v trace")
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
    tmp = f"{out}.tmp{os.getpid()}"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(tmp, out)
    figure = os.path.splitext(out)[0] + ".png"
    if force_column:
        _figure(columns["t"], columns[force_column] * force_scale, found, figure)
    mean = found.table["slip_time"].mean() if len(found) else float("nan")
    click.echo(f"{len(found)} cycles (mean slip time {mean:.4g}) in {out}")


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


def _read_trace(path: str, wanted) -> dict:
    """The columns `wanted` (those present) of a CSV or .mat trace; anything unreadable is
    a `StudyError` naming the problem, never the file's content."""
    from ..study import StudyError

    if not os.path.isfile(path):
        raise StudyError(path, None, "no such file")
    if path.lower().endswith(".mat"):
        return _read_mat(path, wanted)
    import numpy as np

    try:
        with open(path, encoding="utf-8-sig") as f:
            text = f.read()
    except UnicodeDecodeError as err:
        raise StudyError(path, None, f"is not a UTF-8 text CSV (undecodable byte at offset "
                         f"{err.start}); give a CSV or a .mat file") from None  # fmt: skip
    except OSError as err:
        raise StudyError(path, None, f"cannot read the file ({err.strerror})") from None
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    if not lines:
        raise StudyError(path, None, "is empty: expected a header with columns t and x and/or v")
    names = [n.strip() for n in lines[0].split(",")]
    if not all(n.isprintable() and len(n) <= 64 for n in names):
        raise StudyError(path, "columns", "the header holds unprintable or over-long names")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise StudyError(path, "columns", f"name {', '.join(twice)} more than once")
    _check_columns(path, names, wanted)
    if len(lines) < 2:
        raise StudyError(path, None, "has a header but no data rows")
    try:
        data = np.array([[float(c) for c in line.split(",")] for line in lines[1:]], ndmin=2)
    except ValueError:
        raise StudyError(path, None, "holds a value that is not a number") from None
    except Exception:  # ragged rows
        raise StudyError(
            path, None, f"rows must have {len(names)} values, like the header"
        ) from None
    if data.shape[1] != len(names):
        raise StudyError(path, None, f"rows must have {len(names)} values, like the header")
    return {n: data[:, k] for k, n in enumerate(names) if n in wanted}


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
    fig.savefig(path, dpi=100)
    plt.close(fig)
