"""`stickslip run`: run a study and write its data, figures and summary."""

from __future__ import annotations

import click

from ._common import handle_errors, output_options, report_written, set_option


@click.command()
@click.argument("study", type=click.Path(dir_okay=True, path_type=str))
@output_options
@set_option
@click.option("--no-figures", is_flag=True, help="Write the data and summary only.")
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
    report_written(out, quiet)
