r"""Cycles from a position and/or velocity trace (`x=`, `v=`): the flat stretches of
$x - v_b t$ are the sticks (docs/simulator.md, "Semantics of one cycle")."""

from __future__ import annotations

import warnings

import numpy as np

from .._errors import DataError, ParameterError, check_int, check_positive
from ._cycles import Cycles
from ._input import OWNER, as_series, check_length, check_times, power_of_two, runs

_NOISE_SIGMAS = 5.0  # a stuck value is noise beyond 5 sd with probability 6e-7
_ROUNDING = 1e-9  # relative floor of tol: differenced positions carry rounding error
_FIRST_BAND = 0.05  # the first noise estimate looks within 5% of the velocity spread of v_b
_MIN_SLIP_SAMPLES = 3  # fewer sampling intervals per slip cannot time it
_VB_WARN = 0.02  # a given v_b further than 2% from the sticks' own speed is worth a warning
# A given v_b further than 25% from the sticks' own speed (estimated without it, `_sticks_speed`)
# is a mistake (units, a factor 2, a flipped sign), not a belt that slips: refused. Sticks
# share one speed and hold it: among the samples whose velocity holds, the densest window of
# 2% of the velocity range finds it where it stands out as a peak: at least 5% of those
# samples, and 10 times as many as a window 4 widths to either side (a slip's turning point,
# where the velocity also dwells, made 2-4 times; noise about 1). Else nothing is said.
_VB_REFUSE, _MODE_WIDTH, _MODE_SHARE, _MODE_PEAK = 0.25, 0.02, 0.05, 10.0
# Beyond 10% the band about v_b may miss the sticks (it spans 5% of the velocity range); the
# peak's own precision, on a noisy trace smoothed to find it, is a few %.
_VB_SHIFT = 0.1
# Stuck values that cluster no more than chance are noise: independent flags with a
# fraction p stuck make runs whose sample-weighted mean length is (1 + p)/(1 - p); a real
# stick holds its values for its whole length, far beyond that. 3x leaves room for short
# sticks of a coarsely sampled trace; 20 runs are enough to judge.
_CLUSTER_FACTOR, _CLUSTER_MIN_RUNS = 3.0, 20
# Noisy traces: the stuck flags come from a Savitzky-Golay smoothing of v - v_b whose window
# is the one that minimises the measured noise sd of the smoothed stuck values (a wider
# window averages more noise until it blurs the slips into the band); 5 samples is the
# smallest window a quadratic smooths over, 101 bounds the search's cost.
_MIN_WINDOW, _MAX_WINDOW = 5, 101


def extract_velocity(t, x, v, v_b, tol, min_stick) -> Cycles:
    """The cycles of a position (`x`) or velocity (`v`) trace: its sticks are the runs
    that move with the drive (within `tol` of the sticks' own speed, flat in x - v_b t)."""
    v_b = check_positive(OWNER, "v_b", v_b)
    min_stick = check_int(OWNER, "min_stick", 2 if min_stick is None else min_stick, minimum=1)
    if tol is not None:
        tol = check_positive(OWNER, "tol", tol)
    t, tt, xx, vv, vb, r, kind, t0, s_t, s_v = _scaled(t, x, v, v_b)
    vb_given = vb
    r, vb = _from_the_sticks(r, vb, s_v, v_b, "x" if v is None else "v")
    with np.errstate(over="ignore", invalid="ignore"):  # a huge v's integral: not used then
        if x is None:
            xx = np.concatenate([[0.0], np.cumsum(0.5 * (vv[1:] + vv[:-1]) * np.diff(tt))])
        center, sigma, floor = _noise_band(r)
    tol_u = max(_NOISE_SIGMAS * sigma, floor) if tol is None else tol / s_v
    h = float(np.median(np.diff(tt)))
    # the band's centre leans towards the slips' values that fall in it (all below v_b):
    # it is taken as the sticks' speed only where it stands out of the noise (a clean trace
    # with v_b 0.1% off); within the noise, tol covers the offset
    if abs(center) <= sigma:
        center = 0.0
    stuck = np.abs(r - center) <= tol_u
    first, last = runs(stuck)
    r = r - center
    vb_used = vb + center
    _check_clustering(stuck, first, last, tol_u * s_v, v_b)
    # a noisy trace (noise above the rounding floor, tol not given): flag and time the
    # transitions on the smoothed velocity; the flat-run test below keeps the raw values,
    # whose sum over a stick telescopes (x) or has independent terms (v)
    r_s, window, sigma_s, tol_s = r, 0, sigma, tol_u
    if tol is None and sigma > floor:
        window, r_s, sigma_s = _smoothing(r, floor)
        if window:
            tol_s = max(_NOISE_SIGMAS * sigma_s, floor)
            stuck = np.abs(r_s) <= tol_s
            first, last = runs(stuck)
            # the smoothed noise is correlated over the window: a stuck run shorter than
            # it may be one fluctuation of a slip that passes near v_b, not a stick
            min_stick = max(min_stick, window)
    _warn_off(vb + center, vb_given, s_v, v_b)
    if kind == "point":
        weight = np.gradient(tt)  # the time each sample stands for
        limit = tol_u * h * np.sqrt(np.arange(r.size + 1))  # independent noise adds up
    else:
        weight = np.diff(tt)
        limit = np.full(r.size + 1, tol_u * h)  # the sum telescopes to a change of x - v_b t
    found = _flat_runs(r * weight, first, last, limit, min_stick)
    if not found:
        if stuck.any():
            raise ParameterError(
                OWNER, "t", f"samples too coarse: no stick holds min_stick={min_stick} "
                f"consecutive values with |v - v_b| <= tol={tol_u * s_v:.3g} (sampling "
                f"interval {h * s_t:.3g}); sample at least {min_stick + 1} times per stick phase",
            )  # fmt: skip
        raise ParameterError(
            OWNER, "v_b", f"no stick-slip: no sample moves with the belt (|v - v_b| <= "
            f"tol={tol_u * s_v:.3g}); check v_b and tol", v_b,
        )  # fmt: skip
    locate = _locate_point if kind == "point" else _locate_mean
    n = r.size

    def offset(s, e):  # x - v_b t over a stick (a stuck interval e spans samples e, e + 1)
        end = e if kind == "point" else e + 1
        return float(np.median(xx[s : end + 1] - vb_used * tt[s : end + 1]))

    # a slip moves x - v_b t down by the integral of v_b - v > 0; two sticks that a "slip"
    # joins without moving it beyond 5 sd of the position noise are one stick split by
    # noise (position noise: sigma h / sqrt(2) for interval velocities, sigma h for v)
    pos_sd = sigma * h / (np.sqrt(2.0) if kind == "mean" else 1.0)
    joined = _joined(found, offset, _NOISE_SIGMAS * pos_sd)
    n_split = len(found) - len(joined)
    found = joined
    sticks, releases, offsets = [], [], []
    rev_t, rev_s = -tt[::-1], r_s[::-1]
    for s, e in found:
        sticks.append(locate(tt, r_s, s - 1) if s > 0 else np.nan)
        # a release is a stick in reversed time
        releases.append(-locate(rev_t, rev_s, n - 2 - e) if e < n - 1 else np.nan)
        offsets.append(offset(s, e))
    sticks, releases, offsets = map(np.asarray, (sticks, releases, offsets))
    release = releases[:-1]
    stick, next_release = sticks[1:], releases[1:]
    keep = np.isfinite(release) & np.isfinite(stick) & np.isfinite(next_release)
    if not keep.any():
        _no_cycle(found, n, vb_used * s_v, tol_u * s_v, v_b)
    slip_time = (stick - release)[keep]
    distance = ((offsets[:-1] + vb_used * release) - (offsets[1:] + vb_used * stick))[keep]
    _check_slips(release[keep], slip_time, distance, vb_used, pos_sd, h, t0, s_t, s_v)
    stick_time = (next_release - stick)[keep]
    table = dict(
        release_time=release[keep] * s_t + t0,
        slip_time=slip_time * s_t,
        slip_distance=distance * s_t * s_v,
        stick_time=stick_time * s_t,
        period=(slip_time + stick_time) * s_t,
    )
    info = _info(x, v, kind, v_b, vb_used * s_v, tol, tol_s * s_v, tol_u * s_v, window,
                 sigma * s_v, sigma_s * s_v, min_stick, h * s_t, len(found), n_split)  # fmt: skip
    return Cycles(table, info)


def _scaled(t, x, v, v_b):
    """The trace checked and put in units where t spans ~1 and v_b ~ 1 (powers of 2:
    exact), so that a trace scaled by 1e307 neither overflows nor finds other cycles:
    `(t, tt, xx, vv, vb, r, kind, t0, s_t, s_v)`, `r` the velocity less v_b (`kind`
    "point": of each sample; "mean": between samples, from x)."""
    if x is None and v is None:
        raise ParameterError(OWNER, "x", "or 'v' is required: give a position or a velocity")
    t = as_series("t", t, required=True)
    x, v = as_series("x", x), as_series("v", v)
    check_times(t)
    check_length("x", x, t.size)
    check_length("v", v, t.size)
    t0, s_t, s_v = t[0], power_of_two(t[-1] - t[0]), power_of_two(v_b)
    with np.errstate(all="ignore"):  # overflow is checked below, with its reason
        tt = (t - t0) / s_t
        xx = None if x is None else x / s_v / s_t  # in two steps: s_v * s_t may overflow
        vv = None if v is None else v / s_v
        vb = v_b / s_v
        if vv is not None:
            r, kind = vv - vb, "point"
        else:
            r, kind = np.diff(xx) / np.diff(tt) - vb, "mean"
    for name, a in (("t", tt), ("x", xx), ("v", vv), ("x" if v is None else "v", r)):
        if a is not None and not np.all(np.isfinite(a)):
            raise ParameterError(
                OWNER, name, f"overflows in units of v_b={v_b:.3g} and the trace's duration: "
                "the values and v_b differ by more than the float range; rescale them",
            )  # fmt: skip
    return t, tt, xx, vv, vb, r, kind, t0, s_t, s_v


def _flat_runs(step, first, last, limit, min_stick) -> list:
    """The stuck runs (`first`, `last` samples) of at least `min_stick` samples along which
    x - v_b t stays flat within `limit` (`_flat_run`: each run's flat part)."""
    drift = np.concatenate([[0.0], np.cumsum(step)])
    long_enough = last - first + 1 >= min_stick
    found = []
    for s, e in zip(first[long_enough].tolist(), last[long_enough].tolist(), strict=True):
        run = _flat_run(drift, step, s, e, limit, min_stick)
        if run is not None:
            found.append(run)
    return found


def _from_the_sticks(r, vb, s_v, v_b, field):
    """The sticks' own speed, found without v_b: a v_b it contradicts is refused; one off
    by more than `_VB_SHIFT` is replaced by it (the band then starts there and finds the
    speed to the noise's precision, as it does from a v_b closer to it). Returns `r`
    (the velocity less the speed taken) and that speed."""
    v_st = _sticks_speed(r + vb)
    if v_st is not None:
        _check_v_b(v_st * s_v, v_b, field)
        if abs(v_st - vb) > _VB_SHIFT * vb:
            r, vb = r - (v_st - vb), v_st
    return r, vb


def _warn_off(v_sticks, vb_given, s_v, v_b) -> None:
    """The sticks' own speed against v_b as given (a few % off at most is expected)."""
    off = v_sticks - vb_given
    if abs(off) > _VB_WARN * vb_given:
        warnings.warn(
            f"extract_cycles: the sticks move at {v_sticks * s_v:.6g}, "
            f"{100 * off / vb_given:+.2g}% from the given v_b = {v_b:.6g}; using the sticks' "
            "speed",
            stacklevel=5,
        )


def _check_slips(release, slip_time, distance, vb, pos_sd, h, t0, s_t, s_v) -> None:
    """Refuse cycles that are no slips of this trace at this v_b, and slips too short for
    the sampling (in the trace's scaled units; `t0`, `s_t`, `s_v` give them back)."""
    # In a slip v < v_b, so x rises by less than v_b T_sl: d > -v_b T_sl, up to the position
    # noise at both ends. A cycle past that bound is no slip of this trace at this v_b.
    impossible = distance < -vb * slip_time - 2 * _NOISE_SIGMAS * pos_sd
    if impossible.any():
        k = int(np.argmax(impossible))
        raise DataError(
            f"extract_cycles: the cycle released at t = {release[k] * s_t + t0:.6g} has a "
            f"slip distance of {distance[k] * s_t * s_v:.4g}, below -v_b T_sl = "
            f"{-vb * slip_time[k] * s_t * s_v:.4g} (x cannot rise faster than the belt "
            "while slipping): check v_b and the sign and units of the trace"
        )
    if np.median(slip_time) < _MIN_SLIP_SAMPLES * h:
        med = float(np.median(slip_time))
        raise ParameterError(
            OWNER, "t", f"samples too coarse: the median slip lasts {med * s_t:.3g}, "
            f"{med / h:.2g} sampling intervals of {h * s_t:.3g}; need an interval below "
            f"{med * s_t / _MIN_SLIP_SAMPLES:.3g}",
        )  # fmt: skip


def _info(x, v, kind, v_b, v_sticks, tol, tol_used, tol_raw, window, noise_sd,
          noise_sd_smoothed, min_stick, sampling_interval, n_sticks, n_joined) -> dict:  # fmt: skip
    """How a position or velocity trace's cycles were found (in the trace's units)."""
    return dict(
        input="x and v" if x is not None and v is not None else ("x" if x is not None else "v"),
        velocity="v" if kind == "point" else "x differences",
        v_b=v_b, v_b_sticks=float(v_sticks), tol=float(tol_used),
        tol_rule="given" if tol is not None else (
            "5 robust sd of the smoothed |v - v_b| near v_b" if window
            else "5 robust sd of |v - v_b| near v_b"),
        noise_sd=float(noise_sd), noise_sd_smoothed=float(noise_sd_smoothed),
        filter=f"scipy.signal.savgol_filter, {window} samples, polyorder 2" if window
        else "none", smoothing_window=window, tol_raw=float(tol_raw),
        min_stick=min_stick,
        sampling_interval=float(sampling_interval), n_sticks=n_sticks, n_joined=n_joined,
    )  # fmt: skip


def _joined(found, offset, gap):
    """Sticks (first, last sample) that a "slip" joins without moving x - v_b t down by
    more than `gap` joined into one (a stick split by noise)."""
    joined = []
    for s, e in found:
        if joined and offset(*joined[-1]) - offset(s, e) <= gap:
            joined[-1] = (joined[-1][0], e)
        else:
            joined.append((s, e))
    return joined


def _no_cycle(found, n, v_sticks, tol, v_b):
    """Refuse a trace without a complete cycle, naming why: it never slips, it slips once,
    or its sticks were not found at this v_b and tol."""
    if len(found) == 1 and found[0][1] - found[0][0] + 1 >= 0.9 * n:
        raise DataError(
            "extract_cycles: the trace never slips: it moves at the sticks' speed "
            f"{v_sticks:.4g} throughout (one stick phase, no slip to time)"
        )
    if len(found) == 2:
        raise DataError(
            "extract_cycles: the trace holds a single slip between two stick phases; a "
            "complete cycle runs from a release to the next one: record a longer trace"
        )
    raise ParameterError(
        OWNER, "v_b", f"no complete stick-slip cycle in the trace ({len(found)} stick "
        f"phase(s) found with tol={tol:.3g}); check v_b and tol, or record a "
        "longer trace", v_b,
    )  # fmt: skip


def _sticks_speed(vel: np.ndarray) -> float | None:
    """The speed the sticks move at, found without the given v_b (`_MODE_PEAK`): on the
    velocity as it is, else smoothed (Savitzky-Golay, quadratic, over 11, 31 then 101
    samples: a noisy trace's peak stands out once the noise is averaged); `None` where no
    speed stands out."""
    found = _speed_peak(vel)
    for window in (11, 31, 101):
        if found is not None or window >= vel.size:
            break
        from scipy.signal import savgol_filter

        exponent = int(np.frexp(np.max(np.abs(vel)))[1])  # (scaled by a power of 2: exact)
        smooth = np.ldexp(savgol_filter(np.ldexp(vel, -exponent), window, 2), exponent)
        found = _speed_peak(smooth)
    return found


def _speed_peak(vel: np.ndarray) -> float | None:
    """The median of the densest window, `_MODE_WIDTH` of the velocity range wide, of the
    samples whose velocity holds (a change to the next sample no larger than the median
    change), where it is a peak (`_MODE_SHARE`, `_MODE_PEAK`); else `None`."""
    if vel.size < 8:
        return None
    change = np.abs(np.diff(vel))
    flat = np.sort(vel[:-1][change <= np.median(change)])
    lo, hi = np.percentile(vel, [1, 99])
    width = _MODE_WIDTH * float(hi - lo)
    if flat.size < 8 or not width > 0:
        return None
    counts = np.searchsorted(flat, flat + width, side="right") - np.arange(flat.size)
    best = int(np.argmax(counts))
    if counts[best] < _MODE_SHARE * flat.size:
        return None
    mode = float(np.median(flat[best : best + counts[best]]))
    for side in (-4.0, 4.0):
        a, b = np.searchsorted(flat, mode + (side + np.array([-0.5, 0.5])) * width)
        if counts[best] < _MODE_PEAK * max(b - a, 1):
            return None
    return mode


def _check_v_b(v_st: float, v_b: float, name: str) -> None:
    """Refuse a v_b that the sticks' own speed `v_st` contradicts (see `_VB_REFUSE`)."""
    if v_st <= 0:
        raise DataError(
            f"extract_cycles: the sticks move at {v_st:.4g}, against the belt's v_b = {v_b:.4g} "
            f"> 0: is the sign of {name} flipped? (a stick moves with the belt, at +v_b)"
        )
    if abs(v_st / v_b - 1.0) > _VB_REFUSE:
        raise ParameterError(
            OWNER, "v_b", f"disagrees with the trace: its sticks move at {v_st:.4g}, "
            f"{v_st / v_b:.3g} times v_b; check v_b and the units of {name} and t", v_b,
        )  # fmt: skip


def _noise_band(r: np.ndarray) -> tuple[float, float, float]:
    """(center, sd, floor) of the stuck values: the robust centre and sd of the values
    near 0, first within 5% of the spread, then within 5 sd of the centre, until the band
    stops shrinking; the floor is the rounding of differenced positions."""
    spread = float(np.percentile(r, 99) - np.percentile(r, 1))
    floor = _ROUNDING * max(spread, float(np.max(np.abs(r))), 1e-300)
    band, center, sigma = _FIRST_BAND * spread, 0.0, 0.0
    for _ in range(100):
        near = r[np.abs(r - center) <= band]
        if near.size == 0:
            break
        center = float(np.median(near))
        sigma = 1.4826 * float(np.median(np.abs(near - center)))
        narrower = max(_NOISE_SIGMAS * sigma, floor)
        if narrower >= 0.99 * band:
            break
        band = narrower
    return center, sigma, floor


def _smoothing(r: np.ndarray, floor: float) -> tuple[int, np.ndarray, float]:
    """(window, smoothed r, its noise sd): the smallest odd window from 5 whose smoothing
    (Savitzky-Golay, quadratic) brings 5 robust sd of the stuck values within 5% of the
    velocity spread (the band the noise estimate starts from), or failing that the window
    where widening stops reducing that sd; (0, r, sd) where the raw values already fit."""
    from scipy.signal import savgol_filter

    spread = float(np.percentile(r, 99) - np.percentile(r, 1))
    target = _FIRST_BAND * spread / _NOISE_SIGMAS
    best = (0, r, _noise_band(r)[1])
    exponent = int(np.frexp(np.max(np.abs(r)))[1]) if r.size else 0
    for window in range(_MIN_WINDOW, min(_MAX_WINDOW, r.size - 1) + 1, 2):
        if best[2] <= target:
            break
        # scaled by a power of 2 (exact) so that the filter's least squares cannot overflow
        smooth = np.ldexp(savgol_filter(np.ldexp(r, -exponent), window, 2, mode="interp"), exponent)
        sd = _noise_band(smooth)[1]
        if sd >= best[2] or sd <= floor:
            break
        best = (window, smooth, sd)
    return best


def _check_clustering(stuck, first, last, tol, v_b) -> None:
    """Refuse a trace whose stuck values are scattered like noise (see _CLUSTER_FACTOR)."""
    if first.size < _CLUSTER_MIN_RUNS:
        return
    length = (last - first + 1).astype(float)
    p = float(stuck.mean())
    weighted = float((length**2).sum() / length.sum())
    chance = (1.0 + p) / (1.0 - p) if p < 1 else np.inf
    if weighted < _CLUSTER_FACTOR * chance:
        raise DataError(
            f"extract_cycles: no stick phases: the {int(stuck.sum())} values within tol="
            f"{tol:.3g} of v_b={v_b:.6g} ({100 * p:.3g}% of the trace) form {first.size} runs "
            f"of sample-weighted mean length {weighted:.3g}, as scattered noise would "
            f"({chance:.3g}); a stick holds its values for its whole length"
        )


def _flat_run(drift, step, s, e, limit, min_stick):
    """The run s..e, shortened until x - v_b t changes over it by at most `limit` (5 sd of
    the noise): a slip that passes within tol of v_b for a while (a near-miss) drifts; the
    end values of a real stick may hold part of the adjacent slip, so they are shed first
    (the more negative end). None if fewer than `min_stick` values remain. `drift` is the
    cumulative sum of `step`, so each test is O(1)."""
    while e - s + 1 >= min_stick:
        if abs(drift[e + 1] - drift[s]) <= limit[e - s + 1]:
            return s, e
        if step[s] < step[e]:
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
