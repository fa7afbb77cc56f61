"""`stickslip sweep`: run a study over values of one or more settings."""

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
@click.option(
    "--param",
    "-p",
    "params",
    multiple=True,
    required=True,
    metavar="KEY=V1,V2,...",
    help="A setting and its values, e.g. -p model.params.v_b=0.5,1,2 (repeatable).",
)
@click.option(
    "--zip",
    "zipped",
    is_flag=True,
    help="Take the values side by side instead of every combination.",
)
@output_options
@set_option
@dask_option
@handle_errors
def sweep(study, params, zipped, out, overrides, force, quiet, dask):
    """Run STUDY at each value of the --param settings (this replaces any sweep block)."""
    import yaml

    from .._output import check_output_dir
    from ..study import StudyError, load_study, run_study
    from ..study.load import parse_value
    from ..study.schema import short

    values = {}
    for item in params:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key or not text.strip():
            raise StudyError("--param", None, f"expected KEY=V1,V2,... (got {short(item)})")
        if key in values:
            raise StudyError("--param", key, "is given twice (list its values once: V1,V2,...)")
        try:
            values[key] = [parse_value(v) for v in text.split(",")]
        except yaml.YAMLError as err:
            reason = f"values {short(text)} are not valid YAML ({str(err).splitlines()[0]})"
            raise StudyError("--param", key, reason) from None
    block = {"parameters": values, "mode": "zip" if zipped else "product"}
    from ..study.load import sweep_override

    overrides = [*overrides, sweep_override(block)]
    if dask is not None:  # a bad study or --out is reported before any cluster starts
        load_study(study, overrides)
        check_output_dir(out, inputs=[study], force=force)
    with dask_client(dask) as client:
        run_study(
            study,
            out,
            client=client,
            overrides=overrides,
            force=force,
            progress=False if quiet else default_progress(),
        )
    report_written(out, quiet)
