"""The ensemble stick/slip simulator."""

import math

import numpy as np
import pytest
from conftest import chi2_homogeneity
from scipy.optimize import brentq
from scipy.stats import norm

import stickslip as ss
from stickslip._jax import jnp

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)


def closed_form_slip(omega0, zeta, v_b, x0):
    """First t > 0 with v(t) = v_b for x'' + zeta x' + omega0^2 x = 0 from (x0, v_b), and x
    there: the closed-form underdamped trajectory and a bracketed root (to 1e-15)."""
    wd = math.sqrt(omega0**2 - zeta**2 / 4)
    s = -zeta / 2
    a, b = x0, (v_b - s * x0) / wd
    x = lambda t: math.exp(s * t) * (a * math.cos(wd * t) + b * math.sin(wd * t))
    v = lambda t: (
        math.exp(s * t)
        * ((s * a + wd * b) * math.cos(wd * t) + (s * b - wd * a) * math.sin(wd * t))
    )
    grid = np.linspace(1e-9, 4 * math.pi / wd, 100_001)
    f = np.array([v(t) for t in grid]) - v_b
    i = np.nonzero((f[:-1] < 0) & (f[1:] >= 0))[0][0]
    T = brentq(lambda t: v(t) - v_b, grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15)
    return T, x(T)


@pytest.mark.parametrize("tau", [None, 0.1])
@pytest.mark.parametrize("dt", [0.05, 0.01])
def test_noise_free_slip_is_exact(Langevin, tau, dt):
    """D = 0: slip time and stick position equal the closed form to 1e-8 with the exact
    solver, whatever the step: localisation on the solver's flow, not the step, sets it."""
    m = Langevin(omega0=1.0, zeta=0.1, D=0.0, v_b=1.0, x0=1.0, tau=tau)
    T, x_sl = closed_form_slip(1.0, 0.1, 1.0, 1.0)
    ens = ss.simulate(m, 8, dt, 30.0, solver="exact")
    assert np.all(ens.stuck)
    assert np.max(np.abs(ens.slip_time - T)) < 1e-8
    assert np.max(np.abs(ens.stick_position - x_sl)) < 1e-8
    np.testing.assert_allclose(ens.slip_distance, 1.0 - x_sl, atol=1e-8)
    np.testing.assert_allclose(ens.stick_time, (1.0 - x_sl) / 1.0, atol=1e-8)
    np.testing.assert_allclose(ens.period, T + (1.0 - x_sl), atol=1e-8)


def test_noise_free_euler_converges_at_first_order(Langevin):
    m = Langevin(omega0=1.0, zeta=0.1, D=0.0, v_b=1.0, x0=1.0)
    T, _ = closed_form_slip(1.0, 0.1, 1.0, 1.0)
    errors = [
        abs(ss.simulate(m, 4, dt, 30.0, solver="euler").slip_time[0] - T)
        for dt in (0.02, 0.01, 0.005)
    ]
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(rates - 1.0) < 0.15)


@pytest.mark.parametrize(
    "params, solver, monitor",
    [
        (PUBLIC, "exact", "continuous"),
        # (two in the default tier; the others compile their own programs: slow)
        pytest.param(PUBLIC, "euler", "grid", marks=pytest.mark.slow),
        (PUBLIC | {"tau": None}, "euler", "continuous"),  # bridge test draws uniforms too
        pytest.param(
            PUBLIC | {"eta0": "stationary"}, "exact", "continuous", marks=pytest.mark.slow
        ),
    ],
)
def test_results_do_not_depend_on_chunk_size(Langevin, params, solver, monitor):
    m = Langevin(**params)
    runs = [
        ss.simulate(m, 1500, 0.01, 20.0, seed=11, solver=solver, monitor=monitor, chunk_size=c)
        for c in (1500, 700, 128)
    ]
    for other in runs[1:]:
        for name in ("slip_time", "stick_position", "stick_time", "period"):
            np.testing.assert_array_equal(getattr(runs[0], name), getattr(other, name))
        np.testing.assert_array_equal(runs[0].stick_state, other.stick_state)


def test_same_seed_same_results_different_seed_different(Langevin):
    m = Langevin(**PUBLIC)
    a = ss.simulate(m, 300, 0.01, 20.0, seed=3)
    b = ss.simulate(m, 300, 0.01, 20.0, seed=3)
    c = ss.simulate(m, 300, 0.01, 20.0, seed=4)
    np.testing.assert_array_equal(a.slip_time, b.slip_time)
    assert not np.any(a.slip_time == c.slip_time)
    # A path's result does not depend on how many paths run beside it.
    d = ss.simulate(m, 1000, 0.01, 20.0, seed=3)
    np.testing.assert_array_equal(a.slip_time, d.slip_time[:300])


@pytest.mark.parametrize(
    "n",
    [30_000, pytest.param(100_000, marks=pytest.mark.slow)],  # (100 000: 13 s)
)
def test_public_reference_set(Langevin, reference, n):
    """Monte Carlo on the public reference set, with the reference's own stick convention
    (grid monitoring, linear interpolation), against its independent histograms: chi-square
    homogeneity tests (fixed seed) and the mean slip time within 4 standard errors."""
    meta = reference["meta"]
    m = Langevin(**PUBLIC)
    ens = ss.simulate(m, n, meta["mc"]["dt"], meta["mc"]["t_max"], seed=0, monitor="grid")
    assert ens.fraction_stuck == pytest.approx(1.0, abs=1e-4)
    counts_T, _ = np.histogram(ens.slip_time[ens.stuck], bins=reference["T_edges"])
    stat, dof, p = chi2_homogeneity(counts_T, reference["T_counts"])
    assert p > 1e-3, (stat, dof, p)
    counts_d, _ = np.histogram(ens.slip_distance[ens.stuck], bins=reference["d_edges"])
    stat, dof, p = chi2_homogeneity(counts_d, reference["d_counts"])
    assert p > 1e-3, (stat, dof, p)
    mean, se = ens.mean("slip_time")
    se_ref = meta["std_T"] / math.sqrt(meta["mc"]["n_paths"])
    assert abs(mean - meta["mean_T"]) < 4 * math.hypot(se, se_ref)
    mean_d, se_d = ens.mean("slip_distance")
    assert abs(mean_d - meta["mean_d"]) < 4 * math.hypot(se_d, meta["std_d"] / math.sqrt(2e5))
    frac = np.mean(ens.slip_time < 0.1)
    f_ref = meta["frac_T_below_0p1"]
    assert abs(frac - f_ref) < 4 * math.sqrt(f_ref * (1 - f_ref) * (1 / n + 1 / 2e5))


def test_slow_paths_get_nan_and_do_not_change_others(Langevin):
    m = Langevin(**PUBLIC)
    short = ss.simulate(m, 2000, 0.01, 2.0, seed=5)
    full = ss.simulate(m, 2000, 0.01, 30.0, seed=5)
    assert 0.1 < short.fraction_stuck < 0.9
    assert np.all(np.isnan(short.slip_time[~short.stuck]))
    assert np.all(np.isnan(short.period[~short.stuck]))
    assert np.all(short.slip_time[short.stuck] <= 2.0)
    np.testing.assert_array_equal(short.slip_time[short.stuck], full.slip_time[short.stuck])


def test_ensemble_bookkeeping(Langevin):
    m = Langevin(**PUBLIC)
    e = ss.simulate(m, 3000, 0.005, 30.0, seed=2)
    s = e.stuck
    np.testing.assert_allclose(e.period[s], e.slip_time[s] + e.stick_time[s])
    np.testing.assert_allclose(e.slip_distance[s], 1.0 - e.stick_position[s])
    np.testing.assert_allclose(e.stick_time[s], np.maximum(1.0 - e.stick_position[s], 0.0))
    assert np.all(e.stick_time[s] >= 0)
    # At the stick the crossing variable is at the level (to the cubic localisation error).
    assert np.max(np.abs(e.stick_state[s, 1] - 1.0)) < 1e-6
    np.testing.assert_array_equal(e.immediate, e.stuck & (e.slip_time == 0))
    assert e.onset_state.shape == e.stick_state.shape == (3000, 3)
    assert e.state_names == ("x", "v", "eta")
    assert e.info["solver"] == "exact" and e.info["monitor"] == "continuous"
    assert e.stats["path_steps"] > 0 and e.stats["compile_seconds"] >= 0
    values, errors, edges = e.histogram("slip_time", np.linspace(0, 30, 301))
    assert np.isclose(np.sum(values * np.diff(edges)), e.fraction_stuck)
    assert np.all(errors >= 0)
    assert "Ensemble(n_paths=3000" in repr(e)


def test_stationary_noise_onset_gives_immediate_resticks(Langevin):
    """eta0 = 'stationary': the slip ends at once when a(0) >= 0, with probability
    p0 = P(eta0 >= w^2 x0 + zeta v_b)."""
    m = Langevin(**PUBLIC, eta0="stationary")
    # (decided at the onset, whatever the step: dt 0.1, not 0.005, 10 s cold -> 2 s)
    e = ss.simulate(m, 20_000, 0.1, 30.0, seed=9)
    p0 = norm.sf((1.0 + 0.1) / math.sqrt(0.4 / 0.1))
    assert abs(e.fraction_immediate - p0) < 4 * math.sqrt(p0 * (1 - p0) / 20_000)
    imm = e.immediate
    assert np.all(e.slip_time[imm] == 0) and np.all(e.slip_distance[imm] == 0)
    assert np.all(e.slip_time[~imm & e.stuck] > 0)


def test_euler_and_exact_agree(Langevin):
    """Euler-Maruyama at a small step against exact stepping: mean slip times within 4
    standard errors (EM's O(dt) bias, about 0.015 here, is well below that: 0.25 with
    4000 paths a side)."""
    m = Langevin(**PUBLIC)
    ex = ss.simulate(m, 4000, 0.01, 30.0, seed=1, solver="exact")
    em = ss.simulate(m, 4000, 0.002, 30.0, seed=1, solver="euler")
    m_ex, se_ex = ex.mean("slip_time")
    m_em, se_em = em.mean("slip_time")
    assert abs(m_em - m_ex) < 4 * math.hypot(se_ex, se_em)


class _CubicDamping(ss.FrictionModel):
    """A nonlinear slip phase (no linear-Gaussian description): Euler-Maruyama only."""

    c: float = 0.02

    @property
    def state_names(self):
        return ("x", "v")

    @property
    def noise_dim(self):
        return 1

    def drift(self, y):
        return jnp.stack([y[1], -y[0] - self.c * y[1] ** 3])

    def diffusion(self, y):
        return jnp.array([[0.0], [0.0]])

    @property
    def stick_level(self):
        return 1.0

    def onset_state(self, key):
        return jnp.array([1.0, 1.0])


def test_nonlinear_model_runs_with_euler_only():
    m = _CubicDamping()
    e = ss.simulate(m, 16, 0.001, 30.0)
    assert e.info["solver"] == "euler" and np.all(e.stuck)
    with pytest.raises(ss.ParameterError, match="'solver' 'exact' needs a linear-Gaussian model"):
        ss.simulate(m, 16, 0.01, 30.0, solver="exact")


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"n_paths": 0}, r"'n_paths' must be >= 1"),
        ({"n_paths": 2.5}, r"'n_paths' must be an integer"),
        ({"dt": -0.1}, r"'dt' must be > 0"),
        ({"dt": float("nan")}, r"'dt' must be finite"),
        ({"t_max": 0.001}, r"'t_max' must be >= dt"),
        ({"seed": -3}, r"'seed' must be >= 0"),
        ({"solver": "rk4"}, r"'solver' must be one of"),
        ({"monitor": "sometimes"}, r"'monitor' must be one of"),
        ({"chunk_size": 0}, r"'chunk_size' must be >= 1"),
    ],
)
def test_bad_arguments_name_the_argument(Langevin, kwargs, match):
    args = dict(n_paths=10, dt=0.01, t_max=1.0) | kwargs
    with pytest.raises(ss.ParameterError, match=match):
        ss.simulate(Langevin(**PUBLIC), **args)


def test_model_must_be_an_instance(Langevin):
    with pytest.raises(TypeError, match="FrictionModel instance"):
        ss.simulate(Langevin, 10, 0.01, 1.0)


def test_progress_bar(Langevin, capsys):
    ss.simulate(Langevin(**PUBLIC), 300, 0.01, 20.0, progress=True)
    assert "simulate" in capsys.readouterr().err
