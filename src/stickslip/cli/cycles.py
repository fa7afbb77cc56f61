"""`stickslip cycles`: per-cycle stick-slip statistics from a measured trace (a CSV file)."""

from __future__ import annotations

import click

from ._common import handle_errors


@click.command()
@click.argument("trace", type=click.Path(dir_okay=False, path_type=str))
@click.option("--v-b", "v_b", type=float, required=True, help="The driving (belt) speed, > 0.")
@click.option(
    "--tol",
    type=float,
    default=None,
    help="A sample is stuck when |v - v_b| <= tol (default: 5 robust sd of the noise).",
)
@click.option(
    "--out",
    "-o",
    type=click.Path(dir_okay=False, path_type=str),
    default=None,
    help="Write the table here and print a one-line summary (default: the table to stdout).",
)
@handle_errors
def cycles(trace, v_b, tol, out):
    """Find the stick-slip cycles in TRACE and write one row per complete cycle.

    TRACE is a CSV file with a header naming the columns `t` (times, increasing) and `x`
    (position) and/or `v` (velocity). The table has the columns release_time, slip_time,
    slip_distance, stick_time and period (see `stickslip.extract_cycles`).
    """
    from .._errors import ParameterError
    from ..extract import extract_cycles
    from ..study import StudyError

    columns = _read_trace(trace)
    try:
        found = extract_cycles(columns["t"], columns.get("x"), columns.get("v"), v_b=v_b, tol=tol)
    except ParameterError as err:  # bad data or options: bad input, exit 2
        raise StudyError(trace, err.parameter, err.reason) from None
    text = found.to_csv(out)
    if out is None:
        click.echo(text, nl=False)
    else:
        mean = found.table["slip_time"].mean()
        click.echo(
            f"{len(found)} cycles (mean slip time {mean:.4g}, tol {found.info['tol']:.3g}) in {out}"
        )


def _read_trace(path: str) -> dict:
    """The columns t, x, v of a CSV trace; anything unreadable is a `StudyError`."""
    import numpy as np

    from ..study import StudyError

    try:
        with open(path) as f:
            header = f.readline().strip()
            body = f.read()
    except OSError as err:
        raise StudyError(path, None, f"cannot read the file ({err.strerror})") from None
    names = [n.strip() for n in header.split(",")] if header else []
    if not names:
        raise StudyError(path, None, "is empty: expected a header with columns t and x and/or v")
    if "t" not in names or not ({"x", "v"} & set(names)):
        raise StudyError(path, "columns", f"must include t and x and/or v (got {', '.join(names)})")
    rows = [line for line in body.splitlines() if line.strip()]
    if not rows:
        raise StudyError(path, None, "has a header but no data rows")
    try:
        data = np.array([[float(c) for c in line.split(",")] for line in rows], ndmin=2)
    except ValueError as err:
        raise StudyError(path, None, f"holds a value that is not a number ({err})") from None
    if data.shape[1] != len(names):
        raise StudyError(path, None, f"rows must have {len(names)} values, like the header")
    columns = {n: data[:, k] for k, n in enumerate(names) if n in ("t", "x", "v")}
    if np.any(columns["t"] < 0):
        raise StudyError(path, "t", "times must be >= 0")
    return columns
