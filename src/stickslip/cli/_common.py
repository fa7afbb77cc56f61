"""What every command shares: bad input exits 2 with one line, failures exit 1."""

from __future__ import annotations

import contextlib
import functools
import sys

import click

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130


MAX_MESSAGE = 300  # characters of an error line: enough to name the field and the reason


def one_line(text: str, limit: int = MAX_MESSAGE) -> str:
    """`text` as one printable line of at most `limit` characters: line breaks become
    spaces, other control characters are escaped, and a longer text ends in '...'."""
    text = " ".join(str(text).split())
    text = "".join(c if c.isprintable() else ascii(c)[1:-1] for c in text)
    return text if len(text) <= limit else text[: limit - 3].rstrip() + "..."


def _bad_input() -> tuple[type[BaseException], ...]:
    """The errors that mean bad input (exit 2): the study, a value, the data, a size past a
    limit, an output location."""
    from .._errors import DataError, OutputError, ParameterError, ResourceError
    from ..study import StudyError

    return (StudyError, ParameterError, DataError, ResourceError, OutputError)


def handle_errors(func):
    """Run a command body: bad input (a `StudyError`, `ParameterError`, `DataError`,
    `ResourceError` or `OutputError`) is one line on stderr and exit 2; any other error is
    one line and exit 1, with the traceback under `--debug`."""

    @functools.wraps(func)
    def wrapper(*args, debug: bool = False, **kwargs):
        from .._output import catch_interrupts

        caught = catch_interrupts()
        try:
            with caught:
                done = func(*args, **kwargs)
        except _bad_input() as err:
            click.echo(f"error: {one_line(err)}", err=True)
            sys.exit(EXIT_BAD_INPUT)
        except KeyboardInterrupt:
            click.echo("interrupted: nothing was written under the output name", err=True)
            sys.exit(EXIT_INTERRUPTED)
        except Exception as err:  # a failure during the run
            if _from_an_interrupt(err):
                click.echo("interrupted: nothing was written under the output name", err=True)
                sys.exit(EXIT_INTERRUPTED)
            if debug:
                raise
            text = one_line(f"{type(err).__name__}: {err}".rstrip(": "))
            click.echo(f"error: run failed: {text} (--debug shows the traceback)", err=True)
            sys.exit(EXIT_FAILURE)
        if caught.caught:  # one that came after the results were in place
            click.echo("interrupted: the results were complete and are written", err=True)
            sys.exit(EXIT_INTERRUPTED)
        return done

    return click.option("--debug", is_flag=True, help="Show the full traceback of a failure.")(
        wrapper
    )


def _from_an_interrupt(err: BaseException) -> bool:
    """Whether an interrupt is what `err` wraps: Python turns a `KeyboardInterrupt` that
    lands in some places into another error with the interrupt as its cause (in a class
    body's `__set_name__`, during an import: "RuntimeError: Error calling __set_name__"),
    which is still the user's Ctrl-C, not a failure."""
    seen = set()
    while err is not None and id(err) not in seen:
        if isinstance(err, KeyboardInterrupt):
            return True
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return False


def set_option(func):
    return click.option(
        "--set",
        "overrides",
        multiple=True,
        metavar="KEY=VALUE",
        help="Override a setting (dotted key, YAML value), e.g. --set simulation.n_paths=2000.",
    )(func)


def output_options(func):
    """`--out`, `--force` and `--quiet`, shared by the commands that write results."""
    func = click.option("--quiet", "-q", is_flag=True, help="No progress messages or bars.")(func)
    func = click.option(
        "--force",
        is_flag=True,
        help="Replace the results of an earlier run in --out (never a folder of other files).",
    )(func)
    return click.option(
        "--out",
        "-o",
        required=True,
        type=click.Path(path_type=str),
        help="Directory for results.nc, the figures and summary.md.",
    )(func)


def default_progress():
    """A run's progress on stderr: bars on a terminal, else a line per stage (a long run
    writing to a log file said nothing until its end)."""
    return None if sys.stderr.isatty() else "lines"


def report_written(out: str, quiet: bool):
    if not quiet:
        click.echo(f"results in {out}/ (summary.md, results.nc, figures)")


def dask_option(func):
    return click.option(
        "--dask",
        "dask",
        metavar="ADDRESS|local",
        default=None,
        help="Run on a Dask cluster: a scheduler address (tcp://host:8786) or 'local' (one "
        "worker process per CPU it may use); sweep points run as tasks, a single point's paths as "
        'blocks. Needs pip install "stickslip[dask]".',
    )(func)


@contextlib.contextmanager
def dask_client(address: str | None):
    """The client of `--dask` (None without it) for the length of a command; a scheduler
    that cannot be reached, or no dask installed, is bad input (one line, exit 2)."""
    if address is None:
        yield None
        return
    from .. import _distributed
    from .._errors import ParameterError
    from ..study import StudyError

    try:
        client, owned = _distributed.connect("--dask", address)
    except ParameterError as err:
        raise StudyError("--dask", None, err.reason) from None
    try:
        yield client
    finally:
        _distributed.close(client, owned)
