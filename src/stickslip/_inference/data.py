"""The data `fit` is given, and the measurement they went through.

The columns (`KINDS`) and the scale each is fitted on (`to_fit_scale`: durations on a log
scale).

A dict of per-cycle arrays holds per-cycle values of the model (no measurement); a `Cycles`
from `extract_cycles` carries its measurement (`measurement_of` reads it into a
`measurement.Measurement`, which the simulated cycles go through). Data that cannot be
fitted are refused with the evidence (`check_data`), never silently dropped; a dict that
looks sampled gets a warning (`looks_sampled`).
"""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np

from .._errors import DataError, ParameterError, StickSlipError
from ..quantities import names

KINDS = names("fit")  # the columns fitted
LOG_KINDS = names("fit", positive=True)  # positive durations: fitted on a log scale

# A column's density is a kernel estimate whose bandwidth comes from the data's spread, and
# the intervals from per-cycle scores: below 10 cycles, or 10 distinct values (a constant or
# a few repeated levels), there is no density to fit.
MIN_CYCLES = 10
DISTINCT_DIGITS = 1e-9  # values closer than this (relative, on the fitting scale) are one
MAX_LINEAR = 1e150  # a slip distance's spread is a sum of squares: it must stay finite


def to_fit_scale(kind, x):
    if kind in LOG_KINDS:
        x = x[x > 0]
        return np.log(x)
    return x


def measurement_of(data, trace=None, sampling=None, scales=None, owner: str = "fit"):
    """The data as a dict of columns and the measurement they went through: `(data,
    measurement)`, `measurement` a `Measurement` read from a `Cycles` (`None` for a dict:
    per-cycle values of the model). `trace` and `sampling` are the deprecated arguments
    the measurement replaced: honoured where they still mean something (a `Cycles` fitted
    as per-cycle values with `trace=False`), refused where they cannot (a dict has no
    extraction settings to model)."""
    import warnings

    from .._extract import Cycles
    from .measurement import Measurement

    if trace is not None and not isinstance(trace, (bool, np.bool_)):
        raise ParameterError(owner, "trace", "must be True or False", trace)
    is_cycles = isinstance(data, Cycles)
    if trace is not None or sampling is not None:
        warnings.warn(
            f"{owner}: trace= and sampling= are deprecated and will be removed: pass the Cycles "
            "from extract_cycles (or read_cycles of its CSV), which carry their measurement, "
            "or a dict of per-cycle values (no measurement)",
            DeprecationWarning,
            stacklevel=4,
        )
    if not is_cycles:
        if trace:
            raise ParameterError(
                owner, "trace", "cannot model a dict's measurement (it has no extraction "
                "settings): pass the Cycles from extract_cycles or read_cycles instead",
            )  # fmt: skip
        if sampling is not None:
            raise ParameterError(
                owner, "sampling", "is no longer used: pass the Cycles from extract_cycles or "
                "read_cycles, which carry their sampling interval",
                sampling,
            )  # fmt: skip
        if scales is not None:
            raise ParameterError(
                owner, "scales", "applies to a Cycles of a force trace only (a dict carries "
                "no measurement)",
            )  # fmt: skip
        return data, None
    if sampling is not None and not _same(sampling, data.info.get("sampling_interval")):
        raise ParameterError(
            owner, "sampling", "differs from the Cycles' own sampling interval "
            f"({data.info.get('sampling_interval')!r}): drop it",
            sampling,
        )  # fmt: skip
    table = {k: v for k, v in data.table.items() if k != "release_time"}
    if trace is False:  # the deprecated way to fit a table as per-cycle values
        return table, None
    try:
        measurement = Measurement.from_cycles(data, scales=scales)
    except ParameterError as err:  # said in fit's terms: its argument is `data`
        name = "scales" if err.parameter == "scales" else "data"
        raise ParameterError(owner, name, err.reason, err.value) from None
    if measurement.kind.in_si and not isinstance(data.info.get("si"), dict):
        # cycles of a force trace as extract_cycles gave them, in the trace's units (s, N,
        # m): the measurement was read in the model's units, so the table must be too, or
        # stick times in seconds would be scored against simulated ones in 1/omega0
        table = measurement.kind.to_model_units(table, scales, data.info)
    return table, measurement


def _same(a, b) -> bool:
    try:
        return bool(np.isclose(float(a), float(b), rtol=1e-9, atol=0.0))
    except (TypeError, ValueError):
        return False


def refusal(cls, parameter: str, reason: str, value: Any = None) -> StickSlipError:
    """A `DataError` or `ResourceError` about one of fit's arguments, worded as a
    `ParameterError` is; its `parameter`, `reason` and `value` are kept on it, as a
    `ParameterError` keeps them, for callers that re-phrase it (a study's fit)."""
    got = "" if value is None else f" (got {value!r})"
    err = cls(f"fit: parameter '{parameter}' {reason}{got}")
    err.owner, err.parameter, err.reason, err.value = "fit", parameter, reason, value
    return err


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _rows(index: np.ndarray) -> str:
    """The first few of some row numbers (0-based), for a message."""
    shown = ", ".join(str(int(i)) for i in index[:5])
    more = f" and {index.size - 5} more" if index.size > 5 else ""
    return f"row{'s' if index.size > 1 else ''} {shown}{more}"


def _column(name: str, value) -> np.ndarray:
    """One column of per-cycle values as a 1-D float array, or a `DataError` that says what
    it is instead (strings, objects, a table of several columns)."""
    where = f"data['{name}']"
    try:
        x = np.asarray(value)
    except (ValueError, TypeError):  # ragged nested lists
        raise refusal(
            DataError,
            where,
            f"must be a 1-D array of numbers, one per cycle (got a ragged {type(value).__name__})",
        ) from None
    if x.dtype.kind == "O" and all(
        isinstance(v, numbers.Real) and not isinstance(v, bool) for v in x.ravel()
    ):
        x = x.astype(float)
    if x.dtype.kind not in "iuf":
        what = {"U": "strings", "S": "bytes", "b": "booleans", "c": "complex numbers"}
        got = what.get(x.dtype.kind, type(value).__name__ if x.ndim == 0 else "other objects")
        raise refusal(
            DataError, where, f"must hold real numbers, one per cycle (got {got}, shape {x.shape})"
        )
    if x.ndim != 1:
        raise refusal(
            DataError,
            where,
            f"must be 1-D, one value per cycle (got shape {x.shape}"
            f"{', ' + str(x.size) + ' values' if x.ndim > 1 else ''})",
        )
    return x.astype(float)


def check_data(data, measured: bool = False) -> dict[str, np.ndarray]:
    """The known columns of a per-cycle table, as float arrays of one length. Unusable data
    are refused with the evidence (counts, shapes, rows), never silently dropped. With
    `measured` (the cycles of a trace), a slip time of 0 is allowed: `extract_cycles` times
    a slip within one sampling interval as 0, and the simulated cycles through the same
    extraction have such slips too (a point mass, as zero-length sticks are)."""
    if not hasattr(data, "keys") or not len(data):
        raise ParameterError(
            "fit", "data", f"must be a dict of per-cycle arrays ({', '.join(KINDS)})"
        )
    cols = {k: _column(k, data[k]) for k in data.keys() if k in KINDS}
    if not cols:
        raise ParameterError(
            "fit", "data", f"has none of the columns {', '.join(KINDS)}", sorted(map(str, data))
        )
    sizes = {k: x.size for k, x in cols.items()}
    if len(set(sizes.values())) > 1:
        raise refusal(
            DataError,
            "data",
            "columns must have one length, a row per cycle (the likelihood sums each cycle's "
            "columns; columns of different lengths are not rows of one table)",
            sizes,
        )
    for k, x in cols.items():
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise refusal(
                DataError,
                f"data['{k}']",
                f"has {_count(bad.size, 'non-finite value')} (nan or inf) among "
                f"{_count(x.size, 'cycle')}, at {_rows(bad)}: remove or fix those cycles",
            )
        positive = k == "period" or (k == "slip_time" and not measured)
        if positive and np.any(x <= 0):
            hint = "" if k == "period" else "; a trace's cycles time a slip as 0: pass the Cycles"
            raise ParameterError(
                "fit", f"data['{k}']", f"must be > 0 (slips of positive length{hint})"
            )
        if k in LOG_KINDS and not positive and np.any(x < 0):
            raise ParameterError("fit", f"data['{k}']", "must be >= 0")
        if k not in LOG_KINDS and np.max(np.abs(x), initial=0.0) > MAX_LINEAR:
            raise refusal(
                DataError,
                f"data['{k}']",
                f"reaches {np.max(np.abs(x)):.3g}, past {MAX_LINEAR:.0e}: its spread would "
                "overflow",
            )
        _check_spread(k, x)
    return cols


def _check_spread(kind: str, x: np.ndarray) -> None:
    """At least `MIN_CYCLES` values whose density is fitted (the positive ones, on a log
    scale, for durations) and as many distinct ones (to `DISTINCT_DIGITS`, on that scale)."""
    y = to_fit_scale(kind, x)
    scale = max(float(np.max(np.abs(y), initial=0.0)), 1.0 if kind in LOG_KINDS else 0.0)
    distinct = np.unique(np.round(y / (DISTINCT_DIGITS * scale))).size if scale > 0 else 1
    distinct = min(distinct, y.size)
    if y.size >= MIN_CYCLES and distinct >= MIN_CYCLES:
        return
    evidence = _count(x.size, "cycle")
    if y.size < x.size:
        evidence += f", {y.size} of them positive (a log scale is fitted)"
    evidence += f", {_count(distinct, 'distinct value')}"
    if x.size < MIN_CYCLES:
        what = "has too few cycles"
    elif y.size < MIN_CYCLES:
        what = "has too few positive values"
    else:
        what = "is constant" if distinct == 1 else "has too few distinct values"
    raise refusal(
        DataError,
        f"data['{kind}']",
        f"{what}: {evidence}; a density needs at least {MIN_CYCLES} of each (its kernel's "
        "bandwidth comes from the data's spread)",
    )


def looks_sampled(given, cols: dict[str, np.ndarray]) -> str | None:
    """A warning when data given as per-cycle truths (a dict) look like the cycles of a
    sampled trace, which a trace's measurement would have to model (pass the `Cycles`)."""
    meta = getattr(given, "attrs", None)
    interval = getattr(given, "sampling_interval", None)
    if interval is None and hasattr(meta, "get"):
        interval = meta.get("sampling_interval")
    advice = (
        "a dict is fitted as per-cycle values of the model; pass the Cycles from "
        "extract_cycles (or read_cycles of its CSV) so that its measurement is modelled"
    )
    if interval is not None:
        return f"the data carry a sampling interval ({interval!r}) but {advice}"
    durations = [cols[k] for k in ("slip_time", "stick_time", "period") if k in cols]
    pooled = np.unique(np.concatenate(durations)) if durations else np.array([])
    pooled = pooled[pooled > 0]
    if pooled.size >= MIN_CYCLES:
        step = float(np.min(np.diff(np.r_[0.0, pooled])))
        ratio = pooled / step
        if step > 1e-9 * pooled[-1] and np.all(np.abs(ratio - np.round(ratio)) < 1e-3):
            return f"every duration is a multiple of {step:.4g} (a sampled trace's grid): {advice}"
    if "release_time" in getattr(given, "keys", lambda: ())() and "stick_time" in cols:
        if cols["stick_time"].size >= MIN_CYCLES and np.all(cols["stick_time"] > 0):
            return (
                f"the data have release times and no stick of zero length in "
                f"{cols['stick_time'].size} cycles, as cycles extracted from a trace do: {advice}"
            )
    return None
