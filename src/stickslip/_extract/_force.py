r"""Cycles from a force trace: $F = k\,e$ with $e$ the spring's extension, so $e = F/k$
plays the part of $x$. During a stick the force rises along the loading line at
$g = k v_b$; during a slip it falls. Every threshold below is a multiple of the trace's own
noise, measured on it, and recorded in `Cycles.info`.

1. Spikes: a sample further than 5 sd from the running median of 7 samples is replaced
   by that median (the source of the measured traces sees spikes a few samples wide;
   a running median leaves a monotone stretch, the loading line and a slip, unchanged).
2. Noise: $\sigma$ = robust sd of the despiked force's first differences over $\sqrt 2$
   (the loading line moves the force by far less than $\sigma$ per sample).
3. Slips: the force rate from a Savitzky-Golay derivative over `window` samples (SciPy);
   its noise sd is $\sigma\sqrt{12 / (W(W^2-1))}$ per sample. A slip is a stretch where
   the rate lies more than 2 sd below the loading rate $g$ (the median rate) and that
   reaches 5 sd below somewhere; it counts if the force drops across it by more than 5 sd
   of that drop's estimate (medians of `window` samples either side).
4. Timing: each slip's despiked force, less the loading line, is fitted (robust least
   squares) by the model's damped half-oscillation from the loading line to the stick,
   $y = y_0 - A\,[1 - e^{-\kappa\varphi}(\cos\pi\varphi + \frac{\kappa}{\pi}\sin\pi\varphi)]$
   for $\varphi = (t - t_0)/T_{sl} \in [0, 1]$, flat before and after: $\dot y = 0$ at
   both ends, as when the slider leaves and rejoins the loading line, and the slip ends
   when the velocity first returns, half a damped period after the release. Its
   parameters give the release $t_0$, the slip time $T_{sl}$ and the drop; their standard
   errors (from the fit's Jacobian and $\sigma$) say how well they are timed.
"""

from __future__ import annotations

import warnings

import numpy as np

from .._errors import DataError, ParameterError, check_positive
from ._cycles import Cycles
from ._input import OWNER, as_series, check_length, check_times, power_of_two, runs

_SIGMAS = 5.0  # a noise excursion beyond 5 sd: probability 6e-7 per independent value
_EXTENT_SIGMAS = 2.0  # a slip's stretch of the rate: where it is 2 sd below the loading rate
# a stretch is a candidate if the rate reaches 5 sd below somewhere; the 5 sd test on its
# drop then decides (lower, noise stretches crowd out the slips' own)
_CORE_SIGMAS = 5.0
_DESPIKE = 7  # running median of 7 samples removes spikes up to 3 samples wide
_FIRST_WINDOW = 11  # the first pass, that measures the slips' length to choose `window`
_MIN_SAMPLES = 64  # fewer samples cannot show a stick, a slip and the next stick
_MIN_SLIP_SAMPLES = 3  # fewer samples per slip cannot time it
_VB_WARN = 0.02  # a given v_b this far from the loading slope's is worth a warning
_VB_UNITS = 2.0  # a factor 2 off is no calibration error: wrong units
# In a stick the force rises at the loading rate; a rate far above it (5 sd) on more
# than this fraction of the time between slips means the slider never sticks
_RISING_FRACTION = 0.1
# ... and its rate scatters about the loading rate like the noise: 1.0 on simulated
# traces, 2.4 on the measured 42 um/s trace (its noise is not white), 5.1 on the
# 4300 um/s run (no sticks)
_WOBBLE = 4.0
_UNIFORM = 0.01  # the filters assume even sampling: steps may vary by 1%
_MAD = 1.4826  # MAD to sd for Gaussian noise


def extract_force(t, force, stiffness, v_b, window) -> Cycles:
    from scipy.ndimage import median_filter

    k = check_positive(OWNER, "stiffness", stiffness)
    v_b = check_positive(OWNER, "v_b", v_b, allow_none=True)
    t = as_series("t", t, required=True)
    f = as_series("force", force, required=True)
    check_times(t, minimum=_MIN_SAMPLES)
    check_length("force", f, t.size)
    step = np.diff(t)
    h = float(np.median(step))
    if np.max(np.abs(step - h)) > _UNIFORM * h:
        raise ParameterError(
            OWNER, "t", f"must be evenly sampled for a force trace: steps range from "
            f"{step.min():.6g} to {step.max():.6g} about the median {h:.6g}; resample it",
        )  # fmt: skip
    if window is not None:
        window = _odd_window(window)
    # scaled by a power of 2 (exact): a trace in any units finds the same cycles
    s_f = power_of_two(float(np.max(np.abs(f))))
    y_raw = f / s_f
    if np.ptp(y_raw) == 0:
        raise DataError("extract_cycles: no stick-slip: the force is constant")
    med = median_filter(y_raw, size=_DESPIKE, mode="nearest")
    resid = y_raw - med
    res_sd = _MAD * float(np.median(np.abs(resid - np.median(resid))))
    spikes = np.abs(resid) > _SIGMAS * res_sd if res_sd > 0 else np.zeros(f.size, bool)
    s = np.where(spikes, med, y_raw)
    sigma = _noise_sd(s)
    idx = np.arange(s.size, dtype=float)

    first = window or _FIRST_WINDOW
    rate, g, regions, rate_sd = _slip_stretches(s, first, sigma)
    if window is None:
        # the median length of the stretches weighted by the drop each carries: the big
        # slips set the scale, not the many short stretches of small noise bumps
        lengths = regions[1] - regions[0] + 1
        guess = _FIRST_WINDOW
        if lengths.size:
            cum = np.concatenate([[0.0], np.cumsum(rate - g)])
            weight = np.maximum(cum[regions[0]] - cum[regions[1] + 1], 0.0)
            order = np.argsort(lengths)
            share = np.cumsum(weight[order])
            guess = int(lengths[order][np.searchsorted(share, 0.5 * share[-1])]) // 2
        window = _odd_window(min(max(guess, 5), 101))
        if window != first:
            rate, g, regions, rate_sd = _slip_stretches(s, window, sigma)
    a, b = regions
    stick = np.ones(s.size, bool)
    for lo, hi in zip(a.tolist(), b.tolist(), strict=True):
        stick[max(lo - window, 0) : hi + window + 1] = False
    if stick.sum() < window:
        raise DataError(
            "extract_cycles: no stick found: the force rate lies below its median on "
            f"{100 * (1 - stick.mean()):.3g}% of the trace"
        )
    g = _loading_slope(s, stick)  # per sample, from the sticks alone
    rising = float(np.mean(rate[stick] - g > _SIGMAS * rate_sd))
    wobble = _MAD * float(np.median(np.abs(rate[stick] - g))) / rate_sd
    if g <= 0:
        raise DataError(
            "extract_cycles: no stick found: between the force drops the force does not rise "
            f"(loading rate {g * s_f / h:.3g} per s): continuous sliding?"
        )
    if rising > _RISING_FRACTION or wobble > _WOBBLE:
        raise DataError(
            "extract_cycles: no stick found: between the force drops the force rate scatters "
            f"{wobble:.2g} times its noise sd about the loading rate ({g * s_f / h:.3g} per "
            f"s) and exceeds it by > {_SIGMAS:g} sd on {100 * rising:.3g}% of the samples, "
            "where a stick follows the loading line: continuous sliding?"
        )
    v_b_est = g * s_f / h / k
    if v_b is not None:
        ratio = v_b_est / v_b
        if not 1 / _VB_UNITS < ratio < _VB_UNITS:
            raise DataError(
                f"extract_cycles: the sticks load the force at {g * s_f / h:.4g} per s, which "
                f"with stiffness={k:.6g} means v_b = {v_b_est:.4g}, {ratio:.3g} times the "
                f"given v_b={v_b:.6g}: check the units of force, stiffness and v_b"
            )
        if abs(ratio - 1) > _VB_WARN:
            warnings.warn(
                f"extract_cycles: the sticks' loading slope gives v_b = {v_b_est:.4g}, "
                f"{100 * (ratio - 1):+.2g}% from the given v_b = {v_b:.6g}; the slope is used",
                stacklevel=3,
            )
    y = s - g * idx  # flat in a stick
    drop_sd = 1.2533 * sigma * np.sqrt(2.0 / window)  # sd of a difference of two medians
    fits, largest = [], 0.0
    n_regions = a.size
    for j in range(n_regions):
        lo_lim = b[j - 1] + 1 if j > 0 else 0
        hi_lim = a[j + 1] - 1 if j + 1 < n_regions else s.size - 1
        before = y[max(a[j] - window, lo_lim) : a[j]]
        after = y[b[j] + 1 : min(b[j] + 1 + window, hi_lim + 1)]
        if before.size == 0 or after.size == 0:
            continue
        drop = float(np.median(before) - np.median(after))
        largest = max(largest, drop / drop_sd)
        if drop <= _SIGMAS * drop_sd:
            continue
        fits.append(_fit_slip(y, a[j], b[j], lo_lim, hi_lim, window, drop, sigma))
    n_split = 0
    if fits:
        # a slip followed by an immediate re-slip (a zero-length stick) is one stretch of
        # the rate: a fit far longer than the median slip is tried as two slips, kept if
        # that lowers chi^2 by more than 25 (5 sd)
        med = float(np.median([f[1] for f in fits]))
        out = []
        for fit in fits:
            pair = _fit_double(y, fit, sigma) if fit[1] > 1.6 * med else None
            out.extend(pair or [fit])
            n_split += pair is not None
        fits = out
    if len(fits) < 2:
        raise DataError(
            f"extract_cycles: no stick-slip: {len(fits)} force drop(s) above {_SIGMAS:g} sd of "
            f"their estimate (noise sd {sigma * s_f:.3g}; the largest drop is {largest:.3g} sd); "
            "a complete cycle needs two slips"
        )
    fits = np.array([f[:9] for f in fits])  # i0, T, y0, D, kappa, sd_i0, sd_end, ok, seen
    i0, T, y0, D = fits[:, 0], fits[:, 1], fits[:, 2], fits[:, 3]
    med_T = float(np.median(T))
    if med_T < _MIN_SLIP_SAMPLES:
        raise ParameterError(
            OWNER, "t", f"samples too coarse: the median slip lasts {med_T:.2g} sampling "
            f"intervals of {h:.3g}; need an interval below {med_T * h / _MIN_SLIP_SAMPLES:.3g}",
        )  # fmt: skip
    release = np.interp(i0, idx, t)
    stuck_at = np.interp(i0 + T, idx, t)
    seen = fits[:, 8].astype(bool)  # the release has loading line before it in the trace
    keep = seen[:-1]
    slip_time = (stuck_at - release)[:-1]
    stick_time = np.maximum(release[1:] - stuck_at[:-1], 0.0)  # an immediate re-slip: 0
    drop_f = ((D - g * T) * s_f)[:-1]
    table = dict(
        release_time=release[:-1][keep],
        slip_time=slip_time[keep],
        slip_distance=drop_f[keep] / k,
        stick_time=stick_time[keep],
        period=(slip_time + stick_time)[keep],
        peak_force=((y0 + g * i0) * s_f)[:-1][keep],
        force_drop=drop_f[keep],
    )
    ok = fits[:, 7].astype(bool)
    info = dict(
        input="force", units="force in the units given (N), time in s, lengths in m",
        stiffness=k, v_b=v_b, v_b_estimated=float(v_b_est),
        v_b_rule="loading slope of the sticks (median force rate between slips) / stiffness",
        sampling_interval=h, n_samples=int(s.size),
        despike=f"running median of {_DESPIKE} samples; a sample further than "
        f"{_SIGMAS:g} sd of the residual from it is replaced by it",
        spike_threshold=float(_SIGMAS * res_sd * s_f), n_spikes=int(spikes.sum()),
        noise_sd=float(sigma * s_f),
        noise_rule="robust sd (1.4826 MAD) of the despiked force's differences / sqrt(2)",
        window=int(window),
        filter=f"scipy.signal.savgol_filter, {window} samples, polyorder 2, first derivative",
        rate_noise_sd=float(rate_sd * s_f / h),
        slip_rate_threshold=float(_SIGMAS * rate_sd * s_f / h),
        extent_rate_threshold=float(_EXTENT_SIGMAS * rate_sd * s_f / h),
        drop_threshold=float(_SIGMAS * drop_sd * s_f),
        timing="fit of a damped half-oscillation to each slip (scipy least_squares, soft_l1)",
        release_sd_median=float(np.median(fits[:, 5]) * h),
        stick_sd_median=float(np.median(fits[:, 6]) * h),
        n_slips=int(len(fits)), n_fit_failed=int((~ok).sum()), n_split=n_split,
        tol=float(_SIGMAS * sigma * s_f),
    )  # fmt: skip
    return Cycles(table, info)


def _odd_window(window) -> int:
    from .._errors import check_int

    w = check_int(OWNER, "window", window, minimum=5)
    return w if w % 2 else w + 1


def _loading_slope(s, stick) -> float:
    """The sticks' pooled least-squares slope: each stick's own line, one common slope (an
    offset drift moves each stick's level, hardly its slope). Its sd is sigma over the root
    of the summed squared spreads of the sticks' sample indices: far below 1% here."""
    first, last = runs(stick)
    idx = np.arange(s.size, dtype=float)
    label = np.cumsum(np.concatenate([[0], np.diff(stick.astype(np.int8)) == 1]))[stick]
    i, y = idx[stick], s[stick]
    count = np.bincount(label)
    ok = count > 0
    mi = np.bincount(label, i)[ok] / count[ok]
    my = np.bincount(label, y)[ok] / count[ok]
    di = i - np.repeat(mi, count[ok])
    dy = y - np.repeat(my, count[ok])
    var = float(np.sum(di * di))
    return float(np.sum(di * dy) / var) if var > 0 else 0.0


def _noise_sd(s: np.ndarray) -> float:
    d = np.diff(s)
    sd = _MAD * float(np.median(np.abs(d - np.median(d)))) / np.sqrt(2.0)
    if sd > 0:
        return sd
    # coarsely quantised and quiet: most differences are 0; use the rms of the rest
    small = d[np.abs(d) <= np.percentile(np.abs(d), 99)]
    sd = float(np.sqrt(np.mean(small**2) / 2.0))
    return sd if sd > 0 else 1e-12


def _slip_stretches(s, window, sigma):
    """The force rate, the loading rate (median), the stretches (first, last) where the
    rate lies 2 sd below it and reaches 5 sd below, and the rate's noise sd."""
    from scipy.signal import savgol_filter

    if window >= s.size:
        raise ParameterError(OWNER, "window", f"must be shorter than the trace ({s.size})")
    rate = savgol_filter(s, window, 2, deriv=1, mode="interp")
    rate_sd = sigma * np.sqrt(12.0 / (window * (window**2 - 1.0)))
    g = float(np.median(rate))
    u = rate - g
    first, last = runs(u < -_EXTENT_SIGMAS * rate_sd)
    core = np.concatenate([[0], np.cumsum(u < -_CORE_SIGMAS * rate_sd)])
    has_core = core[last + 1] - core[first] > 0
    return rate, g, (first[has_core], last[has_core]), rate_sd


def _shape(phi, kappa):
    """The normalised drop 0 -> 1 of a damped half-oscillation (see the module doc)."""
    phi = np.clip(phi, 0.0, 1.0)
    decay = np.exp(-kappa * phi)
    full = 1.0 + np.exp(-kappa)
    return (1.0 - decay * (np.cos(np.pi * phi) + kappa / np.pi * np.sin(np.pi * phi))) / full


def _fit_slip(y, a, b, lo_lim, hi_lim, window, drop, sigma):
    """Fit one slip on samples around its stretch a..b; returns (i0, T, y0, D, kappa,
    sd(i0), sd(i0 + T), ok, seen) in samples and scaled force."""
    from scipy.optimize import least_squares

    span = b - a + 1
    margin = max(span, window)
    lo, hi = max(a - margin, lo_lim), min(b + margin, hi_lim)
    i = np.arange(lo, hi + 1, dtype=float)
    yy = y[lo : hi + 1]
    # the smoothed rate stretches a slip by half a window at each end
    i0 = a + 0.5 * (window // 2)
    T = max(span - (window // 2), 2.0)
    y0 = float(np.median(y[max(a - window, lo) : a])) if a > lo else float(y[a])
    p0 = np.array([i0, T, y0, drop, 0.5])
    lower = np.array([lo - 0.5 * span, 0.5, -np.inf, 0.0, 0.0])
    upper = np.array([hi, hi - lo + span, np.inf, np.inf, 8.0])
    p0 = np.clip(p0, lower + 1e-9, upper - 1e-9)

    def residual(p):
        return p[2] - p[3] * _shape((i - p[0]) / p[1], p[4]) - yy

    ok = True
    try:
        sol = least_squares(
            residual, p0, bounds=(lower, upper), loss="soft_l1", f_scale=2.0 * sigma,
            x_scale=np.array([1.0, 1.0, sigma, sigma, 0.1]),
        )  # fmt: skip
        p, jac = sol.x, sol.jac
        ok = bool(sol.success)
    except (ValueError, np.linalg.LinAlgError):
        p, jac, ok = p0, None, False
    sd0 = sd1 = np.nan
    if jac is not None:
        try:
            cov = np.linalg.pinv(jac.T @ jac) * sigma**2
            sd0 = float(np.sqrt(max(cov[0, 0], 0.0)))
            sd1 = float(np.sqrt(max(cov[0, 0] + cov[1, 1] + 2 * cov[0, 1], 0.0)))
        except np.linalg.LinAlgError:
            pass
    seen = p[0] - lo >= 1.0 and lo > 0 or p[0] >= window
    cost = float(np.sum(_soft_l1(residual(p), sigma)))
    return (p[0], p[1], p[2], p[3], p[4], sd0, sd1, ok, seen, (lo, hi, cost))


def _soft_l1(r, sigma):
    """least_squares' soft_l1 loss at f_scale 2 sigma, in units of sigma^2 (chi^2-like)."""
    z = (r / (2.0 * sigma)) ** 2
    return 4.0 * 2.0 * (np.sqrt(1.0 + z) - 1.0)


def _fit_double(y, fit, sigma):
    """The stretch of `fit` as two slips, the second starting at or after the first's
    stick; None unless that fits better by chi^2 > 25."""
    from scipy.optimize import least_squares

    i0, T, y0, D, kappa, *_, (lo, hi, cost) = fit
    i = np.arange(lo, hi + 1, dtype=float)
    yy = y[lo : hi + 1]

    def model(p):
        i0a, ta, da, ka, gap, tb, db, kb, base = p
        i0b = i0a + ta + gap
        return base - da * _shape((i - i0a) / ta, ka) - db * _shape((i - i0b) / tb, kb)

    def residual(p):
        return model(p) - yy

    p0 = np.array([i0, 0.45 * T, 0.5 * D, kappa, 0.0, 0.45 * T, 0.5 * D, kappa, y0])
    lower = np.array([lo - T, 0.5, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, -np.inf])
    upper = np.array([hi, hi - lo + T, np.inf, 8.0, hi - lo, hi - lo + T, np.inf, 8.0, np.inf])
    p0 = np.clip(p0, lower + 1e-9, upper - 1e-9)
    try:
        sol = least_squares(
            residual, p0, bounds=(lower, upper), loss="soft_l1", f_scale=2.0 * sigma,
            x_scale=np.array([1.0, 1.0, sigma, 0.1, 1.0, 1.0, sigma, 0.1, sigma]),
        )  # fmt: skip
    except (ValueError, np.linalg.LinAlgError):
        return None
    p = sol.x
    cost2 = float(np.sum(_soft_l1(residual(p), sigma)))
    if not sol.success or cost - cost2 <= 25.0:
        return None
    i0a, ta, da, ka, gap, tb, db, kb, base = p
    try:
        cov = np.linalg.pinv(sol.jac.T @ sol.jac) * sigma**2
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        sd = np.full(p.size, np.nan)
    first = (i0a, ta, base, da, ka, sd[0], float(np.hypot(sd[0], sd[1])), True, fit[8], fit[9])
    second = (i0a + ta + gap, tb, base - da, db, kb, float(np.hypot(sd[0], sd[4])),
              float(np.hypot(sd[4], sd[5])), True, True, fit[9])  # fmt: skip
    return [first, second]
