"""The forward measurement cut about the slips (`measured_cycles(..., sticks="cut")`, the
default for a force trace): the same cycles as `extract_cycles` finds on every sample of
the same simulated trace (the reference: the public extraction, on the whole trace), the
trace-wide statistics of the whole trace from the kept samples, the keyed noise the same
on whichever samples are drawn, and `weighted_median` against the median of the values
written out as often as they count."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy import stats

import stickslip as ss
from stickslip._extract._force import check_thresholds, extract_slips
from stickslip._extract._input import weighted_median
from stickslip._inference.measurement import (
    Measurement,
    keyed_samples,
    measured_cycles,
    measured_trace,
)

# The measured slider of the examples in its reference units: 2 kHz (h = 0.037 of its
# time unit), its noise, spikes, mains line and window; the model near its fit.
SLIDER = dict(omega0=1.24, zeta=1e-3, v_b=0.02, tau=0.1, D=0.37, x0=1.0)
MEASUREMENT = dict(sampling_interval=0.037, signal="force", noise_sd=0.0375, window=29,
                   spike_fraction=0.011, spike_height=0.52, lines=(0.676,),
                   line_amplitude=0.0375,
                   columns=("slip_time", "stick_time", "slip_distance", "peak_force"))  # fmt: skip


def _both(n, seed, **changes):
    """The whole trace's cycles through `extract_cycles`, the cut trace's through the
    forward path, the truth, each extraction's settings and both traces."""
    model = ss.get_model("langevin")(**SLIDER)
    m = Measurement(**{**MEASUREMENT, **changes})
    settings = m.extract_settings(model.v_b)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whole = measured_trace(model, m, n, seed, sticks="whole")
        (w,) = whole.traces
        reference = ss.extract_cycles(**w, **settings)
        cut = measured_trace(model, m, n, seed, sticks="cut")
        (c,) = cut.traces
        # (the cut trace's lines are notched as it is made: `_notched`; the extraction's
        # info, which `extracted` leaves out, has the trace-wide statistics)
        table, info = extract_slips(c["t"], c["force"], m.sampling_interval, 1.0, model.v_b,
                                    m.window, check_thresholds(None), (), cut=c["cut"])  # fmt: skip
    np.testing.assert_array_equal(whole.truth["release_time"], cut.truth["release_time"])
    return reference, (table, info), whole.truth, (w, c)


@pytest.fixture(scope="module", params=["mains line", "no line"])
def pair(request):
    if request.param == "no line":
        return _both(600, 4, lines=(), line_amplitude=0.0)
    return _both(600, 4)


def _match(a, b, tol):
    j = np.clip(np.searchsorted(b, a), 1, b.size - 1)
    j = np.where(np.abs(b[j - 1] - a) <= np.abs(b[j] - a), j - 1, j)
    ok = np.abs(b[j] - a) <= tol
    return np.flatnonzero(ok), j[ok]


@pytest.mark.parametrize("lines", [(), (0.676,), (0.676, 1.352)])
def test_the_cut_trace_is_the_whole_one_notched_at_its_samples(lines):
    """Without noise, the kept samples plus the loading line's rise across the cuts are the
    whole trace through scipy's filtfilt of the extraction's notches: to 1e-8 away from
    the trace's ends (where filtfilt's padding differs from the steady state assumed),
    and a sixth of the samples or fewer kept."""
    from scipy.signal import filtfilt, iirnotch

    from stickslip._extract._force import NOTCH_Q

    model = ss.get_model("langevin")(**SLIDER)
    # (no hum either: the notch's removal of it is scipy's, to 2e-5 of its amplitude)
    quiet = dict(MEASUREMENT, noise_sd=0.0, spike_fraction=0.0, spike_height=0.0,
                 lines=lines, line_amplitude=0.0)  # fmt: skip
    m = Measurement(**quiet)
    (w,) = measured_trace(model, m, 300, 2, sticks="whole").traces
    (c,) = measured_trace(model, m, 300, 2, sticks="cut").traces
    cut = c["cut"]
    assert cut.index.size < w["t"].size / 6
    np.testing.assert_array_equal(c["t"], w["t"][cut.index])
    whole = w["force"]
    for f in lines:
        b, a = iirnotch(f, NOTCH_Q, fs=1.0 / m.sampling_interval)
        whole = filtfilt(b, a, whole)
    inner = (cut.index > 8000) & (cut.index < whole.size - 8000)  # 20 decay times
    got = (c["force"] + cut.shift)[inner]
    # (rounding: two notches are a filter of order 4, run over ~10^6 samples)
    np.testing.assert_allclose(got, whole[cut.index][inner], rtol=0, atol=1e-8)
    if lines:  # the notches' ringing about the slips, which the cut trace would lose
        ring = np.abs(w["force"][cut.index] - whole[cut.index])[inner]
        assert np.percentile(ring, 99) > 0.1 * MEASUREMENT["noise_sd"]


def test_the_cut_trace_finds_the_whole_traces_cycles(pair, request):
    """The same detection decisions in all but <= 0.5 % of cycles (the cycles either finds
    that the other does not: at most the 99th percentile of a binomial count at 0.5 % of
    the cycles), and per cycle the same release, slip time and drop to well within the
    extraction's own error (its robust sd against the simulation's truth; the peak force's
    truth is x0): the 99th
    percentile of |cut - whole| below it, the 90th below half of it. Where a line is
    notched, the drops' and the peak forces' 99th percentile within 2.5 times it: the cut
    trace's noise is not notched (`_notched`), and the notch's share of the noise, though
    0.2 % of its variance, rings for 0.2 s: on the drops, whose own error is a fifth of a
    noise sd, up to 2 of those errors (measured: 1.8 at the 99th percentile, 900 cycles)."""
    line = "no line" not in request.node.callspec.id
    reference, (table, _), truth, _ = pair
    w = reference.table
    tol = MEASUREMENT["window"] * MEASUREMENT["sampling_interval"]
    i, j = _match(w["release_time"], table["release_time"], tol)
    n = max(w["release_time"].size, table["release_time"].size)
    missed = w["release_time"].size + table["release_time"].size - 2 * i.size
    assert missed <= stats.binom.ppf(0.99, 2 * n, 0.005), (missed, n)
    a, b = _match(w["release_time"], truth["release_time"], tol)
    own = {"release_time": truth["release_time"][b], "slip_time": truth["slip_time"][b],
           "slip_distance": truth["slip_distance"][b],
           "peak_force": np.full(b.size, SLIDER["x0"])}  # every slip starts at x0  # fmt: skip
    for k, values in own.items():
        e = w[k][a] - values
        error = 1.4826 * np.median(np.abs(e - np.median(e)))
        d = np.abs(table[k][j] - w[k][i])
        bound = 2.5 if line and k in ("slip_distance", "peak_force") else 1.0
        assert np.percentile(d, 99) < bound * error, (k, np.percentile(d, 99), error)
        assert np.percentile(d, 90) < 0.5 * error, (k, np.percentile(d, 90), error)


def test_the_kept_far_samples_stand_for_the_cut_ones(pair, request):
    """The trace-wide statistics of the cut trace are the whole trace's: the noise sd
    within 4 standard errors of a MAD estimate on the far samples kept, and so the force
    rate's scatter where no line is notched (where one is, the notch's ringing, stronger
    near the slips than over a whole stick, raises the cut trace's by some 6 %: docs/
    fit.md), and the loading slope within 1e-3; unweighted, the slips' share of the kept
    samples would inflate the scatter by several of those errors."""
    reference, (_, info), _, (_, c) = pair
    n_far = int(c["cut"].far.sum())
    se = math.sqrt(2.0 / (2.0 * 0.3675 * n_far))  # relative SE of a difference of MAD sds
    keys = ["noise_sd"] + (["rate_noise_sd"] if "no line" in request.node.callspec.id else [])
    for key in keys:
        ratio = info[key] / reference.info[key]
        assert abs(ratio - 1) < 4 * se, (key, ratio, se)
    assert abs(info["v_b_estimated"] / reference.info["v_b_estimated"] - 1) < 1e-3


def test_measured_cycles_cuts_by_default():
    """`measured_cycles` takes the cut path unless told `sticks="whole"`, and refuses an
    unknown choice in one line naming it."""
    model = ss.get_model("langevin")(**SLIDER)
    m = Measurement(**MEASUREMENT)
    default = measured_cycles(model, m, 200, 3)
    cut = measured_cycles(model, m, 200, 3, sticks="cut")
    for k in default:
        np.testing.assert_array_equal(default[k], cut[k])
    with pytest.raises(ss.ParameterError, match="sticks"):
        measured_cycles(model, m, 200, 3, sticks="half")


def test_keyed_noise_is_the_same_on_whichever_samples_are_drawn():
    """`keyed_samples` at a subset of the grid gives the whole grid's values there; the
    values are standard normal (KS at 0.01) and uncorrelated at lag 1 and across cycles
    (within 4 / sqrt(n)); the uniforms are uniform (KS at 0.01)."""
    rng = np.random.default_rng(2)
    n_cycles, h = 300, 0.1
    stick = rng.uniform(0.0, 20.0, n_cycles)
    slip = rng.uniform(1.0, 3.0, n_cycles)
    release = np.cumsum(np.r_[0.0, (slip + stick)[:-1]])
    n = int(release[-1] / h) + 50
    noise, uniforms = keyed_samples(release, slip, stick, n, h, 7, 0, True, True)
    at = np.sort(rng.choice(n, n // 5, replace=False))
    some, some_u = keyed_samples(release, slip, stick, n, h, 7, 0, True, True, at)
    np.testing.assert_array_equal(some, noise[at])
    np.testing.assert_array_equal(some_u, uniforms[at])
    assert stats.kstest(noise, "norm").pvalue > 0.01
    assert stats.kstest(uniforms, "uniform").pvalue > 0.01
    assert abs(np.corrcoef(noise[:-1], noise[1:])[0, 1]) < 4 / math.sqrt(n)
    other, _ = keyed_samples(release, slip, stick, n, h, 8, 0, True, False)
    assert abs(np.corrcoef(noise, other)[0, 1]) < 4 / math.sqrt(n)


@pytest.mark.parametrize("weight", [1.0, 3.0, 17.0])
def test_weighted_median_is_the_median_of_the_values_written_out(weight):
    """With integer weights, the median of the far values repeated `weight` times and the
    near ones once (np.median), to within one far value's rank."""
    rng = np.random.default_rng(int(weight))
    a = np.r_[rng.normal(0.0, 1.0, 3000), rng.normal(4.0, 2.0, 700)]
    far = np.r_[np.ones(3000, bool), np.zeros(700, bool)]
    rng.shuffle(perm := np.arange(a.size))
    a, far = a[perm], far[perm]
    expanded = np.r_[np.repeat(a[far], int(weight)), a[~far]]
    got = weighted_median(a, far, weight)
    values = np.sort(a[far])
    rank = np.searchsorted(values, np.median(expanded))
    assert values[max(rank - 1, 0)] <= got <= values[min(rank + 1, values.size - 1)]
    assert weighted_median(a, None) == np.median(a)


@pytest.mark.slow  # (10 s in a cold default tier, most of it compiling a user's model)
def test_a_model_with_memory_runs_in_short_paths_with_the_same_law(monkeypatch):
    """A random threshold whose stick, past its next threshold, releases from where it is
    (memory of one cycle, written as a user writes it) is measured in paths of 32 cycles
    (one round of `simulate_cycles` per cycle: one long path took 6x as long); its
    measured cycles have the law of one long path's (two-sample KS per column at 0.01/3,
    independent seeds)."""
    import jax.numpy as jnp

    from stickslip._inference import measurement as meas

    class Held(ss.get_model("random-threshold")):
        carries_state = True

        def release(self, key, y_stick):
            y_next = self.onset_state(key)
            y_next = y_next.at[0].set(jnp.maximum(y_next[0], y_stick[0]))
            return self.stick_duration(y_stick, y_next), y_next

    params = {k: v for k, v in SLIDER.items() if k != "x0"}
    model = Held(**params, threshold="normal", threshold_params={"mean": 1.0, "sd": 0.6})
    m = Measurement(**{**MEASUREMENT, "columns": ("slip_time", "stick_time", "slip_distance")})
    short = measured_cycles(model, m, 1200, 1)
    monkeypatch.setattr(meas, "_CYCLES_PER_PATH_MEMORY", 1200)
    long = measured_cycles(model, m, 1200, 2)
    assert short["slip_time"].size > 800 and long["slip_time"].size > 800
    for k in m.columns:
        assert stats.ks_2samp(short[k], long[k]).pvalue > 0.01 / 3, k


@pytest.mark.parametrize("weight", [1.0, 2.9, 17.02])
@pytest.mark.parametrize("n", [5000, 300_000])
def test_weighted_median_is_the_first_far_value_whose_count_reaches_half(weight, n):
    """Against its definition, evaluated by sorting: the smallest rank r of the far values
    whose count (near values up to it, plus weight (r + 1)) reaches half the total; on
    quantised values (ties, as an ADC's) and a trace's length, where guessing the next
    rank alone alternated between two."""
    rng = np.random.default_rng(n + int(10 * weight))
    a = np.round(np.r_[rng.normal(0.0, 1.0, n), rng.normal(0.8, 3.0, n // 2)], 2)
    far = rng.random(a.size) < 0.35
    outer, inner = np.sort(a[far]), np.sort(a[~far])
    half = 0.5 * (inner.size + weight * outer.size)
    count = np.searchsorted(inner, outer, side="right") + weight * np.arange(1, outer.size + 1)
    assert weighted_median(a, far, weight) == outer[np.argmax(count >= half)]


@pytest.mark.parametrize("size", [1, 3, 7, 31])
def test_running_median_is_scipys_median_filter(size):
    """The despiking median against SciPy's `median_filter(mode="nearest")` (an independent
    implementation: it sorts each window afresh), bit for bit: traces shorter than the
    window, ties (quantised values, runs of one value), spikes; a value that is not finite
    goes to SciPy's filter itself."""
    from scipy.ndimage import median_filter

    from stickslip._extract._median import running_median

    rng = np.random.default_rng(size)
    cases = [rng.normal(size=n) for n in (1, 2, size, size + 1, 1000)]
    cases += [np.round(rng.normal(size=5000), 1), np.repeat(rng.normal(size=400), 5)]
    spiky = rng.normal(size=3000)
    spiky[rng.integers(0, 3000, 60)] += 50.0
    cases.append(spiky)
    for y in cases:
        assert np.array_equal(running_median(y, size), median_filter(y, size, mode="nearest"))
    with pytest.raises(ValueError, match="odd"):
        running_median(cases[0], 4)
