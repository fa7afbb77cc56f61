"""Checks shared by the trace readers: every bad value is a `ParameterError` naming it."""

from __future__ import annotations

import numpy as np

from .._errors import ParameterError

OWNER = "extract_cycles"


def as_series(name: str, value, *, required: bool = False) -> np.ndarray | None:
    """`value` as a finite 1-D float array (None stays None unless `required`)."""
    if value is None:
        if required:
            raise ParameterError(OWNER, name, "is required: give an array of sample values")
        return None
    if isinstance(value, (str, bytes)):
        raise ParameterError(OWNER, name, "must be an array of real numbers, not a string")
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raise ParameterError(OWNER, name, "must be an array of real numbers") from None
    if raw.dtype.kind not in "biuf":
        if raw.dtype.kind != "O":
            kind = {"U": "strings", "S": "bytes", "c": "complex numbers"}.get(
                raw.dtype.kind, f"dtype {raw.dtype}"
            )
            raise ParameterError(OWNER, name, f"must be an array of real numbers (got {kind})")
        if any(isinstance(v, (str, bytes)) for v in raw.ravel()):
            raise ParameterError(OWNER, name, "must be an array of real numbers (got strings)")
    try:
        a = np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(OWNER, name, "must be an array of real numbers") from None
    if a.ndim != 1:
        raise ParameterError(OWNER, name, f"must be 1-D (got shape {a.shape})")
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        raise ParameterError(
            OWNER, name, f"must be finite: {bad.size} NaN/inf value(s), the first at index "
            f"{bad[0]}",
        )  # fmt: skip
    return a


def check_times(t: np.ndarray, *, minimum: int = 3) -> None:
    if t.size < minimum:
        raise ParameterError(OWNER, "t", f"needs at least {minimum} samples (got {t.size})")
    step = np.diff(t)
    bad = np.flatnonzero(~(step > 0))
    if bad.size:
        k = int(bad[0])
        raise ParameterError(
            OWNER, "t", f"must be strictly increasing: t[{k + 1}] = {t[k + 1]!r} follows "
            f"t[{k}] = {t[k]!r} ({bad.size} such step(s))",
        )  # fmt: skip


def check_length(name: str, a: np.ndarray | None, n: int) -> None:
    if a is not None and a.size != n:
        raise ParameterError(OWNER, name, f"must have the length of t ({n}), got {a.size}")


def power_of_two(scale: float) -> float:
    """The power of 2 nearest above `scale` (> 0): dividing by it is exact, so a trace
    and the same trace times 2**k give the same cycles bit for bit."""
    if not scale > 0 or not np.isfinite(scale):
        return 1.0
    return float(np.ldexp(1.0, int(np.frexp(scale)[1])))


def runs(flags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first, last) indices of each run of True (run-length encoding, no Python loop)."""
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    edges = np.diff(padded)
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
