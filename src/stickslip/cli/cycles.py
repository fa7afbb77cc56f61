"""`stickslip cycles`: per-cycle stick-slip statistics from a measured trace (CSV or .mat)."""

from __future__ import annotations

import os
import pathlib
import sys

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
@click.option(
    "--kind",
    default=None,
    metavar="NAME",
    help="A trace kind from a plugin (`stickslip.trace_kinds`): its inputs are read from "
    "the columns of their names, its settings from --option.",
)
@click.option(
    "--option",
    "options",
    multiple=True,
    metavar="KEY=VALUE",
    help="With --kind: a setting of that kind (a number, or text); repeat for more.",
)
@click.option("--force", "replace", is_flag=True, help="Replace an existing --out file.")
@handle_errors
def cycles(trace, v_b, force_column, force_scale, stiffness, tol, kind, options, out, replace):
    """Find the stick-slip cycles in TRACE and write one row per complete cycle.

    TRACE is a CSV file with a header naming the columns (`t` and `x` and/or `v`, or a force
    column named by --force-column) or a MATLAB .mat file holding those variables. The
    table has the columns release_time, slip_time, slip_distance, stick_time and period
    (and peak_force, force_drop with a force), after a `#` block with every setting used
    (see `stickslip.extract_cycles`). A trace of another kind (a plugin's) is read with
    --kind NAME, its inputs from the columns named like them.
    """
    from .._errors import DataError, ParameterError
    from .._output import check_interrupted, clean_file_leftovers
    from ..extract import extract_cycles
    from ..study import StudyError

    plugin = _plugin_kind(kind, options, force_column, stiffness, tol, force_scale)
    if plugin is None:
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
    if plugin is not None:
        wanted = ("t", *plugin[0].inputs)
    from ..study.traces import read_trace

    columns = read_trace(trace, wanted)
    try:
        if plugin is not None:
            given = {k: columns[k] for k in plugin[0].inputs if k in columns}
            found = extract_cycles(columns["t"], v_b=v_b, **given, **plugin[1])
        elif force_column:
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
        reason = str(err).removeprefix("extract_cycles: ")
        if force_column and v_b is not None:  # say which regime the run is in instead
            reason = _regime(columns["t"], columns[force_column] * force_scale, stiffness,
                             v_b) or reason  # fmt: skip
        raise StudyError(trace, None, reason) from None
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


def _regime(t, force, stiffness, v_b) -> str | None:
    """A force trace without cycles read in its regime (`analyse_run`): 'no cycles: the
    run is an oscillation: (evidence)', or None where it is stick-slip by its shape."""
    from ..extract import analyse_run

    try:
        run = analyse_run(t, force, stiffness=stiffness, v_b=v_b)
    except Exception:  # the extraction's own reason stands
        return None
    if run.regime == "stick-slip":
        return None
    what = "an oscillation" if run.regime == "oscillation" else "steady sliding"
    return f"no cycles: the run is {what}: {run.evidence}"


def _plugin_kind(kind, options, force_column, stiffness, tol, force_scale):
    """`(kind, settings)` for `--kind NAME` with its `--option KEY=VALUE` settings (numbers
    where they read as one), or None without --kind; the built-in kinds' options are
    refused beside it."""
    import json

    from ..study import StudyError

    if kind is None:
        if options:
            raise StudyError("--option", None, "applies with --kind only")
        return None
    from .._errors import PluginError
    from ..trace_kinds import get_trace_kind

    try:
        found = get_trace_kind(kind)()
    except PluginError as err:
        raise StudyError("--kind", None, str(err)) from None
    if type(found).__module__ == "stickslip.trace_kinds":
        raise StudyError("--kind", None, f"names a plugin's kind: a {found.name} trace is read "
                         "with --force-column (a force) or from its t, x, v columns")  # fmt: skip
    for name, given in (("--force-column", force_column), ("--stiffness", stiffness),
                        ("--tol", tol), ("--force-scale", force_scale != 1.0 or None)):  # fmt: skip
        if given is not None:
            raise StudyError(name, None, "applies to the built-in kinds: with --kind, give "
                             "the kind's settings as --option KEY=VALUE")  # fmt: skip
    settings = {}
    for item in options:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise StudyError("--option", None, f"must be KEY=VALUE (got {item!r})")
        try:
            settings[key.strip()] = json.loads(value)
        except ValueError:
            settings[key.strip()] = value
    return found, settings


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
    from .._output import real_number
    from ..study import StudyError

    if real_number(figure) == real_number(out):
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
