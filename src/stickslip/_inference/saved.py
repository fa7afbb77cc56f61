"""A fit on disk: `FitResult.save(path)` writes it (`save_fit`); `loaded.load_fit` reads it.

One JSON file (readable, diffable, and loaded without executing anything: no pickle):
the model by its registered name and the arguments that rebuild it, the estimate, the
intervals, the log-likelihood, the data's columns, the measurement, the settings and the
diagnostics (the evaluated points, the covariance and Hessian, the design's points and
values, the warnings) and the goodness of fit when there was one. Not kept: the cycles the
fit simulated at its design points (`compare_fits` simulates them again, the same cycles:
a function of the point and the seed). A loaded fit simulates, plots, compares and checks
as the one saved (`simulated()` gives the same cycles for the same seed).
"""

from __future__ import annotations

import dataclasses
import json
import os
import pathlib

import numpy as np

from .._errors import ParameterError

FORMAT = "stickslip fit"
VERSION = 1
# What of `diagnostics` is written (the rest is rebuilt: `to_fit` from the scales, the
# measurement's aliases `observe`, `trace` and `sampling` from it).
_KEPT = ("n_sim", "dt", "t_max", "seed", "n_data", "zero_fraction", "bandwidth", "scales",
         "box", "covariance", "hessian", "evaluations", "points", "seconds", "warnings",
         "optimizer", "design", "mc_noise", "dependence", "runs", "profile")  # fmt: skip
# The SI mapping a fit was given (`scales=`), by its class.
UNITS = ("Slider", "Scales")


def jsonable(value):
    """JSON-ready values: NumPy scalars and arrays to Python, dataclasses to dicts, tuples
    to lists (non-finite floats stay, as JSON's NaN and Infinity extensions)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return jsonable(dataclasses.asdict(value))
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def save_fit(result, path) -> pathlib.Path:
    """Write `result` (a `FitResult`) to `path` as JSON, through a temporary file renamed
    into place (a file already there is replaced whole or not at all). Returns the path."""
    from .._registry import model_name
    from .params import model_kwargs

    path = pathlib.Path(path)
    d = result.diagnostics
    params = jsonable(model_kwargs(result.model))
    try:
        json.dumps(params)
    except TypeError as err:
        raise ParameterError(
            "FitResult.save", "model", f"has parameters JSON cannot hold ({err}); a model "
            "whose parameters are numbers, strings, lists and dicts can be saved",
        ) from None  # fmt: skip
    design = dict(d.design or {})
    design["samples"] = None  # simulated again where needed (the same cycles)
    diagnostics = {k: getattr(d, k) for k in _KEPT if getattr(d, k) is not None}
    diagnostics["design"] = design
    measurement = d.measurement
    units = d.units
    if units is not None:
        units = dict(dataclasses.asdict(units), kind=type(units).__name__)
    document = dict(
        format=FORMAT, version=VERSION, stickslip=_version(),
        model=model_name(type(result.model)), params=params,
        estimate=result.estimate, ci=result.ci, log_likelihood=result.log_likelihood,
        method=result.method, data=result.data,
        measurement=None if measurement is None else dataclasses.asdict(measurement),
        diagnostics=diagnostics, units=units,
        goodness=None if result.goodness is None else _goodness(result.goodness),
    )  # fmt: skip
    text = json.dumps(jsonable(document), indent=1)
    part = path.with_name(f".{path.name}.partial-{os.getpid()}")
    try:
        part.write_text(text)
        os.replace(part, path)
    finally:
        part.unlink(missing_ok=True)
    return path


def _goodness(goodness) -> dict:
    """A goodness of fit's fields, its statistic by class name, symbol and words."""
    out = {f.name: getattr(goodness, f.name) for f in dataclasses.fields(goodness)}
    s = goodness.statistic
    out["statistic"] = dict(kind=type(s).__name__, name=s.name, symbol=s.symbol)
    return out


def _version() -> str:
    from .. import __version__

    return str(__version__)
