"""`stickslip validate`: check a study without running it."""

from __future__ import annotations

import click

from ._common import handle_errors, set_option


@click.command()
@click.argument("study", type=click.Path(dir_okay=True, path_type=str))
@set_option
@handle_errors
def validate(study, overrides):
    """Check STUDY (a YAML file): exit 0 and a one-line description if it is valid, exit 2
    and one line naming the bad field otherwise."""
    from ..study import load_study

    s = load_study(study, list(overrides))
    points = len(s.points())
    parts = [f"model {s.model.name}"]
    if s.method == "auto":
        parts.append(f"method auto (L1 <= {s.tolerance:g}; chosen when run)")
    else:
        if s.simulation is not None:
            parts.append(f"{s.simulation.n_paths} paths")
        parts.append(f"{len(s.analytic)} analytic method(s)")
    parts.append("outputs " + ", ".join(s.resolved_outputs()))
    if points > 1:
        parts.append(f"{points} sweep points")
    if s.fit is not None and s.fit.candidates is not None:
        names = ", ".join(c.name for c in s.fit.candidates)
        parts.append(f"fit: {len(s.fit.candidates)} candidates ({names})")
    elif s.fit is not None:
        parts.append(f"fit: {', '.join(s.fit.free)} free")
    click.echo(f"ok: {study}: " + "; ".join(parts))
