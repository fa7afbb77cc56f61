"""`stickslip campaign`: every run of a campaign file read in its regime, one table, a
regime map."""

from __future__ import annotations

import click

from ._common import handle_errors, output_options


@click.command()
@click.argument("campaign_file", metavar="CAMPAIGN", type=click.Path(dir_okay=False, path_type=str))
@output_options
@handle_errors
def campaign(campaign_file, out, force, quiet):
    """Read every run CAMPAIGN lists in its regime (stick-slip, oscillation or steady
    sliding) and write runs.csv, runs.nc, regime_map.png and runs.png to --out.

    CAMPAIGN is a YAML file with `runs:`, a list of entries `file` (a CSV with a header or
    a MATLAB .mat file, relative to CAMPAIGN), `time` (default t), `force` (the force
    column, default force), `scale` (newtons per unit of it, default 1), `stiffness` (N/m),
    `v_b` (m/s), `mass` (kg, optional), `name`; and optionally `model: {name, params}`, a
    model with a critical stiffness whose predicted regions the regime map shades."""
    from .._output import check_output_dir
    from ..study.campaign import Campaign

    # the output folder checked before any run is read (it may not hold the campaign)
    check_output_dir(out, inputs=[campaign_file], force=force, what="--out")
    c = Campaign.from_yaml(campaign_file)
    paths = c.write(out, force=force)
    if not quiet:
        for run in c.runs:
            click.echo(f"{run!r}: {run.evidence}")
        click.echo(f"results in {out}/ ({', '.join(p.rsplit('/', 1)[-1] for p in paths)})")
