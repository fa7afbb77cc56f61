"""`stickslip run`: run a study and write its data, figures and summary."""

from __future__ import annotations

import click

from ._common import handle_errors, set_option


@click.command()
@click.argument("study", type=click.Path(dir_okay=True, path_type=str))
@click.option(
    "--out",
    "-o",
    required=True,
    type=click.Path(path_type=str),
    help="Directory for results.nc, the figures and summary.md.",
)
@set_option
@click.option("--force", is_flag=True, help="Replace an existing, non-empty output directory.")
@click.option("--no-figures", is_flag=True, help="Write the data and summary only.")
@click.option("--quiet", "-q", is_flag=True, help="No progress messages or bars.")
@handle_errors
def run(study, out, overrides, force, no_figures, quiet):
    """Run the study in STUDY (a YAML file) and write the results to --out."""
    from ..study import run_study

    run_study(
        study,
        out,
        overrides=list(overrides),
        force=force,
        figures=not no_figures,
        progress=False if quiet else None,
    )
    if not quiet:
        click.echo(f"results in {out}/ (summary.md, results.nc, figures)")
