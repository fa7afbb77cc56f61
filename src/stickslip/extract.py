r"""`extract_cycles`: per-cycle stick-slip statistics from a measured trace.

A block driven at speed $v_b$ sticks when its velocity first returns to $v_b$ and then moves
with the belt, $x(t) = x_{sl} + v_b (t - t_{sl})$, until static friction gives way (docs/
simulator.md, "Semantics of one cycle"). In the drifting frame $y = x - v_b t$ a stick is a
flat stretch; during a slip $\dot y = v - v_b < 0$. This module finds the flat stretches of a
sampled trace and times the transitions between them.
"""

from __future__ import annotations

import dataclasses
import os
from typing import Any

import numpy as np

from ._errors import ParameterError, check_int, check_positive

_OWNER = "extract_cycles"
COLUMNS = ("release_time", "slip_time", "slip_distance", "stick_time", "period")
_NOISE_SIGMAS = 5.0  # a stuck value is noise beyond 5 sd with probability 6e-7
_ROUNDING = 1e-9  # relative floor of tol: differenced positions carry rounding error
_FIRST_BAND = 0.05  # the first noise estimate looks within 5% of the velocity spread of v_b
_MIN_SLIP_SAMPLES = 3  # fewer sampling intervals per slip cannot time it


@dataclasses.dataclass(frozen=True, eq=False)
class Cycles:
    """The cycles found by `extract_cycles`.

    - `table`: a dict of equal-length arrays, one row per complete cycle (a slip whose
      release and stick were both seen, and the stick that follows it up to the next
      release): `release_time`, `slip_time` $T_{sl}$, `slip_distance` $d = x_0 - x_{sl}$,
      `stick_time` $T_{st}$, `period` $T = T_{sl} + T_{st}$;
    - `info`: how they were found: `v_b`, `tol`, `min_stick`, `velocity` (`"v"` or
      `"x differences"`), `sampling_interval` (the median), `n_sticks`.
    """

    table: dict[str, np.ndarray]
    info: dict[str, Any]

    def __len__(self) -> int:
        return int(self.table["period"].size)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.table[name]

    def to_csv(self, path: str | os.PathLike | None = None) -> str:
        """The table as CSV text (header, one row per cycle); written to `path` if given."""
        rows = np.column_stack([self.table[k] for k in COLUMNS]) if len(self) else []
        lines = [",".join(COLUMNS)] + [",".join(f"{value:.10g}" for value in row) for row in rows]
        text = "\n".join(lines) + "\n"
        if path is not None:
            with open(path, "w") as f:
                f.write(text)
        return text

    def __repr__(self) -> str:
        return f"Cycles(n={len(self)}, tol={self.info['tol']:.3g}, v_b={self.info['v_b']})"


def extract_cycles(
    t,
    x=None,
    v=None,
    *,
    v_b: float,
    tol: float | None = None,
    min_stick: int | None = None,
) -> Cycles:
    r"""Find the stick-slip cycles in a measured trace and time each one.

    **Arguments:**

    - `t`: sample times, 1-D, strictly increasing (the spacing may vary).
    - `x`, `v`: position and/or velocity at those times (at least one). With `v` the stick
      phases are found from `v`; with only `x`, from the mean velocity of each sampling
      interval, $(x_{k+1} - x_k)/(t_{k+1} - t_k)$, which is exactly $v_b$ on an interval
      inside a stick (central differences would blur every transition over two intervals).
      With only `v`, the position is its cumulative trapezoid integral from 0.
    - `v_b`: the driving speed ($> 0$).
    - `tol`: a velocity value is *stuck* when $|v - v_b| \le$ `tol`. Default: 5 robust
      standard deviations of the stuck values' noise, $5 \times 1.4826\,\mathrm{MAD}$ of
      $v - v_b$ over the values near $v_b$ (first within 5% of the velocity's spread,
      then within 5 sd of the previous estimate, until the band stops shrinking), and at
      least $10^{-9}$ times the spread (rounding of differenced positions). On a clean
      trace the stuck values sit exactly on $v_b$, so `tol` is that floor; with Gaussian
      noise a stuck value falls outside with probability $6 \times 10^{-7}$.
    - `min_stick`: the fewest consecutive stuck values that make a stick (default 2):
      samples of `v`, or sampling intervals of `x` when only `x` is given. Shorter runs
      are part of a slip (noise about $v_b$).

    **Locating the transitions.** In this model the velocity approaches $v_b$ from below at
    a stick and leaves it downwards at a release ($v < v_b$ during a slip). The stick lies
    between the last slipping value before a stuck run and the run (or, if the velocity
    overshoots above `tol`, between the last value below $v_b$ and the next one, a sign
    change of $v - v_b$). Within that bracket it is placed by the slip's trend:
    $v_b - v$ is taken as linear in time near the stick, fitted to the last two slipping
    samples of `v` (extrapolated to $v_b$), or, with `x` only, to the mean velocities of the
    last two slipping intervals (whose deficits are $a\delta^2/2h$ and $a(\delta + h'/2)$
    for a stick $\delta$ into an interval of length $h$). The result is clipped to the
    bracket, so the error is at most one sampling interval, and $O(h^2)$ for a smooth
    velocity. A release is located the same way in reversed time.

    **Positions.** Within a stick $x - v_b t$ is constant; its median over the stick's
    samples, $c$, gives the position at the stick, $c + v_b t_{sl}$, and at the release,
    $c + v_b t_0$. The slip distance is $d = x(t_0) - x(t_{sl})$.

    **Cycles that a trace cannot show.** A slip that ends with a stick of zero length
    ($T_{st} = 0$, e.g. a short slip that ends beyond its threshold) or with a stick holding
    fewer than `min_stick` values runs on into the next slip: the trace shows one longer
    slip. An immediate re-stick ($T_{sl} = 0$) is invisible: the stick continues.

    **Returns:** a `Cycles`, one row per complete cycle. The incomplete first and last
    cycles (the trace starts or ends inside a slip, or ends inside a stick) are dropped.

    **Raises:** `ParameterError` for non-finite or mismatched inputs, `t` not strictly
    increasing, neither `x` nor `v`, `v_b <= 0`, a trace with no complete stick-slip cycle,
    and sampling too coarse to time the slips (a median slip shorter than 3 intervals).
    """
    t, x, v, v_b, min_stick = _validate(t, x, v, v_b, min_stick)
    if v is not None:
        times, r, kind = t, v - v_b, "point"
    else:
        times, r, kind = t, np.diff(x) / np.diff(t) - v_b, "mean"
    if x is None:
        x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    tol = _default_tol(r) if tol is None else check_positive(_OWNER, "tol", tol)
    h = float(np.median(np.diff(t)))
    stuck = np.abs(r) <= tol
    if kind == "point":
        weight = np.gradient(t)  # the time each sample stands for
        limit = tol * h * np.sqrt(np.arange(r.size + 1))  # independent noise adds up
    else:
        weight = np.diff(t)
        limit = np.full(r.size + 1, tol * h)  # the sum telescopes to a change of x - v_b t
    runs = [
        run
        for s, e in _runs(stuck)
        if (run := _flat_run(r * weight, s, e, limit, min_stick)) is not None
    ]
    if not runs:
        if stuck.any():
            raise ParameterError(
                _OWNER, "t", f"samples too coarse: no stick holds min_stick={min_stick} "
                f"consecutive values with |v - v_b| <= tol={tol:.3g} (sampling interval "
                f"{h:.3g}); sample at least {min_stick + 1} times per stick phase",
            )  # fmt: skip
        raise ParameterError(
            _OWNER, "v_b", f"no stick-slip: no sample moves with the belt (|v - v_b| <= "
            f"tol={tol:.3g}); check v_b and tol", v_b,
        )  # fmt: skip
    locate = _locate_point if kind == "point" else _locate_mean
    n = r.size
    sticks, releases, offsets = [], [], []
    for s, e in runs:
        sticks.append(locate(times, r, s - 1) if s > 0 else np.nan)
        if e < n - 1:
            # a release is a stick in reversed time
            releases.append(-locate(-times[::-1], r[::-1], n - 2 - e))
        else:
            releases.append(np.nan)
        last = e if kind == "point" else e + 1  # a stuck interval e spans samples e, e + 1
        offsets.append(float(np.median(x[s : last + 1] - v_b * t[s : last + 1])))
    sticks, releases, offsets = map(np.asarray, (sticks, releases, offsets))
    release = releases[:-1]
    stick, next_release = sticks[1:], releases[1:]
    keep = np.isfinite(release) & np.isfinite(stick) & np.isfinite(next_release)
    slip_time = (stick - release)[keep]
    slip_distance = ((offsets[:-1] + v_b * release) - (offsets[1:] + v_b * stick))[keep]
    stick_time = (next_release - stick)[keep]
    if not keep.any():
        raise ParameterError(
            _OWNER, "v_b", f"no complete stick-slip cycle in the trace ({len(runs)} stick "
            f"phase(s) found with tol={tol:.3g}); check v_b and tol, or record a longer trace",
            v_b,
        )  # fmt: skip
    if np.median(slip_time) < _MIN_SLIP_SAMPLES * h:
        raise ParameterError(
            _OWNER, "t", f"samples too coarse: the median slip lasts "
            f"{np.median(slip_time):.3g}, {np.median(slip_time) / h:.2g} sampling intervals "
            f"of {h:.3g}; need an interval below {np.median(slip_time) / _MIN_SLIP_SAMPLES:.3g}",
        )  # fmt: skip
    table = dict(
        release_time=release[keep],
        slip_time=slip_time,
        slip_distance=slip_distance,
        stick_time=stick_time,
        period=slip_time + stick_time,
    )
    info = dict(
        v_b=v_b, tol=float(tol), min_stick=min_stick, sampling_interval=h, n_sticks=len(runs),
        velocity="v" if kind == "point" else "x differences",
    )  # fmt: skip
    return Cycles(table, info)


def _validate(t, x, v, v_b, min_stick):
    v_b = check_positive(_OWNER, "v_b", v_b)
    min_stick = check_int(_OWNER, "min_stick", 2 if min_stick is None else min_stick, minimum=1)
    if x is None and v is None:
        raise ParameterError(_OWNER, "x", "or 'v' is required: give a position or a velocity")
    arrays = {}
    for name, value in (("t", t), ("x", x), ("v", v)):
        if value is None:
            arrays[name] = None
            continue
        try:
            a = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(_OWNER, name, "must be an array of real numbers") from None
        if a.ndim != 1:
            raise ParameterError(_OWNER, name, f"must be 1-D (got shape {a.shape})")
        bad = np.nonzero(~np.isfinite(a))[0]
        if bad.size:
            raise ParameterError(
                _OWNER, name, f"must be finite: {bad.size} NaN/inf value(s), the first at "
                f"index {bad[0]}",
            )  # fmt: skip
        arrays[name] = a
    t = arrays["t"]
    if t.size < 3:
        raise ParameterError(_OWNER, "t", f"needs at least 3 samples (got {t.size})")
    for name in ("x", "v"):
        if arrays[name] is not None and arrays[name].size != t.size:
            raise ParameterError(
                _OWNER, name, f"must have the length of t ({t.size}), got {arrays[name].size}"
            )
    step = np.diff(t)
    if np.any(step <= 0):
        k = int(np.nonzero(step <= 0)[0][0])
        raise ParameterError(
            _OWNER, "t", f"must be strictly increasing: t[{k + 1}] = {t[k + 1]!r} follows "
            f"t[{k}] = {t[k]!r}",
        )  # fmt: skip
    return t, arrays["x"], arrays["v"], v_b, min_stick


def _default_tol(r: np.ndarray) -> float:
    """5 robust sd of the noise of the values near 0 (see `extract_cycles`)."""
    spread = float(np.percentile(r, 99) - np.percentile(r, 1))
    floor = _ROUNDING * max(spread, float(np.max(np.abs(r))), 1e-300)
    band, sigma = _FIRST_BAND * spread, 0.0
    while True:
        near = np.abs(r[np.abs(r) <= band])
        if near.size == 0:
            break
        sigma = 1.4826 * float(np.median(near))
        narrower = max(_NOISE_SIGMAS * sigma, floor)
        if narrower >= 0.99 * band:
            break
        band = narrower
    return max(_NOISE_SIGMAS * sigma, floor)


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True."""
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    edges = np.diff(padded)
    return list(zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0] - 1, strict=True))


def _flat_run(drift: np.ndarray, s: int, e: int, limit: np.ndarray, min_stick: int):
    """The run s..e, shortened until x - v_b t changes over it by at most `limit` (5 sd of
    the noise): a slip that passes within tol of v_b for a while (a near-miss) drifts; the
    end values of a real stick may hold part of the adjacent slip, so they are shed first
    (the more negative end). None if fewer than `min_stick` values remain."""
    while e - s + 1 >= min_stick:
        if abs(drift[s : e + 1].sum()) <= limit[e - s + 1]:
            return s, e
        if drift[s] < drift[e]:
            s += 1
        else:
            e -= 1
    return None


def _last_below(r: np.ndarray, p: int) -> int:
    """The last index <= p with r < 0: an overshoot above v_b moves the bracket back to the
    sign change."""
    while p > 0 and r[p] >= 0:
        p -= 1
    return p


def _locate_point(t, r, p) -> float:
    """Stick time after the slipping sample p (point values of v - v_b)."""
    p = _last_below(r, p)
    lo = t[p]
    # the crossing is before the first sample at or above v_b, and at most one sample into
    # a stuck run whose first value still lies (within tol) below v_b
    hi = t[p + 1] if r[p + 1] >= 0 or p + 2 >= t.size else t[p + 2]
    if p >= 1 and r[p - 1] < r[p] < 0:
        guess = t[p] - r[p] * (t[p] - t[p - 1]) / (r[p] - r[p - 1])
    elif r[p + 1] > r[p]:
        guess = t[p] - r[p] * (t[p + 1] - t[p]) / (r[p + 1] - r[p])
    else:
        guess = t[p + 1]
    return float(np.clip(guess, lo, hi))


def _locate_mean(t, r, p) -> float:
    """Stick time after the slipping interval p (r[k]: mean of v - v_b over [t_k, t_k+1])."""
    p = _last_below(r, p)
    h1 = t[p + 1] - t[p]
    if p < 1 or not r[p - 1] < r[p] < 0:
        return float(t[p] + 0.5 * h1)
    h2 = t[p] - t[p - 1]
    rho = r[p] / r[p - 1]
    if rho <= 0.5 * h1 / (h1 + 0.5 * h2):  # the stick lies inside interval p
        delta = h1 * rho + np.sqrt((h1 * rho) ** 2 + h1 * h2 * rho)
        return float(t[p] + min(delta, h1))
    # interval p slipped throughout: the stick lies in the next one, whose deficit (within
    # tol) bounds how far in, by the same relation one interval later
    delta = (rho * (h1 + 0.5 * h2) - 0.5 * h1) / (1.0 - rho)
    if p + 2 >= t.size or r[p + 1] >= 0:
        return float(t[p + 1])
    h3 = t[p + 2] - t[p + 1]
    rho3 = r[p + 1] / r[p]
    cap = h3 * rho3 + np.sqrt((h3 * rho3) ** 2 + h3 * h1 * rho3)
    return float(t[p + 1] + min(delta, cap, h3))
