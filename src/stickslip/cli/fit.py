"""`stickslip fit`: estimate model parameters from measured cycles (a study's fit block)."""

from __future__ import annotations

import warnings

import click

from ._common import handle_errors, one_line, output_options, set_option


@click.command()
@click.argument("study", type=click.Path(dir_okay=True, path_type=str))
@output_options
@set_option
@handle_errors
def fit(study, out, overrides, force, quiet):
    """Fit the free parameters of STUDY's fit block to its data; write fit.json, fit.png and
    summary.md to --out. With candidates, fit each candidate model and choose the simplest
    the data do not reject (also fit_<name>.png per candidate and candidates.png). Each
    warning is one line on stderr (and in summary.md)."""
    from .._inference.compare import Comparison
    from ..study.fitting import run_fit

    caught = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            # a fit's warnings (UserWarning) each time, also when two candidates say the
            # same; other categories keep their filters (a DeprecationWarning stays hidden)
            warnings.simplefilter("always", UserWarning)
            result = run_fit(study, out, overrides=list(overrides), force=force,
                             progress=not quiet)  # fmt: skip
    finally:
        ours = [w for w in caught if _ours(w.filename) and issubclass(w.category, UserWarning)]
        for text in dict.fromkeys(one_line(w.message) for w in ours):  # in order, once
            click.echo(f"warning: {text}", err=True)
        for w in caught:  # another library's, or a deprecation: as Python shows it
            if w not in ours:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if not quiet:
        click.echo(result.summary())
        more = ", fit_<candidate>.png, candidates.png" if isinstance(result, Comparison) else ""
        click.echo(f"results in {out}/ (fit.json, fit.png{more}, summary.md)")


def _ours(filename) -> bool:
    """A warning issued from stickslip's code (a fit's, the model choice's)."""
    import pathlib

    return pathlib.Path(__file__).resolve().parents[1] in pathlib.Path(filename).resolve().parents
