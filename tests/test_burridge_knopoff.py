"""The `burridge-knopoff` chain: reduction to `langevin`, events, crossing statistics,
errors."""

import importlib.util
import json
import pathlib

import numpy as np
import pytest
from conftest import chi2_homogeneity, new_process

import stickslip as ss
from stickslip.friction import LinearViscous


@pytest.fixture(scope="module")
def BK():
    return ss.get_model("burridge-knopoff")


def _gaps(run):
    """Stuck time before each event (the first: from t = 0)."""
    return np.concatenate(
        [
            np.concatenate([s[:1], s[1:] - (s[:-1] + d[:-1])])
            for s, d in zip(run.start, run.duration, strict=True)
        ]
    )


@pytest.mark.slow
def test_one_block_with_linear_friction_is_langevin(BK):
    """N = 1, F(V) = F_k + mu V: the Langevin model with omega0^2 = k_p, zeta = mu,
    x0 = (F_s - F_k - mu v_b) / k_p. A block that sticks beyond its static limit releases
    at once from where it stuck (Langevin restarts from x0), so the slips compared are those
    that follow a stick of positive length: they start from the threshold, as every
    Langevin slip does. Chi-square on the slip-time histograms (fixed seeds)."""
    kp, mu, Fs, Fk, vb, D, tau = 1.0, 0.1, 2.2, 1.0, 1.0, 0.4, 0.1
    chain = BK(1, 0.0, kp, vb, LinearViscous(static=Fs, viscosity=mu, kinetic=Fk), D=D, tau=tau)
    run = ss.simulate_chain(chain, 50, 0.002, 800.0, seed=1)
    dur = run.events("duration")[_gaps(run) > 0.004]
    assert dur.size > 4000 and set(run.events("size")) == {1}
    x0 = (Fs - Fk - mu * vb) / kp
    lv = ss.get_model("langevin")(omega0=kp**0.5, zeta=mu, D=D, v_b=vb, x0=x0, tau=tau)
    st = ss.simulate(lv, 40_000, 0.002, 60.0, seed=2).slip_time
    edges = np.append(np.arange(0, 12.01, 0.25), 100)
    _, _, p = chi2_homogeneity(np.histogram(dur, edges)[0], np.histogram(st, edges)[0])
    assert p > 0.01


def test_noise_free_single_block_is_exact_to_second_order(BK):
    """D = 0, N = 1, linear friction: the slip is the noise-free Langevin slip, whose stick
    time the exact solver gives to rounding (an independent solution of the same ODE).
    Heun's method makes the chain's slip duration second order in dt, and the release,
    where the stuck block's force (linear in time) reaches the limit, exact at any dt."""
    kp, mu, Fs, Fk, vb = 1.0, 0.1, 2.2, 1.0, 1.0
    x0 = (Fs - Fk - mu * vb) / kp
    lv = ss.get_model("langevin")(omega0=kp**0.5, zeta=mu, D=0.0, v_b=vb, x0=x0)
    exact = ss.simulate(lv, 1, 0.05, 60.0).slip_time[0]
    errors = []
    for dt in (0.04, 0.02, 0.01):  # none divides the release times
        chain = BK(1, 0.0, kp, vb, LinearViscous(static=Fs, viscosity=mu, kinetic=Fk))
        run = ss.simulate_chain(chain, 1, dt, 60.0)
        errors.append(abs(run.duration[0][0] - exact))
        # every release where the force k_p (v_b t - u) reaches F_s, u the slip so far
        slips = np.concatenate([[0.0], np.cumsum(run.slip[0])[:-1]])
        np.testing.assert_allclose(run.start[0], (Fs / kp + slips) / vb, atol=1e-9)
    assert errors[1] < errors[0] / 3 and errors[2] < errors[1] / 3, errors
    assert errors[2] < 1e-4


def test_released_blocks_move_and_thresholds_follow_their_law(BK):
    """The configuration that recorded 84 % of events with zero duration or slip when a
    released block whose drawn limit lay below F(0+) re-stuck at once: now none, and the
    limits the releases overcame follow the threshold law (KS test)."""
    from scipy import stats

    m = BK(4, k_c=5.0, k_p=1.0, v_b=0.05, friction="velocity-weakening",
           friction_params={"F0": 1.0, "alpha": 2.0}, D=1e-3, tau=0.1, threshold="uniform",
           threshold_params={"low": 0.6, "high": 1.0})  # fmt: skip
    run = ss.simulate_chain(m, 2, 0.01, 400.0, seed=0, record_releases=True)
    duration, slip = run.events("duration"), run.events("slip")
    assert duration.size > 100
    assert np.mean((duration <= 0) | (slip <= 0)) <= 0.01
    limits = np.concatenate([r[:, 2] for r in run.releases])
    assert limits.size > 400 and run.info["releases_dropped"] == 0
    assert stats.kstest(limits, stats.uniform(0.6, 0.4).cdf).pvalue > 1e-3


@pytest.mark.slow
def test_event_statistics_converge_in_dt(BK):
    """OU noise, dt = 0.01 against 0.0025: event sizes and durations are one distribution
    (chi-square, p > 1e-3) and the event rate agrees within 4 standard errors. The drop at
    onset is sigma = 0.2 here; with sigma = 0.01 against this noise, convergence is slower
    (docs/models.md)."""
    m = BK(4, k_c=5.0, k_p=1.0, v_b=0.05, friction="velocity-weakening",
           friction_params={"F0": 1.0, "alpha": 2.0, "sigma": 0.2}, D=1e-3, tau=0.1,
           threshold="uniform", threshold_params={"low": 0.6, "high": 1.0})  # fmt: skip
    a = ss.simulate_chain(m, 16, 0.01, 1000.0, seed=1)
    b = ss.simulate_chain(m, 16, 0.0025, 1000.0, seed=2)
    sizes = [np.bincount(r.events("size"), minlength=5)[1:] for r in (a, b)]
    assert chi2_homogeneity(*sizes)[2] > 1e-3
    edges = np.append(np.arange(0.0, 12.0, 0.5), np.inf)
    durations = [np.histogram(r.events("duration"), edges)[0] for r in (a, b)]
    assert chi2_homogeneity(*durations)[2] > 1e-3
    na, nb = a.n_events.sum(), b.n_events.sum()  # Poisson counts over the same time
    assert na > 1000 and abs(na - nb) < 4 * np.sqrt(na + nb)


@pytest.mark.slow  # a second chain run at other segment lengths (~7 s CPU)
def test_segments_do_not_change_the_events(BK, monkeypatch):
    """Events are streamed out segment by segment; the segment length changes nothing."""
    from stickslip._simulate import chain

    m = BK(8, 2.0, 1.0, 0.1, "velocity-weakening", {"F0": 1.0, "alpha": 2.0, "sigma": 0.1},
           D=1e-3, tau=0.1)  # fmt: skip
    a = ss.simulate_chain(m, 2, 0.01, 300.0, seed=3, record_dt=0.5)
    monkeypatch.setattr(chain, "SEGMENT", 256)
    b = ss.simulate_chain(m, 2, 0.01, 300.0, seed=3, record_dt=0.5)
    assert a.info["segments"] == 8 and b.info["segments"] == 118
    for q in ("start", "duration", "size", "slip"):
        for x, y in zip(getattr(a, q), getattr(b, q), strict=True):
            np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a.mean_force, b.mean_force)
    assert a.t.size == a.mean_force.shape[1] == 601


def test_white_noise_is_refused(BK):
    m = BK(4, 1.0, 1.0, 0.1, "velocity-weakening", {"F0": 1.0, "alpha": 1.0}, D=1e-3)
    with pytest.raises(ss.ParameterError, match="'tau'") as info:
        ss.simulate_chain(m, 1, 0.01, 10.0)
    assert "\n" not in str(info.value)


def test_a_coarse_step_warns(BK):
    m = BK(4, 100.0, 1.0, 0.1, "velocity-weakening", {"F0": 1.0, "alpha": 1.0, "sigma": 0.1})
    with pytest.warns(UserWarning, match="fastest time scale"):
        ss.simulate_chain(m, 1, 0.05, 1.0)


def test_noise_free_single_block_is_periodic(BK):
    """D = 0: every slip after the first stick is the same deterministic cycle."""
    chain = BK(1, 0.0, 1.0, 0.5, LinearViscous(static=2.0, viscosity=0.2, kinetic=1.0))
    run = ss.simulate_chain(chain, 1, 0.001, 200.0, seed=0)
    d, s = run.duration[0][1:], run.slip[0][1:]
    assert d.size > 5 and np.ptp(d) < 2e-3 and np.ptp(s) < 2e-3


def test_a_longer_run_compiles_nothing_and_begins_as_the_shorter(BK):
    """Twice the `t_max` doubles the default spacing of the time series (t_max / 1000: every
    100, then every 200 steps), which once changed the segment's compiled shape: now the
    same program runs (no trace, compilation or load), and the longer run's first half is
    the shorter run (the noise-free chain is deterministic; the samples fall on the same
    steps)."""
    chain = BK(1, 0.0, 1.0, 0.5, LinearViscous(static=2.0, viscosity=0.2, kinetic=1.0))
    short = ss.simulate_chain(chain, 1, 0.002, 200.0, seed=0)
    counts = {k: ss.cache_info()[k] for k in ("traces", "compiles", "executables_loaded")}
    long = ss.simulate_chain(chain, 1, 0.002, 400.0, seed=0)
    assert {k: ss.cache_info()[k] for k in counts} == counts
    assert long.t.size == short.t.size == 1001
    np.testing.assert_array_equal(long.t[:501], short.t[::2])
    np.testing.assert_array_equal(long.mean_force[:, :501], short.mean_force[:, ::2])
    n = short.start[0].size - 1  # the shorter run's events but the one its end may cut
    assert long.start[0].size > 2 * n
    for q in ("start", "duration", "slip"):
        np.testing.assert_array_equal(getattr(long, q)[0][:n], getattr(short, q)[0][:n])


@pytest.mark.slow
def test_hundred_blocks_broad_event_sizes(BK):
    """N = 100 with noise over 1e4 time units: sizes span 1 to N, and P(s) falls over two
    decades as a power law for small events (slope of log P against log s between -3 and -1)."""
    path = pathlib.Path(__file__).parents[1] / "examples" / "burridge_knopoff.py"
    spec = importlib.util.spec_from_file_location("bk_example", path)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    size_distribution = example.size_distribution

    run = ss.simulate_chain(BK.example(), 1, 0.02, 1e4, seed=1)
    sizes = run.events("size")
    assert sizes.size > 1000 and sizes.min() == 1 and sizes.max() == 100
    s, p, counts = size_distribution(sizes, 100)
    fit = (s <= 30) & (counts > 0)
    slope = np.polyfit(np.log(s[fit]), np.log(p[fit]), 1)[0]
    assert -3.0 < slope < -1.0
    assert p[0] / p[fit][-1] > 100
    # events are disjoint in time and the slip is positive
    for start, dur in zip(run.start, run.duration, strict=True):
        assert np.all(start[1:] >= start[:-1] + dur[:-1] - 1e-9)
    assert np.all(run.events("slip") > 0)
    assert run.mean_velocity.shape == (1, run.t.size) and np.all(run.slipping <= 1)


def test_chunking_free_periodic_and_random_thresholds(BK):
    """Periodic ends and random per-block thresholds run; paths are independent of how many
    run together (counter-based noise)."""
    law = {"low": 0.9, "high": 1.1}
    m = BK(16, 5.0, 1.0, 0.05, "velocity-weakening", {"F0": 1.0, "alpha": 2.0}, D=1e-3,
           tau=0.1, boundary="periodic", threshold="uniform", threshold_params=law)  # fmt: skip
    a = ss.simulate_chain(m, 3, 0.01, 300.0, seed=4)
    b = ss.simulate_chain(m, 1, 0.01, 300.0, seed=4)
    np.testing.assert_array_equal(a.size[0], b.size[0])
    assert a.n_events.min() > 5


def test_simulate_chain_takes_simulates_order_and_still_reads_the_old_one(BK):
    """`simulate_chain(model, n_paths, dt, t_max)` as `simulate`; the order before (t_max
    first, or t_max alone with n_paths by name) gives the same run with a DeprecationWarning
    that says how it was read; the new order warns nothing."""
    m = BK(4, 5.0, 1.0, 0.05, "velocity-weakening", {"F0": 1.0, "alpha": 2.0}, D=1e-3,
           tau=0.1)  # fmt: skip
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        new = ss.simulate_chain(m, 2, 0.01, 40.0, seed=4)
        named = ss.simulate_chain(m, t_max=40.0, dt=0.01, n_paths=2, seed=4)
    assert new.t_max == pytest.approx(40.0)
    assert new.n_events.shape == (2,)
    old_calls = (
        lambda: ss.simulate_chain(m, 40.0, 0.01, 2, 4),
        lambda: ss.simulate_chain(m, 40.0, dt=0.01, n_paths=2, seed=4),
        lambda: ss.simulate_chain(m, 40, 0.01, n_paths=2, seed=4),
    )
    for call in old_calls:
        with pytest.warns(DeprecationWarning, match=r"read as n_paths=2, dt=0.01, t_max=40"):
            old = call()
        for run in (old, named):
            np.testing.assert_array_equal(run.n_events, new.n_events)
            np.testing.assert_array_equal(run.events("size"), new.events("size"))
    with pytest.warns(DeprecationWarning, match="n_paths=1"):
        one = ss.simulate_chain(m, 40.0, dt=0.01, seed=4)
    assert one.n_events.shape == (1,)
    with pytest.raises(TypeError, match="multiple values for 'dt'"):
        ss.simulate_chain(m, 40.0, 0.01, dt=0.02)


def test_empirical_estimator_on_the_chain(BK):
    """The crossing variable is the mean sliding velocity (quiet at the event level); the
    empirical estimator takes the chain's crossings, and F_g1 carries at most the mass of
    the first quiet time."""
    chain = BK(8, 2.0, 1.0, 0.1, "viscous", {"static": 1.0, "viscosity": 0.5, "kinetic": 0.6},
               D=0.05, tau=0.2)  # fmt: skip
    run = ss.simulate_chain(chain, 2, 0.01, 2000.0, seed=3)
    up = run.upcrossings(window=20.0)
    est = ss.CrossingEstimator(chain, ensemble=up, dt=0.1)
    t = np.arange(0, 20.0, 0.1)
    F = est.first_passage(t)
    mass = np.trapezoid(F, t)
    first = up.times[:, 0]  # nan: never quiet in the window
    assert 0.5 < mass <= 1.0 + 1e-9
    assert mass == pytest.approx(np.mean(first <= 20.0), abs=0.15)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(k_c=-1.0), "k_c"),
        (dict(k_p=0.0), "k_p"),
        (dict(v_b=-0.1), "v_b"),
        (dict(D=-1.0), "D"),
        (dict(tau=0.0), "tau"),
        (dict(n_blocks=0), "n_blocks"),
        (dict(boundary="closed"), "boundary"),
        (dict(friction="rubber"), "friction"),
        (dict(friction_params={"F0": -1.0, "alpha": 1.0}), "friction_params.F0"),
        (dict(friction_params={"F0": 1.0, "alpha": 1.0, "sigma": 1.5}), "friction_params.sigma"),
        (dict(threshold="gamma"), "threshold"),
        (
            dict(threshold="uniform", threshold_params={"low": -0.1, "high": 1}),
            "threshold_params.low",
        ),
    ],
)
def test_bad_parameters(BK, kwargs, field):
    base = dict(n_blocks=4, k_c=1.0, k_p=1.0, v_b=0.1, friction="velocity-weakening",
                friction_params={"F0": 1.0, "alpha": 1.0}, D=0.0)  # fmt: skip
    with pytest.raises(ss.ParameterError) as info:
        BK(**(base | kwargs))
    assert f"'{field}'" in str(info.value) and "\n" not in str(info.value)


def test_simulate_points_to_simulate_chain(BK):
    with pytest.raises(ss.ParameterError, match="simulate_chain"):
        ss.simulate(BK.example(), 10, 0.01, 1.0)


CHAIN = """
import json
import numpy as np
import stickslip as ss
m = ss.get_model("burridge-knopoff")(2, 5.0, 1.0, 0.05, "velocity-weakening",
                                     {"F0": 1.0, "alpha": 2.0}, D=1e-3, tau=0.1)
run = ss.simulate_chain(m, 1, 0.01, 5.0, seed=1)
print(json.dumps([np.asarray(run.mean_velocity).sum().hex(), ss.cache_info()]))
"""


@pytest.mark.slow  # two new processes (~8 s)
def test_a_new_process_loads_the_chain_from_the_cache(tmp_path):
    """The chain's solve is traced and compiled once and kept on disk (it once had a host
    callback, diffrax's check of runtime end points, and every process compiled it again;
    then every process traced it again): the second process neither traces nor compiles
    it, loads both, and gets the same run."""
    first, info = json.loads(new_process(CHAIN, tmp_path, timeout=300))
    assert info["traces"] >= 1 and info["compiles"] >= 1, info
    second, again = json.loads(new_process(CHAIN, tmp_path, timeout=300))
    assert again["traces"] == 0 and again["compiles"] == 0, again
    assert again["exported_loaded"] >= 1 and again["executables_loaded"] >= 1, again
    assert second == first
