"""`stickslip run`: run a study and write its data, figures and summary."""

from __future__ import annotations

import click

from ._common import (
    dask_client,
    dask_option,
    default_progress,
    handle_errors,
    output_options,
    report_written,
    set_option,
)


@click.command()
@click.argument("study", type=click.Path(dir_okay=True, path_type=str))
@output_options
@set_option
@click.option("--no-figures", is_flag=True, help="Write the data and summary only.")
@dask_option
@handle_errors
def run(study, out, overrides, force, no_figures, quiet, dask):
    """Run the study in STUDY (a YAML file) and write the results to --out."""
    from .._output import check_output_dir
    from ..study import load_study, run_study

    # A bad study, --out or --dask is reported before anything else (a cluster, the note
    # below), in one line.
    load_study(study, list(overrides))
    check_output_dir(out, inputs=[study], force=force)
    with dask_client(dask) as client:
        if not quiet:
            from .._compile import cold_note

            note = cold_note()
            if note:
                click.echo(note, err=True)
        run_study(
            study,
            out,
            client=client,
            overrides=list(overrides),
            force=force,
            figures=not no_figures,
            progress=False if quiet else default_progress(),
        )
    report_written(out, quiet)
