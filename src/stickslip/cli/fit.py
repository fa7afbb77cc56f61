"""`stickslip fit`: estimate model parameters from measured cycles (a study's fit block)."""

from __future__ import annotations

import click

from ._common import handle_errors, output_options, set_option


@click.command()
@click.argument("study", type=click.Path(dir_okay=True, path_type=str))
@output_options
@set_option
@handle_errors
def fit(study, out, overrides, force, quiet):
    """Fit the free parameters of STUDY's fit block to its data; write fit.json, fit.png and
    summary.md to --out."""
    from ..study.fitting import run_fit

    result = run_fit(study, out, overrides=list(overrides), force=force, progress=not quiet)
    if not quiet:
        click.echo(result.summary())
        click.echo(f"results in {out}/ (fit.json, fit.png, summary.md)")
