"""The `stickslip` command line: one module per command.

Exit codes: 0 success, 2 bad input (one line on stderr naming the field and the reason),
1 a failure during a run (one line; `--debug` shows the traceback).
"""

from __future__ import annotations

import atexit
import os
import sys
import threading

import click

from .cache import cache
from .campaign import campaign
from .cycles import cycles
from .fit import fit
from .models import models
from .run import run
from .schema import schema
from .sweep import sweep
from .validate import validate


class _Group(click.Group):
    """Usage errors (a missing argument, an unknown option) as one line, exit 2."""

    def main(self, args=None, prog_name=None, **extra):
        try:
            return super().main(args, prog_name, standalone_mode=False, **extra)
        except click.exceptions.Exit as stop:  # --help, --version
            sys.exit(stop.exit_code)
        except click.UsageError as err:
            where = f"{err.ctx.command_path}: " if err.ctx is not None else ""
            hint = f" (see '{err.ctx.command_path} --help')" if err.ctx is not None else ""
            click.echo(f"error: {where}{err.format_message()}{hint}", err=True)
            sys.exit(2)
        except click.ClickException as err:
            click.echo(f"error: {err.format_message()}", err=True)
            sys.exit(err.exit_code)
        except click.Abort:
            click.echo("aborted", err=True)
            sys.exit(1)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="stickslip")
def main():
    """Statistics of frictional stick-slip motion."""


for _command in (run, validate, sweep, models, schema, cycles, fit, cache, campaign):
    main.add_command(_command)


def console():
    """The `stickslip` command (and `python -m stickslip.cli`): `main`, then `quick_exit`."""
    try:
        main()
    except SystemExit as stop:
        quick_exit(stop.code)
    quick_exit(0)


def quick_exit(code):
    """Leave as `sys.exit(code)` would, without the interpreter's teardown after it.

    Once a run is done, freeing its compiled programs and modules one by one took 0.55-1.15 s
    on 2 cores (the README's main job and a simulation of the public set: the time from the
    command's end to the process's, measured against `os._exit`). Here the exit handlers all
    run (`atexit`: JAX's, logging's, Dask's), the streams are flushed, and the process ends.
    Where that could lose something it exits the ordinary way instead: a code that is not
    an int, or a thread still running that is not a daemon (a plugin's; the simulator's own
    pool of idle refinement threads is shut down first)."""
    if code is not None and not isinstance(code, int):
        sys.exit(code)
    bridge = sys.modules.get("stickslip._simulate.bridge")  # (not imported: no pool)
    ours = bridge.POOL_THREADS if bridge is not None else None
    main_thread = threading.main_thread()
    if any(
        t is not main_thread and not t.daemon and not (ours and t.name.startswith(ours))
        for t in threading.enumerate()
    ):
        sys.exit(code)
    if bridge is not None and bridge._pool.cache_info().currsize:
        bridge._pool().shutdown(wait=True)
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None:  # (`None`: the process started with it closed)
                stream.flush()
        except (OSError, ValueError):  # closed, or a closed pipe: as the ordinary exit
            pass
    os._exit(code or 0)
