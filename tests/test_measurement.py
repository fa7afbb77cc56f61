"""The measurement inside the forward model: `Measurement` read from a `Cycles`, and
`measured_cycles` (simulate a trace, sample it, add the noise, extract), checked against
the model's own per-cycle values (`simulate`, an independent run), its cycle table (the
truth behind the trace) and the noise put in."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

import stickslip as ss
from stickslip._extract import Cycles, read_cycles
from stickslip._inference.measurement import Measurement, measured_cycles, measured_trace

# Few zero-length sticks (0.07 % of 20 000 simulated cycles) and no slip beyond 50: the
# trace of a fine sampling sees every cycle, so its cycles are the per-cycle values.
CLEAN = dict(omega0=1.0, zeta=0.3, D=0.1, v_b=0.5, x0=1.0, tau=0.3)
# The public set: 37 % of its sticks last zero time, which a trace cannot see.
PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
DURATIONS = ("slip_time", "slip_distance", "stick_time", "period")


def langevin(params):
    return ss.get_model("langevin")(**params)


def test_fine_noise_free_sampling_gives_the_per_cycle_values():
    """(a) h = 0.05 (a slip lasts 3-50, a stick 1.4 or more) and no noise: each duration is
    timed to within 2h, and the cycles' law is the model's. A two-sample KS test against
    an independent `simulate` run of the same model, per column at 0.01 / 4."""
    model = langevin(CLEAN)
    meas = Measurement(sampling_interval=0.05, signal="x")
    got = measured_cycles(model, meas, 1500, seed=3)
    assert set(got) == set(DURATIONS)
    ens = ss.simulate(model, 4000, 0.05, 200.0, seed=11)
    keep = ens.stuck & ~ens.immediate
    assert keep.mean() > 0.999 and np.mean(ens.stick_time[keep] == 0) < 0.005
    assert got["period"].size > 1300  # cycles joined or lost to the paths' ends: few
    for k in DURATIONS:
        p = stats.ks_2samp(got[k], np.asarray(getattr(ens, k))[keep]).pvalue
        assert p > 0.01 / len(DURATIONS), (k, p)


def _mad_se(n: int) -> float:
    """Relative standard error of the 1.4826 MAD sd of n independent Gaussian values
    (asymptotic efficiency 0.3675 against the sample sd's 1/(2n) relative variance)."""
    return math.sqrt(1.0 / (2.0 * 0.3675 * n))


@pytest.mark.parametrize("signal", ["v", "x"])
def test_the_measurement_is_read_back_from_the_extracted_cycles(signal):
    """(b) A trace simulated with a known interval and noise sd, extracted as data would
    be: `Measurement.from_cycles` gives the interval and the noise sd back. The sd is a
    robust (MAD) estimate from the n stuck samples: tolerance 4 standard errors; for `x`
    the interval velocities' noise is a moving average of lag 1 (correlation -1/2), and
    the MAD's indicators of |values| correlate by at most 1/4 at lag 1 (even functions of
    a Gaussian pair: at most rho^2), so the variance is at most 1.5 times the independent
    one. Transition samples that fall in the stuck band (a fraction ~20 sd / (|dv/dt|
    T_st) ~ 0.3 % here) bias the sd up by about as much: below one standard error."""
    model = langevin(CLEAN)
    h, sd = 0.1, 1e-3 if signal == "v" else 1e-4
    truth = Measurement(sampling_interval=h, signal=signal, noise_sd=sd)
    trace = measured_trace(model, truth, 400, seed=5)
    (signals,) = trace.traces
    # every step h, but one in each long stick, where the grid is re-anchored at the next
    # release (its keyed phase): between h and 2h
    step = np.diff(signals["t"])
    assert np.all(step >= h * (1 - 1e-9)) and np.all(step < 2 * h)
    assert np.mean(np.isclose(step, h, rtol=1e-9, atol=0)) > 0.95
    cycles = ss.extract_cycles(**signals, v_b=CLEAN["v_b"])
    got = Measurement.from_cycles(cycles)
    assert got.signal == signal and got.tol is None
    assert got.sampling_interval == pytest.approx(h, rel=1e-9)
    n_stuck = float(np.sum(cycles["stick_time"])) / h
    assert n_stuck > 5000
    se = _mad_se(int(n_stuck)) * (1.0 if signal == "v" else math.sqrt(1.5))
    assert abs(got.noise_sd / sd - 1.0) < 4.0 * se, (got.noise_sd, sd, se)
    assert got.columns == DURATIONS


def test_coarse_sampling_joins_short_sticks():
    """(c) The public set sampled at h = 0.4 without noise, positions only: a stick is
    seen when two sampling intervals lie inside it (their mean velocities are exactly
    v_b), so every visible stick is a distinct model stick of at least 2h, and every model
    stick of at least 3h holds two whole intervals and is seen; the rest join the slips
    on either side (the zero-length sticks among them). Counted against the model's own
    cycles behind the trace."""
    model = langevin(PUBLIC)
    h = 0.4
    meas = Measurement(sampling_interval=h, signal="x", columns=("slip_time", "stick_time"))
    trace = measured_trace(model, meas, 2000, seed=7)
    got = measured_cycles(model, meas, 2000, seed=7)
    stick = trace.truth["stick_time"]
    n_paths = len(trace.traces)
    assert np.mean(stick == 0) > 0.3
    n = got["stick_time"].size
    # each path's trace loses the cycles cut at its two ends (and the last cycle's stick)
    assert np.sum(stick >= 3 * h) - 3 * n_paths <= n <= np.sum(stick >= 2 * h)
    assert n < 0.7 * stick.size  # fewer cycles than the model ran
    assert np.min(got["stick_time"]) > 0.0  # no zero-length stick is seen
    # the joined slips are longer than the model's
    assert np.mean(got["slip_time"]) > np.mean(trace.truth["slip_time"])
    # reproducible: the same seed gives the same cycles, another seed others
    again = measured_cycles(model, meas, 2000, seed=7)
    assert all(np.array_equal(got[k], again[k]) for k in got)
    other = measured_cycles(model, meas, 2000, seed=8)
    assert other["slip_time"].size != n or not np.array_equal(other["slip_time"], got["slip_time"])


def _velocity_info(**change):
    info = dict(
        input="x", velocity="x differences", v_b=1.0, v_b_sticks=1.0, tol=0.05,
        tol_rule="5 robust sd of |v - v_b| near v_b", noise_sd=0.01, noise_sd_smoothed=0.01,
        filter="none", smoothing_window=0, tol_raw=0.05, min_stick=2,
        sampling_interval=0.1, n_sticks=12, n_joined=0,
    )  # fmt: skip
    info.update(change)
    return info


def _table(n=12):
    rng = np.random.default_rng(0)
    slip, stick = rng.uniform(2, 4, n), rng.uniform(0.5, 2, n)
    return dict(
        release_time=np.cumsum(slip + stick), slip_time=slip,
        slip_distance=rng.uniform(1, 2, n), stick_time=stick, period=slip + stick,
    )  # fmt: skip


def test_from_cycles_reads_the_settings_and_survives_the_csv(tmp_path):
    cycles = Cycles(_table(), _velocity_info())
    m = Measurement.from_cycles(cycles)
    # the interval velocities' noise sd is sqrt(2) sigma_x / h
    assert m.noise_sd == pytest.approx(0.01 * 0.1 / math.sqrt(2.0))
    assert (m.signal, m.min_stick, m.tol) == ("x", 2, None)
    assert m.extract_settings(1.0) == dict(v_b=1.0, tol=None, min_stick=2)
    cycles.to_csv(tmp_path / "cycles.csv")
    assert Measurement.from_cycles(read_cycles(tmp_path / "cycles.csv")) == m
    given = Measurement.from_cycles(Cycles(_table(), _velocity_info(input="v", tol_rule="given")))
    assert (given.tol, given.noise_sd) == (0.05, 0.01)


def test_from_cycles_refuses_what_carries_no_measurement():
    with pytest.raises(ss.ParameterError, match="lacks input, sampling_interval, noise_sd"):
        Measurement.from_cycles(Cycles(_table(), {}))
    with pytest.raises(ss.ParameterError, match="per-cycle values carries no measurement"):
        Measurement.from_cycles(_table())
    info = _velocity_info()
    del info["min_stick"]
    with pytest.raises(ss.ParameterError, match="lacks min_stick") as err:
        Measurement.from_cycles(Cycles(_table(), info))
    assert "\n" not in str(err.value)
    with pytest.raises(ss.ParameterError, match=r"\['noise_sd'\]' must be a finite number"):
        Measurement.from_cycles(Cycles(_table(), _velocity_info(noise_sd="nan")))


def test_a_force_measurement_is_put_in_the_model_units():
    """A force trace's settings in s and N, through a slider's scales: times over
    1/omega0, forces over k x0, line frequencies times 1/omega0."""
    from stickslip.units import Slider

    slider = Slider(mass=0.0307, stiffness=168.0, v_b=42e-6, static_friction=0.0964,
                    kinetic_friction=0.0911, damping=1e-3)  # fmt: skip
    s = slider.scales
    info = dict(
        input="force", sampling_interval=5e-4, noise_sd=1.9e-4, window=29,
        thresholds=dict(spike=5.0, slip=5.0, extent=2.0, drop=5.0, split=25.0),
        n_spikes=8239, n_samples=751281, spike_threshold=1.3e-3, lines_removed=[50.01],
    )  # fmt: skip
    table = dict(_table(), peak_force=np.full(12, 0.1), force_drop=np.full(12, 0.01))
    with pytest.raises(ss.ParameterError, match="'scales' is required for a force trace"):
        Measurement.from_cycles(Cycles(table, info))
    m = Measurement.from_cycles(Cycles(table, info), scales=slider)
    assert m.sampling_interval == pytest.approx(5e-4 * math.sqrt(168.0 / 0.0307))
    assert m.noise_sd == pytest.approx(1.9e-4 / (168.0 * s.length))
    assert m.lines == pytest.approx((50.01 / s.omega0,))
    assert m.spike_fraction == pytest.approx(8239 / 751281)
    assert "force_drop" in m.columns and m.window == 29
    assert m.extract_settings(0.5)["stiffness"] == 1.0
    # a Slider.to_model table keeps the extraction's settings under info["si"]
    assert Measurement.from_cycles(slider.to_model(Cycles(table, info)), scales=s) == m


def test_bad_arguments_are_one_line():
    with pytest.raises(ss.ParameterError, match="'signal' must be one of"):
        Measurement(sampling_interval=0.1, signal="position")
    with pytest.raises(ss.ParameterError, match="'window' applies to force traces only"):
        Measurement(sampling_interval=0.1, signal="x", window=11)
    with pytest.raises(ss.ParameterError, match="'sampling_interval' must be"):
        Measurement(sampling_interval=-1.0, signal="v")
    meas = Measurement(sampling_interval=0.1, signal="x")
    with pytest.raises(ss.ParameterError, match="'n_cycles' must be >= 10"):
        measured_cycles(langevin(PUBLIC), meas, 5, seed=0)
    with pytest.raises(ss.ParameterError, match="'measurement' must be a Measurement"):
        measured_cycles(langevin(PUBLIC), {"sampling_interval": 0.1}, 100, seed=0)


def test_a_trace_past_the_memory_limit_is_refused(monkeypatch):
    """A 1e-7 interval over 10^4 cycles of mean period ~4.7: 4.7e11 samples, said once the
    cycles are simulated (their table, a few MB), before their slips are recorded."""
    monkeypatch.setenv("STICKSLIP_MEMORY_LIMIT", "1e9")
    meas = Measurement(sampling_interval=1e-7, signal="x")
    with pytest.raises(ss.ResourceError, match="measured_cycles: a trace of 4.*e\\+11 samples"):
        measured_cycles(langevin(PUBLIC), meas, 10_000, seed=0)


def test_slips_that_do_not_stick_within_the_horizon_are_a_data_error(monkeypatch):
    """Slips followed for 1e-3 of the slow time scale (the public set's last ~2.5): none
    sticks, and the trace is refused in one line that says so."""
    from stickslip._inference import measurement as meas

    monkeypatch.setattr(meas, "_PILOT_HORIZON", 1e-3)
    m = Measurement(sampling_interval=0.05, signal="x")
    with pytest.raises(ss.DataError, match="sticks again within 0.001 slow time scales in 0 "
                       "of 200 successive cycles"):  # fmt: skip
        measured_cycles(langevin(PUBLIC), m, 200, seed=0, dt=1e-5)


def test_a_measurement_too_coarse_for_the_model_is_a_data_error():
    """h = 2: the public set's median slip (about 2.5) is shorter than 3 intervals."""
    meas = Measurement(sampling_interval=2.0, signal="x")
    with pytest.raises(ss.DataError, match="shows no cycles through this measurement"):
        measured_cycles(langevin(PUBLIC), meas, 200, seed=0)


def test_each_cycle_keeps_its_sampling_phase_when_a_parameter_moves():
    """Common random numbers through the measurement: D 2 % apart moves every later release
    by the sum of earlier changes (many sampling intervals after a few hundred cycles), yet
    a cycle after a stick of 10 intervals or more is sampled at the same phase from its own
    release at both values (on one uniform grid the phase would be the accumulated time
    over h: unrelated). The phases are uniform on [0, h) (KS test at 0.01)."""
    h = 0.1
    meas = Measurement(sampling_interval=h, signal="x", noise_sd=1e-3)
    phases, releases = [], []
    for D in (0.4, 0.4 * math.exp(0.02)):
        trace = measured_trace(langevin({**PUBLIC, "D": D}), meas, 400, seed=5)
        (signals,) = trace.traces
        truth = trace.truth
        release, stick = truth["release_time"], truth["stick_time"]
        after_long = np.flatnonzero(np.r_[False, stick[:-1] >= 10 * h])
        after_long = after_long[release[after_long] < signals["t"][-1] - 1.0]
        first = np.searchsorted(signals["t"], release[after_long])
        phase = (signals["t"][first] - release[after_long]) / h
        phases.append(dict(zip(after_long.tolist(), phase, strict=True)))
        releases.append(release)
    both = sorted(set(phases[0]) & set(phases[1]))  # (a stick may cross 10 h)
    assert len(both) > 100
    np.testing.assert_allclose([phases[0][c] for c in both], [phases[1][c] for c in both],
                               rtol=0, atol=1e-9)  # fmt: skip
    assert stats.kstest(list(phases[0].values()), "uniform").pvalue > 0.01
    # the releases themselves moved by many sampling intervals by the end
    assert abs(releases[0][both[-1]] - releases[1][both[-1]]) > 5 * h


def test_a_force_traces_noise_and_spikes_are_keyed_by_cycle():
    """Common random numbers on a force trace's one uniform grid: D 2 % apart moves every
    later release by many sampling intervals, yet after a stick of 10 intervals or more a
    cycle meets the same noise values and spikes, counted in samples from its release, at
    both values (on one stream over the grid they would be fresh draws). The noise is
    recovered as the noisy trace less the noise-free one of the same seed; it is standard
    normal (KS at 0.01) and uncorrelated from sample to sample, and the spikes take their
    fraction of the samples."""
    h, sd, frac = 0.1, 1e-3, 0.02
    kw = dict(sampling_interval=h, signal="force", window=11)
    noisy = Measurement(noise_sd=sd, spike_fraction=frac, spike_height=1.0, **kw)
    clean = Measurement(**kw)
    seen = []
    for D in (0.4, 0.4 * math.exp(0.02)):
        model = langevin({**PUBLIC, "D": D})
        a = measured_trace(model, noisy, 400, seed=5)
        b = measured_trace(model, clean, 400, seed=5)
        (sa,), (sb,) = a.traces, b.traces
        np.testing.assert_array_equal(sa["t"], sb["t"])
        e = (sa["force"] - sb["force"]) / sd
        spike = np.abs(e) > 100  # spikes are 1.0 = 1000 sd; the noise never reaches 100 sd
        release, stick = a.truth["release_time"], a.truth["stick_time"]
        after_long = np.flatnonzero(np.r_[False, stick[:-1] >= 10 * h])
        after_long = after_long[release[after_long] < sa["t"][-1] - 3.0]
        first = np.searchsorted(sa["t"], release[after_long] - 1e-12)
        window = first[:, None] + np.arange(-5, 20)[None, :]  # samples about each release
        seen.append({c: (e[w], spike[w]) for c, w in zip(after_long.tolist(), window, strict=True)})
        noise = e[~spike]
        assert stats.kstest(noise, "norm").pvalue > 0.01
        assert abs(np.corrcoef(noise[:-1], noise[1:])[0, 1]) < 4 / math.sqrt(noise.size)
        assert abs(spike.mean() - frac) < 4 * math.sqrt(frac * (1 - frac) / spike.size)
        assert abs(np.mean(e[spike] > 0) - 0.5) < 4 * math.sqrt(0.25 / spike.sum())
    both = sorted(set(seen[0]) & set(seen[1]))
    assert len(both) > 100
    # the same draws, sample for sample from the first at or after each release
    for c in both:
        np.testing.assert_allclose(seen[0][c][0], seen[1][c][0], rtol=0, atol=1e-6)
        np.testing.assert_array_equal(seen[0][c][1], seen[1][c][1])
    # ... which a stream over the grid would not give (the releases moved)
    release = [measured_trace(langevin({**PUBLIC, "D": D}), clean, 400, seed=5).truth[
        "release_time"] for D in (0.4, 0.4 * math.exp(0.02))]  # fmt: skip
    assert abs(release[0][both[-1]] - release[1][both[-1]]) > 5 * h


def test_paths_shared_between_threads_keep_their_order_and_errors():
    """`_cpu.on_two_threads`: each path's result in its place, whichever thread ran it, and a
    path's error raised in the caller's thread (the first path's, as a loop raises it)."""
    import threading

    from stickslip._cpu import on_two_threads

    ran = {}

    def work(p):
        ran[p] = threading.current_thread().name
        return p * p

    assert on_two_threads(work, 7) == [p * p for p in range(7)]
    assert sorted(ran) == list(range(7))

    def failing(p):
        if p in (2, 5):
            raise ss.DataError(f"path {p}")
        return p

    with pytest.raises(ss.DataError, match="path 2"):
        on_two_threads(failing, 7)
