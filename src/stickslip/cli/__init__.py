"""The `stickslip` command line: one module per command."""

from __future__ import annotations

import click

from .models import models


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="stickslip")
def main():
    """Statistics of frictional stick-slip motion."""


main.add_command(models)
