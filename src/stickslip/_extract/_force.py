r"""Cycles from a force trace: $F = k\,e$ with $e$ the spring's extension, so $e = F/k$
plays the part of $x$. During a stick the force rises along the loading line at
$g = k v_b$; during a slip it falls. Every threshold below is a multiple (`THRESHOLDS`,
changeable through `extract_cycles(..., thresholds=...)`) of a noise level measured on the
trace itself, and recorded in `Cycles.info`.

1. Spikes: a sample further than `spike` sd from the running median of 7 samples is
   replaced by that median (the source of the measured traces sees spikes a few samples
   wide; a running median leaves a monotone stretch, the loading line and a slip, unchanged).
2. Noise: $\sigma$ = robust sd of the despiked force's first differences over $\sqrt 2$
   (the loading line moves the force by far less than $\sigma$ per sample).
3. Slips: the force rate from a Savitzky-Golay derivative over `window` samples (SciPy).
   Its noise sd is measured as the rate's robust scatter about the loading rate $g$ (its
   median); white noise would give $\sigma\sqrt{12 / (W(W^2-1))}$, coloured noise (the
   measured trace's 50 Hz mains hum passes the derivative filter) more. A slip is a stretch
   where the rate lies more than `extent` sd below $g$ and that reaches `slip` sd below
   somewhere; it counts if the force drops across it by more than `drop` sd of that drop's
   estimate (medians of `window` samples either side; that sd is also measured).
4. Timing: each slip's despiked force, less the loading line, is fitted (robust least
   squares) by the model's damped half-oscillation from the loading line to the stick,
   $y = y_0 - A\,[1 - e^{-\kappa\varphi}(\cos\pi\varphi + \frac{\kappa}{\pi}\sin\pi\varphi)]$
   for $\varphi = (t - t_0)/T_{sl} \in [0, 1]$, flat before and after: $\dot y = 0$ at
   both ends, as when the slider leaves and rejoins the loading line, and the slip ends
   when the velocity first returns, half a damped period after the release. Its
   parameters give the release $t_0$, the slip time $T_{sl}$ and the drop; their standard
   errors (from the fit's Jacobian and $\sigma$) say how well they are timed. Each slip is
   fitted by a compiled Levenberg-Marquardt, the soft-L1 loss by reweighting
   (`_shape_fit`).
5. Re-slips: a fit far longer than the median slip is tried as two slips (the second
   starting at or after the first's stick); kept if chi^2 falls by more than `split`
   times the noise's variance inflation at the rate's scale (1 for white noise) and
   each part drops by more than `drop` sd.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Mapping

import numpy as np

from .._errors import DataError, ParameterError, check_positive
from ._cycles import Cycles
from ._input import (
    OWNER,
    as_series,
    check_length,
    check_times,
    median,
    power_of_two,
    runs,
    weighted_median,
)
from ._median import running_median

# In noise sd. A noise excursion beyond 5 sd: probability 6e-7 per independent value.
THRESHOLDS = {
    "spike": 5.0,  # a sample this far from the running median is a spike
    "slip": 5.0,  # a stretch is a slip candidate if the rate reaches this far below g
    "extent": 2.0,  # ... and a slip's stretch is where the rate lies this far below g
    "drop": 5.0,  # a slip counts if the force drops by more than this (of the drop's sd)
    "split": 25.0,  # chi^2 gain (5 sd) that makes one long slip two
}
_DESPIKE = 7  # running median of 7 samples removes spikes up to 3 samples wide
# The robust sd of white noise's residual about its running median of 7, in the noise's sd
# (4e6 normal samples: 0.8168; a seventh of the residuals are 0): `_spike_scale`.
_MEDIAN_RESIDUAL = 0.817
_FIRST_WINDOW = 11  # the first pass, that measures the slips' length to choose `window`
_MIN_SAMPLES = 64  # fewer samples cannot show a stick, a slip and the next stick
_MIN_SLIP_SAMPLES = 3  # fewer samples per slip cannot time it
_VB_WARN = 0.02  # a given v_b this far from the loading slope's is worth a warning
_VB_UNITS = 2.0  # a factor 2 off is no calibration error: wrong units
# The force rate's scatter over what white noise of the samples' sd gives (the larger at
# the first pass's 11 samples and at the chosen window), spectral lines removed: 1.0-1.1
# on the simulated traces, 1.24 on the measured 42 um/s trace (2.6 with its 50 Hz hum
# left in), 10.3 on the 4300 um/s run, where the force oscillates all the time and never
# follows a loading line. Between 2.6 and 10.3, a factor 2 from either
_SCATTER = 5.5
# a spectral line: a Welch bin of the differences' spectrum (segments of up to 16384
# samples: 0.12 Hz at 2 kHz) 10 times the median of the 65 bins about it; white noise's
# bins scatter by 1/sqrt(segments) about it (10% on the measured trace, 25% on 20 000
# samples): 10 times is far beyond noise
_LINE, _LINE_SEGMENT, _LINE_BINS, _MAX_LINES = 10.0, 16384, 65, 3
# ... searched for only near the mains frequencies and their harmonics (the trace's time in
# s), within 2 % of each: a regular stick-slip's own spectrum is a comb of lines at the
# multiples of its rate (0.65, 1.29, 1.94 Hz ... on a 1.5 s period), which a search over
# all frequencies took for hum and notched out, bending every loading line
_MAINS, _MAINS_BAND = (50.0, 60.0), 0.02
NOTCH_Q = 30.0  # bandwidth f0 / 30: 1.7 Hz at 50 Hz, wider than the mains' wander
# Stick-slip against sliding: the skewness of the force rate at the first pass's window.
# A stick-slip force rises slowly and falls fast (many small positive rates, a few large
# negative ones); an oscillation rises and falls alike, steady sliding is noise. On the six
# public paper-on-paper runs: -2.2 to -6.7 for the three stick-slip runs (the 1100 um/s
# one has rounded sticks, whose varying rate scatters 10.5 times the noise's), -0.64 to
# -0.10 for the three oscillating ones; between them, a factor 2 from either.
_SKEW = -1.2
_UNIFORM = 0.01  # the filters assume even sampling: steps may vary by 1%
_MAD = 1.4826  # MAD to sd for Gaussian noise
_LONG = 1.6  # a fit this many median slips long may be two slips
# The window's search (`_choose_window`): from half the median slip, wider by _WIDER at a
# time while the sticks hide force drops, up to _MAX_WINDOW samples and _STICK_SHARE of the
# median stick; a hidden drop is a step between the medians of _SCAN windows either side
# that passes the drop threshold at that width. At 4 times the default sensor noise on
# generated traces (drops ~9 sd) the first guess, 21 samples, missed 14-41 of ~200 slips
# and took the loading speed 11-30 % low; at 61-131 samples none, and within 0.6 %.
_WIDER, _MAX_WINDOW, _STICK_SHARE, _SCAN = 1.6, 301, 0.25, 3
# A hidden drop counts from this share of the median drop found: the small slips a wider
# window also finds (a real trace's precursors, a noisy slider's micro-slips of a few
# noise sd) hardly bend the loading line (a step of a fifth of a stick's rise in one of
# a hundred sticks moves the slope by ~0.3 %), and chasing them widened the window to
# its limit on the measured slider, finding 18 more slips than the 252 it had.
_HIDDEN_SHARE = 0.2
# A shape fit has converged when a step gains less than this in chi^2 (the soft-L1 cost in
# units of the noise's variance; one standard error of a parameter is a gain of 1). The
# fits that went on past it crawled along flat directions (the kappa of a short slip, the
# empty half of a two-slip fit) for up to 100 steps: on the public runs the slips' times
# moved by at most 0.2 of a sample, and a fit point costs 17 % less.
_GAIN_TOL = 1e-3


def check_thresholds(thresholds) -> dict[str, float]:
    """`THRESHOLDS` updated by a mapping of some of its keys to numbers > 0."""
    out = dict(THRESHOLDS)
    if thresholds is None:
        return out
    if not isinstance(thresholds, Mapping):
        raise ParameterError(OWNER, "thresholds", f"must be a mapping of {', '.join(out)}")
    for key, value in thresholds.items():
        if key not in out:
            raise ParameterError(
                OWNER, "thresholds", f"unknown key {str(key)[:40]!r}: use {', '.join(out)}"
            )
        out[key] = check_positive(OWNER, f"thresholds[{key!r}]", value)
    return out


def extract_force(t, force, stiffness, v_b, window, thresholds=None, lines=None) -> Cycles:
    k = check_positive(OWNER, "stiffness", stiffness)
    v_b = check_positive(OWNER, "v_b", v_b, allow_none=True)
    thr = check_thresholds(thresholds)
    t = as_series("t", t, required=True)
    f = as_series("force", force, required=True)
    check_times(t, minimum=_MIN_SAMPLES)
    check_length("force", f, t.size)
    step = np.diff(t)
    h = median(step)
    if np.max(np.abs(step - h)) > _UNIFORM * h:
        raise ParameterError(
            OWNER, "t", f"must be evenly sampled for a force trace: steps range from "
            f"{step.min():.6g} to {step.max():.6g} about the median {h:.6g}; resample it",
        )  # fmt: skip
    if window is not None:
        window = _odd_window(window)
    lines = _check_lines(lines, h)
    table, info = extract_slips(t, f, h, k, v_b, window, thr, lines)
    return Cycles(table, info)


@dataclasses.dataclass(frozen=True)
class Cut:
    """A force trace with the middles of its sticks cut out (the forward measurement's
    trace, `measured_cycles`): `index`, each kept sample's index in the whole trace; `far`,
    the kept samples as far from every slip as the cut ones (more than `Cut.FAR` windows),
    which stand for those in the trace-wide statistics (the noise sd, the loading rate and
    the rate's scatter, the drop's sd, the spikes' threshold): each counts `weight` times,
    (far kept + cut) / far kept; `shift`, the force taken out of each kept sample: a
    stick's cut ends are joined with the force lowered by the loading line's rise across
    the cut, so that the kept trace is the whole one, less the cut samples, on a line that
    stays continuous (added back to the peak forces)."""

    index: np.ndarray
    far: np.ndarray
    weight: float
    shift: np.ndarray | None = None

    FAR = 2  # in windows of the force rate: what a slip moves (rate, medians) lies within


def extract_slips(t, f, h, k, v_b, window, thr, lines, cut: Cut | None = None):
    """The extraction of a force trace whose settings are checked: `(table, info)`. `t`
    and `f` are evenly sampled at `h` unless `cut` says which samples of such a trace they
    are (`Cut`)."""
    far, weight = (None, 1.0) if cut is None else (cut.far, cut.weight)
    s_f, s, spikes, res_sd = _despiked(f, thr, far, weight)
    s, lines, line_rule = _remove_lines(s, h, lines)
    sigma = _noise_sd(s, far, weight)
    idx = np.arange(s.size, dtype=float)

    first = window or _FIRST_WINDOW
    rate, g, regions, rate_sd, white_sd = _slip_stretches(s, first, sigma, thr, far, weight)
    scatter = rate_sd / white_sd
    skew = _skewness(rate, far, weight)
    search = None
    if window is None:
        if cut is not None:
            raise ParameterError(OWNER, "window", "must be given for a cut trace")
        window = _odd_window(min(max(_first_guess(rate, g, regions), 5), 101))
        # ... then wider while the sticks still hide force drops (`_choose_window`)
        window, search = _choose_window(s, window, sigma, thr, regions)
        if window != first:
            rate, g, regions, rate_sd, white_sd = _slip_stretches(s, window, sigma, thr, far,
                                                                  weight)  # fmt: skip
    # the larger of the two passes': coloured sensor noise peaks at one scale, a force that
    # never sticks scatters at all
    scatter = max(scatter, rate_sd / white_sd)
    # a rate that scatters far more than the noise explains: sliding, unless the force
    # still rises slowly and falls fast (rounded sticks, whose rate varies along them)
    if scatter > _SCATTER and skew > _SKEW:
        raise DataError(
            f"extract_cycles: no stick found: the force rate scatters {scatter:.3g} times as "
            f"much as the samples' noise (sd {sigma * s_f:.3g}) explains and rises and falls "
            f"alike (skewness {skew:+.2f}; a stick-slip force rises slowly and falls fast, "
            f"below {_SKEW:g}): an oscillation or steady sliding (analyse_run reads which)"
        )
    a, b = regions
    stick = _stick_mask(s.size, regions, window)
    if stick.sum() < window:
        raise DataError(
            "extract_cycles: no stick found: the force rate lies below its median on "
            f"{100 * (1 - stick.mean()):.3g}% of the trace"
        )
    if cut is None:
        g = _loading_slope(s, stick)  # per sample, from the sticks alone
    else:  # on the whole trace's positions: the slips' ends weigh as they would there
        g = _loading_slope(s + (0.0 if cut.shift is None else cut.shift / s_f), stick,
                           cut.index.astype(float))  # fmt: skip
    if g <= 0:
        raise DataError(
            "extract_cycles: no stick found: between the force drops the force does not rise "
            f"(loading rate {g * s_f / h:.3g} per s): continuous sliding?"
        )
    v_b_est = g * s_f / h / k
    hidden = None if search is None else search[-1]["hidden"]
    if v_b is not None:
        _check_loading(g * s_f / h, k, v_b, hidden, window, sigma * s_f)
    y = s - g * idx  # flat in a stick
    drop_sd = _drop_sd(y, window, sigma, far, weight)
    lo_lim, hi_lim, drops = _stretch_drops(y, regions, window)
    largest = float(np.max(drops, initial=-np.inf) / drop_sd)
    keep = drops > thr["drop"] * drop_sd
    fits = _fit_slips(y, a[keep], b[keep], lo_lim[keep], hi_lim[keep], window, drops[keep], sigma)
    # coloured noise inflates a chi^2 gain over a slip's few window lengths by the rate's
    # variance ratio; white noise: 1
    split_gain = thr["split"] * (rate_sd / white_sd) ** 2
    fits, n_split = _split_doubles(y, fits, sigma, split_gain, thr["drop"] * drop_sd)
    if len(fits) < 2:
        raise DataError(
            f"extract_cycles: no stick-slip: {len(fits)} force drop(s) above {thr['drop']:g} "
            f"sd of their estimate (noise sd {sigma * s_f:.3g}; the largest drop is "
            f"{largest:.3g} sd); a complete cycle needs two slips"
        )
    table = _cycles_table(fits, t, idx, h, g, s_f, k, cut)
    info = _info(
        fits, k=k, v_b=v_b, v_b_est=v_b_est, h=h, thr=thr, lines=lines, line_rule=line_rule,
        res_sd=res_sd, s_f=s_f, spikes=spikes, sigma=sigma, window=window, search=search,
        hidden=hidden, rate_sd=rate_sd, white_sd=white_sd, skew=skew, drop_sd=drop_sd,
        split_gain=split_gain, n_split=n_split,
        n_samples=s.size if cut is None else int(cut.index[-1] - cut.index[0] + 1),
    )  # fmt: skip
    return table, info


def _cycles_table(fits, t, idx, h, g, s_f, k, cut) -> dict:
    """The cycles of the slips' fits (each slip with the stick after it; a slip whose
    release has no loading line before it in the trace left out), in the trace's units."""
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
    return dict(
        release_time=release[:-1][keep],
        slip_time=slip_time[keep],
        slip_distance=drop_f[keep] / k,
        stick_time=stick_time[keep],
        period=(slip_time + stick_time)[keep],
        peak_force=((y0 + g * i0) * s_f + _shift(cut, i0))[:-1][keep],
        force_drop=drop_f[keep],
    )


def _despiked(f, thr, far, weight):
    """The force scaled by a power of 2 (exact: a trace in any units finds the same
    cycles), its spikes (further than `thr["spike"]` robust sd from a running median)
    replaced by that median: `(scale, force, spikes, the residual's robust sd)`."""
    s_f = power_of_two(float(np.max(np.abs(f))))
    y_raw = f / s_f
    if np.ptp(y_raw) == 0:
        raise DataError("extract_cycles: no stick-slip: the force is constant")
    med = running_median(y_raw, _DESPIKE)
    resid = y_raw - med
    res_sd = _spike_scale(y_raw, resid, far, weight)
    spikes = np.abs(resid) > thr["spike"] * res_sd if res_sd > 0 else np.zeros(f.size, bool)
    return s_f, np.where(spikes, med, y_raw), spikes, res_sd


def _first_guess(rate, g, regions) -> int:
    """A first window: half the median length of the slip stretches weighted by the drop
    each carries (the big slips set the scale, not the many short stretches of small noise
    bumps)."""
    lengths = regions[1] - regions[0] + 1
    guess = _FIRST_WINDOW
    if lengths.size:
        cum = np.concatenate([[0.0], np.cumsum(rate - g)])
        weight = np.maximum(cum[regions[0]] - cum[regions[1] + 1], 0.0)
        order = np.argsort(lengths)
        share = np.cumsum(weight[order])
        guess = int(lengths[order][np.searchsorted(share, 0.5 * share[-1])]) // 2
    return guess


def _check_loading(rate, k, v_b, hidden, window, noise_sd) -> None:
    """The sticks' loading `rate` (force per s) against the given `v_b`: refused far from
    it (units, or drops hidden in the sticks that bend the loading line), a warning when
    it differs by more than a few per cent (the slope is used)."""
    v_b_est = rate / k
    ratio = v_b_est / v_b
    if not 1 / _VB_UNITS < ratio < _VB_UNITS:
        why = (
            f"but {hidden} force drops lie hidden in the sticks even at a window of "
            f"{window} samples: the slips are too small against the noise (sd "
            f"{noise_sd:.3g}) to be found, and the missed drops bend the loading "
            "line; give a larger window (or check the units)"
            if hidden else "check the units of force, stiffness and v_b"
        )  # fmt: skip
        raise DataError(
            f"extract_cycles: the sticks load the force at {rate:.4g} per s, which "
            f"with stiffness={k:.6g} means v_b = {v_b_est:.4g}, {ratio:.3g} times the "
            f"given v_b={v_b:.6g}: {why}"
        )
    if abs(ratio - 1) > _VB_WARN:
        warnings.warn(
            f"extract_cycles: the sticks' loading slope gives v_b = {v_b_est:.4g}, "
            f"{100 * (ratio - 1):+.2g}% from the given v_b = {v_b:.6g}; the slope is used",
            stacklevel=6,
        )


def _split_doubles(y, fits, sigma, split_gain, drop_min):
    """The long slips (past `_LONG` times the median) that two slips fit better (by more
    than `split_gain` in chi^2) replaced by those two: the fits and how many were split."""
    n_split = 0
    if len(fits):
        long = np.flatnonzero(fits[:, 1] > _LONG * float(np.median(fits[:, 1])))
        pairs = dict(zip(long.tolist(), _fit_doubles(y, fits[long], sigma, split_gain, drop_min),
                         strict=True))  # fmt: skip
        rows = []
        for j, fit in enumerate(fits):
            pair = pairs.get(j)
            rows.extend(pair or [fit])
            n_split += pair is not None
        fits = np.array(rows).reshape(-1, fits.shape[1])
    return fits, n_split


def _info(fits, *, k, v_b, v_b_est, h, thr, lines, line_rule, res_sd, s_f, spikes, sigma,
          window, search, hidden, rate_sd, white_sd, skew, drop_sd, split_gain, n_split,
          n_samples) -> dict:  # fmt: skip
    """How a force trace's cycles were found: every setting, threshold and rule."""
    ok = fits[:, 7].astype(bool)
    return dict(
        input="force", units="force in the units given (N), time in s, lengths in m",
        stiffness=k, v_b=v_b, v_b_estimated=float(v_b_est),
        v_b_rule="loading slope of the sticks (pooled least squares between slips) / stiffness",
        sampling_interval=h, n_samples=n_samples,
        thresholds=thr,
        lines_removed=lines,
        line_rule=line_rule,
        despike=f"running median of {_DESPIKE} samples; a sample further than "
        f"{thr['spike']:g} sd of the residual from it is replaced by it",
        spike_threshold=float(thr["spike"] * res_sd * s_f), n_spikes=int(spikes.sum()),
        noise_sd=float(sigma * s_f),
        noise_rule="robust sd (1.4826 MAD) of the despiked force's differences / sqrt(2)",
        window=int(window),
        window_rule="given" if search is None else (
            f"half the median slip of a first pass with {_FIRST_WINDOW} samples, widened "
            f"{_WIDER:g}x at a time (up to {_MAX_WINDOW} samples and a {_STICK_SHARE:g} "
            "of the median stick) while the sticks hide force drops (a step between the "
            f"medians of {_SCAN} windows either side beyond the drop threshold and "
            f"{_HIDDEN_SHARE:g} of the median drop)"
        ),
        windows_tried=None if search is None else [
            [int(x["window"]), int(x["drops"]), int(x["hidden"])] for x in search
        ],
        hidden_drops=None if search is None else int(hidden),
        miss_rate=None if search is None else float(
            hidden / max(search[-1]["drops"] + hidden, 1)
        ),
        filter=f"scipy.signal.savgol_filter, {window} samples, polyorder 2, first derivative",
        rate_noise_sd=float(rate_sd * s_f / h),
        rate_noise_rule="robust sd of the force rate about the loading rate (at least "
        "white noise's)",
        rate_noise_ratio=float(rate_sd / white_sd),
        rate_skewness=float(skew),
        slip_rate_threshold=float(thr["slip"] * rate_sd * s_f / h),
        extent_rate_threshold=float(thr["extent"] * rate_sd * s_f / h),
        drop_noise_sd=float(drop_sd * s_f),
        drop_threshold=float(thr["drop"] * drop_sd * s_f),
        split_chi2=float(split_gain),
        timing="fit of a damped half-oscillation to each slip (Levenberg-Marquardt, "
        "soft-L1 loss at 2 noise sd)",
        release_sd_median=float(np.median(fits[:, 5]) * h),
        stick_sd_median=float(np.median(fits[:, 6]) * h),
        timing_sd_rule="from the fit's Jacobian and the white noise sd; coloured noise widens "
        "it, by up to rate_noise_ratio",
        n_slips=int(len(fits)), n_fit_failed=int((~ok).sum()), n_split=n_split,
        tol=float(thr["drop"] * sigma * s_f),
    )  # fmt: skip


def _shift(cut, i) -> np.ndarray | float:
    """The force a cut trace's samples at (fractional) positions `i` were lowered by."""
    if cut is None or cut.shift is None:
        return 0.0
    return np.interp(i, np.arange(cut.shift.size, dtype=float), cut.shift)


def _skewness(rate, far=None, weight=1.0) -> float:
    """The third standardised moment of the force rate (0 for a constant rate); with `far`,
    those samples count `weight` times (`Cut`)."""
    # (dot products: np.average's temporaries and u**3's power took 13 ms on a fit's
    # 10^6-sample traces, a tenth of its extraction)
    if far is None:
        u = rate - rate.mean()
        u2 = u * u
        var, third = u2.mean(), _dot(u2, u) / u.size
    else:
        w = np.where(far, weight, 1.0)
        total = w.sum()
        u = rate - _dot(w, rate) / total
        u2 = u * u
        var, third = _dot(w, u2) / total, _dot(w * u2, u) / total
    sd = float(np.sqrt(var))
    return float(third / sd**3) if sd > 0 else 0.0


def read_regime(t, f) -> dict:
    """Whether a force trace is stick-slip by its shape (`analyse_run`): despiked and its
    mains lines notched as `extract_force` does, its rate at the first pass's window, its
    skewness against `_SKEW` and the share of samples where it falls, in one line; the
    despiked force, its mean and the samples' noise sd (N)."""
    from scipy.signal import savgol_filter

    h = median(np.diff(t))
    med = running_median(f, _DESPIKE)
    resid = f - med
    res_sd = _spike_scale(f, resid)
    spikes = np.abs(resid) > THRESHOLDS["spike"] * res_sd if res_sd > 0 else resid != resid
    s = np.where(spikes, med, f)
    s, _, _ = _remove_lines(s, h)
    window = min(_FIRST_WINDOW, s.size - 1 - (s.size % 2 == 0))
    rate = savgol_filter(s, window, 2, deriv=1, mode="interp")
    skew = _skewness(rate)
    fall = float(np.mean(rate < 0))
    stick_slip = skew <= _SKEW
    evidence = (
        f"the force rate is skewed {skew:+.2f} and falls on {100 * fall:.0f} % of the "
        f"samples ({'a slow rise and a fast fall' if stick_slip else 'rising and falling alike'}"
        f"; stick-slip below {_SKEW:g})"
    )
    return dict(stick_slip=bool(stick_slip), evidence=evidence, despiked=s, skew=skew,
                fall=fall, mean=float(np.mean(s)), noise=float(_noise_sd(s)))  # fmt: skip


def _stick_mask(size, regions, window) -> np.ndarray:
    """True on the samples a window or more away from every slip stretch."""
    stick = np.ones(size, bool)
    for lo, hi in zip(regions[0].tolist(), regions[1].tolist(), strict=True):
        stick[max(lo - window, 0) : hi + window + 1] = False
    return stick


def _choose_window(s, window, sigma, thr, first_regions) -> tuple[int, list[dict]]:
    """The force rate's window: `window` (half the median slip), wider by `_WIDER` at a
    time while the sticks between the slips it finds still hide force drops
    (`_hidden_drops`), up to `_MAX_WINDOW` samples and `_STICK_SHARE` of the median stick
    (the first pass's spacing of its stretches): the first that hides none, or else the one
    that hides fewest. Returns it and, per window tried, its slips and hidden drops, the
    chosen one last. A wider window finds smaller drops (its rate's noise falls as
    W^-3/2, a slip's rate as 1/W once W passes its length); the slips are timed by their
    shape fits whatever the window."""
    a, b = first_regions
    gaps = a[1:] - b[:-1]
    longest = _MAX_WINDOW
    if gaps.size:
        longest = min(_MAX_WINDOW, max(int(_STICK_SHARE * float(np.median(gaps))), 5))
    longest = _odd_window(max(longest, window))
    tried = []
    while True:
        tried.append(_hidden_pass(s, window, sigma, thr))
        if tried[-1]["hidden"] == 0 or window >= longest:
            break
        window = _odd_window(min(int(_WIDER * window), longest))
    best = min(tried, key=lambda x: (x["hidden"], x["window"]))
    tried.remove(best)
    return best["window"], [*tried, best]


def _hidden_pass(s, window, sigma, thr) -> dict:
    """A pass at `window` up to the drops (as `extract_force` makes it): its slips (the
    stretches whose drop passes the threshold) and the force drops its sticks hide."""
    rate, g, regions, rate_sd, white_sd = _slip_stretches(s, window, sigma, thr)
    stick = _stick_mask(s.size, regions, window)
    out = dict(window=window, drops=0, hidden=0)
    if stick.sum() < window:
        return out
    g = _loading_slope(s, stick)
    y = s - g * np.arange(s.size, dtype=float)
    drop_sd = _drop_sd(y, window, sigma)
    _, _, drops = _stretch_drops(y, regions, window)
    found = drops > thr["drop"] * drop_sd
    out["drops"] = int(np.sum(found))
    least = _HIDDEN_SHARE * float(np.median(drops[found])) if found.any() else 0.0
    out["hidden"] = _hidden_drops(y, stick, _odd_window(_SCAN * window), sigma, thr, least)
    return out


def _stretch_drops(y, regions, window):
    """Each stretch's drop in the flattened force `y`: the medians of up to `window`
    samples either side, not reaching into the neighbouring stretches (-inf where a side
    is empty); with the limits `(lo_lim, hi_lim)` each stretch's samples keep within."""
    a, b = regions
    lo_lim = np.concatenate([[0], b[:-1] + 1])
    hi_lim = np.concatenate([a[1:] - 1, [y.size - 1]])
    before = _medians(y, np.maximum(a - window, lo_lim), a)
    after = _medians(y, b + 1, np.minimum(b + 1 + window, hi_lim + 1))
    drops = np.where(np.isnan(before) | np.isnan(after), -np.inf, before - after)
    return lo_lim, hi_lim, drops


def _hidden_drops(y, stick, width, sigma, thr, least=0.0) -> int:
    """How many force drops the sticks hide: in each stretch of `stick` at least two
    `width`s long, the runs of positions (every quarter width) where the median of the
    `width` samples before less that of the `width` after passes the drop threshold at
    that width (`_drop_sd`) and `least`. A flattened stick is flat: only a slip the
    detector missed makes such a step (the offset's drift moves it by far less over a few
    windows)."""
    first, last = runs(stick)
    keep = last - first + 1 >= 2 * width
    first, last = first[keep], last[keep]
    if first.size == 0:
        return 0
    stride = max(1, width // 4)
    at, piece = [], []
    for j, (lo, hi) in enumerate(zip(first.tolist(), last.tolist(), strict=True)):
        p = np.arange(lo + width, hi - width + 2, stride)
        at.append(p)
        piece.append(np.full(p.size, j))
    at, piece = np.concatenate(at), np.concatenate(piece)
    step = _medians(y, at - width, at) - _medians(y, at, at + width)
    over = step > max(thr["drop"] * _drop_sd(y, width, sigma), least)
    # a run of positions over the threshold within one stick is one drop
    starts = over & ~np.concatenate([[False], over[:-1] & (piece[1:] == piece[:-1])])
    return int(np.sum(starts))


def _odd_window(window) -> int:
    from .._errors import check_int

    w = check_int(OWNER, "window", window, minimum=5)
    return w if w % 2 else w + 1


def _medians(y, start, stop) -> np.ndarray:
    """The median of each `y[start[j]:stop[j]]` (nan where empty), all at once: the same
    numbers as `np.median` of each slice (the middle value, or the mean of the two)."""
    count = np.maximum(stop - start, 0)
    out = np.full(count.size, np.nan)
    if count.size == 0 or count.max() == 0:
        return out
    width = int(count.max())
    j = np.arange(width)
    take = np.minimum(start[:, None] + j[None, :], y.size - 1)
    vals = np.sort(np.where(j[None, :] < count[:, None], y[take], np.inf), axis=1)
    ok = count > 0
    row = np.flatnonzero(ok)
    lo, hi = vals[row, (count[ok] - 1) // 2], vals[row, count[ok] // 2]
    out[ok] = (lo + hi) / 2.0  # one middle value: (v + v) / 2 is v
    return out


def _dot(a, b) -> float:
    """The dot product of two long 1-d arrays, in this thread: np.dot hands them to BLAS,
    whose threads then spin for some milliseconds after the call, a second core taken
    from the simulator's and the shape fits' threads (measured: 0.1 s of CPU a fit's point
    of 0.13 s)."""
    return float(np.einsum("i,i->", a, b))


def _loading_slope(s, stick, position=None) -> float:
    """The sticks' pooled least-squares slope: each stick's own line, one common slope (an
    offset drift moves each stick's level, hardly its slope). Its sd is sigma over the root
    of the summed squared spreads of the sticks' sample indices: far below 1% here. Each
    stick is a run of consecutive samples, so its indices' spread about their mean is
    n (n^2 - 1) / 12 in closed form and the sums run once over the stuck samples (5-6 times
    faster than labelling them, the same number to 1e-16)."""
    first, last = runs(stick)
    n = last - first + 1
    if n.size == 0:
        return 0.0
    y = s[stick]
    starts = np.concatenate([[0], np.cumsum(n)[:-1]])
    if position is not None:  # a cut trace: its samples' positions in the whole one
        x = position[stick]
        x = x - np.repeat(np.add.reduceat(x, starts) / n, n)
        var = _dot(x, x)
        return _dot(x, y - np.repeat(np.add.reduceat(y, starts) / n, n)) / var \
            if var > 0 else 0.0  # fmt: skip
    mean_y = np.add.reduceat(y, starts) / n
    # each sample's index within its stick, less the stick's mean index
    j = np.arange(y.size, dtype=float) - np.repeat(starts + 0.5 * (n - 1), n)
    var = float(np.sum(n * (n * n - 1.0) / 12.0))
    return _dot(j, y - np.repeat(mean_y, n)) / var if var > 0 else 0.0


def _drop_sd(y, window, sigma, far=None, weight=1.0) -> float:
    """The sd of a drop's estimate, the median of `window` samples of the flattened force
    before a slip less that after: for white noise 1.2533 sigma sqrt(2 / window); measured
    on the trace (consecutive blocks, robustly: slips are a few % of them) where the noise
    is coloured; whichever is larger."""
    white = 1.2533 * sigma * math.sqrt(2.0 / window)
    n = y.size // window
    if n < 8:
        return white
    # each block's middle value (the window is odd): np.median's, without its per-row mean
    blocks = np.partition(y[: n * window].reshape(n, window), window // 2, axis=1)
    d = np.diff(blocks[:, window // 2])
    if far is None:
        return max(white, _MAD * float(np.median(np.abs(d - np.median(d)))))
    far = far[: n * window].reshape(n, window).all(axis=1)
    far = far[1:] & far[:-1]
    return max(white, _MAD * weighted_median(np.abs(d - weighted_median(d, far, weight)), far,
                                             weight))  # fmt: skip


def _check_lines(lines, h):
    """`lines` as `extract_cycles` takes it: None (search near the mains frequencies), or
    the frequencies to notch, each > 0 and below the Nyquist frequency."""
    if lines is None:
        return None
    if isinstance(lines, (str, bytes)) or not hasattr(lines, "__iter__"):
        raise ParameterError(OWNER, "lines", "must be a sequence of frequencies (or None)")
    out = []
    for f in lines:
        f = check_positive(OWNER, "lines", f)
        if not f < 0.5 / h:
            raise ParameterError(
                OWNER, "lines", f"must lie below the Nyquist frequency {0.5 / h:.6g}", f
            )
        out.append(float(f))
    return tuple(out)


def _remove_lines(s, h, given=None):
    """`s` less its spectral lines (a mains hum, say), the frequencies removed and the rule.
    `given` (frequencies in the inverse of t's unit): notch those. None: search a Welch
    spectrum of the force's differences (white for white noise; the sawtooth's own
    spectrum a comb at the multiples of its rate) near the mains frequencies, 50 and 60 Hz
    and their harmonics (`_MAINS_BAND`), for a bin `_LINE` times the level about it or
    more, the strongest first, at most `_MAX_LINES`. Each is notched out by scipy's
    iirnotch (Q = 30) run forwards and backwards (filtfilt: zero phase)."""
    from scipy.ndimage import median_filter
    from scipy.signal import filtfilt, iirnotch, welch

    fs = 1.0 / h
    notch = f"notched out (scipy iirnotch Q {NOTCH_Q:g}, filtfilt)"
    if given is not None:
        for f0 in given:
            b, a = iirnotch(f0, NOTCH_Q, fs=fs)
            s = filtfilt(b, a, s)
        return s, [round(f, 6) for f in given], f"the lines given, {notch}"
    rule = (
        f"Welch bins of the despiked differences >= {_LINE:g} x their median within "
        f"{100 * _MAINS_BAND:g} % of 50 or 60 Hz or a harmonic (t in s), {notch}, at most "
        f"{_MAX_LINES}"
    )
    n = min(_LINE_SEGMENT, 1 << int(np.log2(max(s.size // 8, 1))))
    if n < 256:
        return s, [], rule
    # no per-segment detrending (scipy's costs a fifth of an extraction): a constant moves
    # only the bins below 2 (the Hann window's), which the search leaves out
    freq, power = welch(np.diff(s), fs=fs, nperseg=n, detrend=False)
    # the level about each bin: the spectrum is smooth but not flat (differencing, slips)
    base = median_filter(power, size=_LINE_BINS, mode="nearest")
    usable = (freq > 4 * fs / n) & (freq < 0.45 * fs)  # not the drift, not near Nyquist
    usable &= _near_mains(freq)
    excess = np.where(usable & (base > 0), power / np.where(base > 0, base, 1.0), 0.0)
    lines = []
    for _ in range(_MAX_LINES):
        j = int(np.argmax(excess))
        if not excess[j] > _LINE:
            break
        near = slice(max(j - 2, 0), j + 3)
        f0 = float(np.sum(freq[near] * power[near]) / np.sum(power[near]))
        excess[max(j - 4, 0) : j + 5] = 0.0
        if not _near_mains(f0):  # a broad peak's shoulder in the band, centred outside it
            continue
        b, a = iirnotch(f0, NOTCH_Q, fs=fs)
        s = filtfilt(b, a, s)
        lines.append(round(f0, 3))
    return s, lines, rule


def _near_mains(freq):
    """Whether each frequency lies within `_MAINS_BAND` of 50 or 60 Hz or a harmonic."""
    freq = np.asarray(freq, float)
    out = np.zeros(freq.shape, bool)
    for f0 in _MAINS:
        m = np.maximum(np.round(freq / f0), 1.0)
        out |= np.abs(freq - m * f0) <= _MAINS_BAND * m * f0
    return out


def _robust_sd(d: np.ndarray, far=None, weight=1.0) -> float:
    """1.4826 MAD; where over half the values are equal (coarsely quantised, quiet), the
    rms of the values within their 99th percentile of size (0 if they are all equal).
    With `far`, those values count `weight` times (`Cut`)."""
    sd = _MAD * weighted_median(np.abs(d - weighted_median(d, far, weight)), far, weight)
    if sd > 0:
        return sd
    small = d[np.abs(d) <= np.percentile(np.abs(d), 99)]
    return float(np.sqrt(np.mean(small**2)))


def _spike_scale(y, resid, far=None, weight=1.0) -> float:
    """The scale of a sample's residual `resid` about the running median of `y`, against
    which a spike is judged: its robust sd, but at least what white noise of the
    differences' sd gives (`_MEDIAN_RESIDUAL`). A running median follows a steep loading
    line sample for sample: where the line rises by about a noise sd a sample, the middle
    sample is its window's median in over 40 % of the windows (a seventh for noise alone)
    and the residuals' robust sd falls to a quarter of the noise's. On a generated trace
    (0.15 mN a sample, 0.2 mN of noise) 13 % of the samples were then taken for spikes,
    replaced by the median (the noise measured 13 % low) and put back into the model's
    trace as spikes of their own."""
    return max(_robust_sd(resid, far, weight), _MEDIAN_RESIDUAL * _noise_sd(y, far, weight))


def _noise_sd(s: np.ndarray, far=None, weight=1.0) -> float:
    far = None if far is None else far[1:] & far[:-1]
    sd = _robust_sd(np.diff(s), far, weight) / np.sqrt(2.0)
    return sd if sd > 0 else 1e-12


def _slip_stretches(s, window, sigma, thr, far=None, weight=1.0):
    """The force rate, the loading rate (median), the stretches (first, last) where the
    rate lies `extent` sd below it and reaches `slip` sd below, the rate's noise sd
    (measured) and white noise's; with `far`, those samples count `weight` times in the
    median and the sd (`Cut`)."""
    from scipy.signal import savgol_filter

    if window >= s.size:
        raise ParameterError(OWNER, "window", f"must be shorter than the trace ({s.size})")
    rate = savgol_filter(s, window, 2, deriv=1, mode="interp")
    white_sd = sigma * math.sqrt(12.0 / (window * (window**2 - 1.0)))
    g = weighted_median(rate, far, weight)
    u = rate - g
    # slips are a few % of the samples: the MAD sees the noise only
    rate_sd = max(white_sd, _MAD * weighted_median(np.abs(u), far, weight))
    first, last = runs(u < -thr["extent"] * rate_sd)
    core = np.concatenate([[0], np.cumsum(u < -thr["slip"] * rate_sd)])
    has_core = core[last + 1] - core[first] > 0
    return rate, g, (first[has_core], last[has_core]), rate_sd, white_sd


def _fit_slips(y, a, b, lo_lim, hi_lim, window, drop, sigma) -> np.ndarray:
    """Fit each slip on samples around its stretch a..b; rows of (i0, T, y0,
    D, kappa, sd(i0), sd(i0 + T), ok, seen, lo, hi, cost) in samples and scaled force."""
    span = b - a + 1
    margin = np.maximum(span, window)
    lo, hi = np.maximum(a - margin, lo_lim), np.minimum(b + margin, hi_lim)
    # the smoothed rate stretches a slip by half a window at each end
    i0 = a + 0.5 * (window // 2)
    T = np.maximum(span - (window // 2), 2.0)
    y0 = _medians(y, np.maximum(a - window, lo), a)
    y0 = np.where(a > lo, y0, y[a])
    p0 = np.column_stack([i0 - lo, T, y0, drop, np.full(a.size, 0.5)])
    lower = np.column_stack([-0.5 * span, np.full(a.size, 0.5), np.full(a.size, -np.inf),
                             np.zeros(a.size), np.zeros(a.size)])  # fmt: skip
    upper = np.column_stack([hi - lo, hi - lo + span, np.full(a.size, np.inf),
                             np.full(a.size, np.inf), np.full(a.size, 8.0)])  # fmt: skip
    p0 = np.clip(p0, lower + 1e-9, upper - 1e-9)
    from ._shape_fit import fit_windows  # (Numba imported on first use)

    p, ok, cost, cov = fit_windows(False, y, lo, hi - lo + 1, p0, lower, upper, sigma, _GAIN_TOL)
    sd0 = np.sqrt(np.maximum(cov[:, 0, 0], 0.0))
    sd1 = np.sqrt(np.maximum(cov[:, 0, 0] + cov[:, 1, 1] + 2 * cov[:, 0, 1], 0.0))
    i0_fit = p[:, 0] + lo
    seen = ((p[:, 0] >= 1.0) & (lo > 0)) | (i0_fit >= window)
    return np.column_stack([i0_fit, p[:, 1:], sd0, sd1, ok, seen, lo, hi, cost])


def _fit_doubles(y, fits, sigma, min_gain, min_drop):
    """Each fit (a row of `_fit_slips`) as two slips, the second starting at or after the
    first's stick; a list with, per fit, its two rows or None unless two
    lower chi^2 by more than `min_gain` and each part drops by more than `min_drop` (the
    drop a slip found on its own needs)."""
    i0, T, y0, D, kappa = fits[:, :5].T
    lo, hi, cost = fits[:, 9].astype(int), fits[:, 10].astype(int), fits[:, 11]
    n, span = fits.shape[0], (hi - lo).astype(float)
    zeros, ones = np.zeros(n), np.ones(n)
    p0 = np.column_stack([i0 - lo, 0.45 * T, 0.5 * D, kappa, zeros, 0.45 * T, 0.5 * D, kappa,
                          y0])  # fmt: skip
    lower = np.column_stack([-T, 0.5 * ones, zeros, zeros, zeros, 0.5 * ones, zeros, zeros,
                             np.full(n, -np.inf)])  # fmt: skip
    upper = np.column_stack([span, span + T, np.full(n, np.inf), 8.0 * ones, span, span + T,
                             np.full(n, np.inf), 8.0 * ones, np.full(n, np.inf)])  # fmt: skip
    p0 = np.clip(p0, lower + 1e-9, upper - 1e-9)
    from ._shape_fit import fit_windows  # (Numba imported on first use)

    p, ok, cost2, cov = fit_windows(True, y, lo, hi - lo + 1, p0, lower, upper, sigma, _GAIN_TOL)
    sd = np.sqrt(np.maximum(np.einsum("nii->ni", cov), 0.0))
    result = [None] * n
    for j in range(n):
        i0a, ta, da, ka, gap, tb, db, kb, base = p[j]
        if not ok[j] or cost[j] - cost2[j] <= min_gain or min(da, db) <= min_drop:
            continue
        e = sd[j]
        rest = (lo[j], hi[j], cost2[j])
        first = (i0a + lo[j], ta, base, da, ka, e[0], np.hypot(e[0], e[1]), True, fits[j, 8],
                 *rest)  # fmt: skip
        second = (i0a + ta + gap + lo[j], tb, base - da, db, kb, np.hypot(e[0], e[4]),
                  np.hypot(e[4], e[5]), True, True, *rest)  # fmt: skip
        result[j] = [first, second]
    return result
