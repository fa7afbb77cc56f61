"""`stickslip models`: the installed model plugins and their parameters."""

from __future__ import annotations

import dataclasses
import warnings

import click


@click.command()
@click.option("--names", is_flag=True, help="Print only the model names, one per line.")
def models(names: bool):
    """List the friction models found through the `stickslip.models` entry points."""
    from .. import list_models

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        found = list_models()
    for w in caught:  # broken plugins: named, but not fatal
        click.echo(f"warning: {w.message}", err=True)
    for name, cls in found.items():
        if names:
            click.echo(name)
            continue
        doc = (cls.__doc__ or "").strip().splitlines()
        click.echo(f"{name}  ({cls.__module__}.{cls.__qualname__})")
        if doc:
            click.echo(f"    {doc[0]}")
        params = []
        for pname, default in cls.parameters().items():
            if default is dataclasses.MISSING:
                params.append(pname)
            else:
                params.append(f"{pname}={default!r}")
        click.echo(f"    parameters: {', '.join(params)}")
