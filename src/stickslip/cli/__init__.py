"""The `stickslip` command line: one module per command.

Exit codes: 0 success, 2 bad input (one line on stderr naming the field and the reason),
1 a failure during a run (one line; `--debug` shows the traceback).
"""

from __future__ import annotations

import sys

import click

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


for _command in (run, validate, sweep, models, schema, cycles, fit):
    main.add_command(_command)
