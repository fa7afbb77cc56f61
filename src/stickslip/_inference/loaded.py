"""`load_fit(path)`: a fit saved by `FitResult.save` (`saved`), read back."""

from __future__ import annotations

import json
import math
import pathlib

import numpy as np

from .._errors import DataError
from .saved import FORMAT, UNITS, VERSION


def load_fit(path):
    """The `FitResult` saved at `path` (`FitResult.save`).

    **Raises:** `DataError` for a file that is not a saved fit (not JSON, another format,
    a newer version, a field missing), naming the file and what is wrong; `PluginError`
    where its model is not installed."""
    from .._registry import get_model
    from .diagnostics import FitDiagnostics
    from .goodness import GoodnessOfFit
    from .measurement import Measurement
    from .params import ToFit
    from .result import FitResult
    from .statistics import saved_statistic

    path = pathlib.Path(path)
    try:
        document = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise DataError(f"load_fit: {path} cannot be read as a saved fit: {err}") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise DataError(f"load_fit: {path} is not a saved stickslip fit (no '{FORMAT}' format)")
    if document.get("version", math.inf) > VERSION:
        raise DataError(
            f"load_fit: {path} was saved in format version {document.get('version')} by "
            f"stickslip {document.get('stickslip')}; this version reads up to {VERSION}"
        )
    need = ("model", "params", "estimate", "ci", "log_likelihood", "method", "data",
            "measurement", "diagnostics", "goodness")  # fmt: skip
    missing = [k for k in need if k not in document]
    if missing:
        raise DataError(f"load_fit: {path} lacks {', '.join(missing)}")
    model = get_model(document["model"])(**document["params"])
    data = {k: np.asarray(v, float) for k, v in document["data"].items()}
    measurement = document["measurement"]
    if measurement is not None:
        if measurement.get("thresholds") is not None:
            measurement["thresholds"] = dict(measurement["thresholds"])
        for key in ("lines", "columns"):
            measurement[key] = tuple(measurement[key])
        measurement = Measurement(**measurement)
    d = FitDiagnostics.from_mapping(document["diagnostics"])
    d.measurement, d.to_fit = measurement, ToFit(d.scales)
    d.points = [(np.asarray(x, float), float(v)) for x, v in d.points]
    if d.box is not None:
        d.box = {k: tuple(v) for k, v in d.box.items()}
    d.units = _units(document.get("units"), path)
    goodness = document["goodness"]
    if goodness is not None:
        for key in ("replicates", "data", "reference"):
            goodness[key] = {k: np.asarray(v, float) for k, v in goodness[key].items()}
        goodness["statistic"] = saved_statistic(goodness.get("statistic"))
        goodness = GoodnessOfFit(**goodness)
    return FitResult(
        estimate={k: float(v) for k, v in document["estimate"].items()},
        ci={k: (float(a), float(b)) for k, (a, b) in document["ci"].items()},
        log_likelihood=float(document["log_likelihood"]), method=document["method"],
        diagnostics=d, data=data, model=model, goodness=goodness,
    )  # fmt: skip


def _units(saved, path):
    """The `Slider` or `Scales` a fit was given, from its saved fields (None if none)."""
    from ..units import Scales, Slider

    if saved is None:
        return None
    kind = saved.pop("kind", None)
    if kind not in UNITS:
        raise DataError(f"load_fit: {path}: its units are of an unknown kind ({kind!r})")
    if kind == "Scales":
        return Scales(**saved)
    if saved.get("threshold") is not None:
        law, params = saved["threshold"]
        saved["threshold"] = (law, dict(params))
    return Slider(**saved)
