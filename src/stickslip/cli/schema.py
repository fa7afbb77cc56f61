"""`stickslip schema`: the JSON schema of a study (or of one model's parameters)."""

from __future__ import annotations

import json

import click

from ._common import handle_errors


@click.command()
@click.option(
    "--model",
    "model_name",
    default=None,
    metavar="NAME",
    help="Print the schema of this model's parameters instead.",
)
@handle_errors
def schema(model_name):
    """Print the JSON schema of a study file."""
    from ..study import StudyError, study_schema

    if model_name is None:
        click.echo(json.dumps(study_schema(), indent=2))
        return
    from .. import list_models
    from ..study.schema import suggest

    models = list_models()
    if model_name not in models:
        raise StudyError(
            "--model",
            None,
            f"unknown model '{model_name}' (installed: {', '.join(models)})"
            + suggest(model_name, models),
        )
    click.echo(json.dumps(models[model_name].params_model().model_json_schema(), indent=2))
