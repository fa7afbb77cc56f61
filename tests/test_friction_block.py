"""The `friction-block` plugin: discovery, the deterministic slip against an ODE solver, a
noisy ensemble, the identity with `langevin` for a linear viscous law, the empirical
crossing estimator, and its one-line parameter errors."""

import math
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from stickslip_friction_block import FrictionBlock

import stickslip as ss
from stickslip.friction import FrictionLaw, LinearViscous, VelocityWeakening

VW = {"F0": 1.0, "alpha": 1.0, "sigma": 0.2}
N_PATHS = 2000


def test_discovered_through_its_entry_point():
    assert "friction-block" in ss.list_models()
    assert ss.get_model("friction-block") is FrictionBlock
    names = ("k", "v_b", "D", "tau", "friction", "friction_params")
    assert tuple(FrictionBlock.parameters()) == names
    m = FrictionBlock.example()
    assert m.params()["friction"] == "velocity-weakening"
    assert FrictionBlock(**m.params()) == m
    law = VelocityWeakening(**VW)
    own = FrictionBlock(1.0, 0.5, 0.0, 0.1, law)
    assert own == FrictionBlock(1.0, 0.5, 0.0, 0.1, "velocity-weakening", VW)
    assert own.params()["friction_params"] == VW
    assert m.linear_gaussian() is None and m.crossing_is_smooth is True


def test_deterministic_slip_matches_an_ode_solver():
    """D = 0: Euler-Maruyama converges at first order to the slip of the ODE (solved to
    1e-11 by SciPy); Richardson extrapolation of dt = 0.004, 0.002 cancels the O(dt) term."""
    m = FrictionBlock(1.0, 0.5, 0.0, 0.1, "velocity-weakening", VW)
    law, x0 = m.friction, 1.0  # threshold static / k

    def rhs(t, y):
        return [y[1], -m.k * y[0] + float(law.force(m.v_b - y[1]))]

    def stick(t, y):
        return y[1] - m.v_b

    stick.terminal, stick.direction = True, 1
    sol = solve_ivp(rhs, (0, 30), [x0, m.v_b], events=stick, rtol=1e-11, atol=1e-12)
    T, d = sol.t_events[0][0], x0 - sol.y_events[0][0][0]
    runs = [ss.simulate(m, 128, dt, 30.0, seed=0) for dt in (0.004, 0.002)]
    for e in runs:
        assert np.ptp(e.slip_time) == 0.0  # no noise: every path is the same
        assert e.slip_time[0] == pytest.approx(T, abs=2e-3)
        assert e.slip_distance[0] == pytest.approx(d, abs=2e-2) and d > 1.0
        np.testing.assert_allclose(e.stick_time, e.slip_distance / m.v_b, rtol=1e-12)
    coarse, fine = runs
    assert 2 * fine.slip_time[0] - coarse.slip_time[0] == pytest.approx(T, abs=1e-4)
    assert 2 * fine.slip_distance[0] - coarse.slip_distance[0] == pytest.approx(d, abs=1e-4)


@pytest.fixture(scope="module")
def noisy():
    """The example (OU friction noise) with the free run recorded up to t = 30."""
    m = FrictionBlock.example()
    return m, ss.simulate(m, N_PATHS, 0.01, 30.0, seed=1, record_upcrossings=16)


def test_noisy_ensemble(noisy):
    m, e = noisy
    x0 = m.friction.static_limit / m.k
    assert e.stuck.all() and not e.immediate.any()  # a(0) = -sigma F0 < 0: every slip starts
    assert np.all(np.isfinite(e.slip_time)) and np.all(e.slip_time > 0)
    np.testing.assert_allclose(e.onset_state, [[x0, m.v_b, 0.0]] * N_PATHS, rtol=0, atol=0)
    np.testing.assert_allclose(e.stick_position, x0 - e.slip_distance, rtol=1e-12)
    # the stick rides the belt back to the same threshold
    np.testing.assert_allclose(e.stick_time, np.maximum(e.slip_distance, 0) / m.v_b, rtol=1e-12)
    np.testing.assert_allclose(e.period, e.slip_time + e.stick_time, rtol=1e-12)
    # A full slip swings the block back (d > 0); the noise also ends some slips early, while
    # the block still moves with about the belt's speed, a little beyond its start (d < 0).
    full = e.slip_time > 1.0
    assert np.all(e.slip_distance[full] > 0) and np.all(e.slip_distance[~full] < 0)
    assert 0.5 < full.mean() < 1.0


def test_empirical_estimator(noisy):
    m, e = noisy
    est = ss.CrossingEstimator(m, ensemble=e)
    up = e.upcrossings
    assert est.immediate_probability == 0.0 and not est.exact
    assert est.t_complete == 30.0  # no path had 16 upcrossings
    # The free run is the slip until the stick: its first upcrossing is the stick (located
    # in the same step, by linear rather than cubic interpolation).
    assert np.max(np.abs(up.times[:, 0] - e.slip_time)) <= 0.01
    # The first-passage density integrates to the fraction of stuck paths: F_g1 has mass
    # 1 - exp(-int n1), and the free run keeps upcrossing (int n1 ~ 5 by t = 30).
    mass = est.diagnostics(30.0)["mass"]
    assert mass == pytest.approx(e.fraction_stuck, abs=0.01)
    # Bonferroni on the same sample: E[N] - E[N(N-1)/2] <= P(N >= 1) <= E[N] by each cell
    # edge, N the upcrossings before it (the truncations F_n^(1), F_n^(2) on the cells).
    h = est.dt
    grid = np.arange(int(round(30.0 / h)) + 1) * h
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ss.ApproximationWarning)  # F_n^(2) goes negative
        upper, lower = (
            h * (np.cumsum(F) - F[0] / 2)
            for F in (est.first_passage(grid, "truncation", k) for k in (1, 2))
        )
    P = (up.times[:, :1] < grid + h / 2).mean(axis=0)
    assert np.all(lower <= P + 1e-12) and np.all(P <= upper + 1e-12)
    assert upper[-1] > 2.0 and P[-1] == 1.0


# continuous monitoring in the slow tier (5 s cold): the grid variant checks the same law
@pytest.mark.parametrize("monitor", ["grid", pytest.param("continuous", marks=pytest.mark.slow)])
def test_linear_viscous_block_is_langevin(Langevin, monitor):
    """With F(V) = F_k + mu V the slip is `langevin` (omega0^2 = k, zeta = mu) with x shifted
    by (F_k + mu v_b) / k. Same seed and Euler-Maruyama on both: the same noise drives the
    same SDE, so on the grid the results agree to rounding. The continuous monitor places
    the stick on the cubic through the step's ends with the drift as slopes; at the end
    (V < 0) the block holds the force at F(0+) = F_k where langevin goes on linearly, so
    the slopes differ by mu (v - v_b) = O(dt) and the stick moves by O(mu dt^2)."""
    k, mu, Fs, Fk, vb, D, tau = 2.25, 0.3, 3.0, 1.0, 1.0, 0.4, 0.1
    block = FrictionBlock(k, vb, D, tau, LinearViscous(static=Fs, viscosity=mu, kinetic=Fk))
    shift = (Fk + mu * vb) / k
    plain = Langevin(omega0=math.sqrt(k), zeta=mu, D=D, v_b=vb, x0=Fs / k - shift, tau=tau)
    dt = 0.01
    a = ss.simulate(block, 1000, dt, 20.0, seed=7, solver="euler", monitor=monitor)
    b = ss.simulate(plain, 1000, dt, 20.0, seed=7, solver="euler", monitor=monitor)
    assert a.info["solver"] == b.info["solver"] == "euler"
    assert np.array_equal(a.stuck, b.stuck) and a.fraction_stuck > 0.99
    tol = 1e-12 if monitor == "grid" else mu * dt**2
    for name in ("slip_time", "slip_distance", "stick_time"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=0, atol=tol)
    np.testing.assert_allclose(a.stick_position - shift, b.stick_position, rtol=0, atol=tol)


def test_stribeck_slips_have_zero_length():
    """F(0+) = F_s: the slip starts with dv/dt = 0, the noise wins over the deceleration at
    short times and v re-crosses v_b at once: every slip is an immediate re-stick."""
    m = FrictionBlock(
        1.0, 0.5, 0.01, 0.1, "stribeck", {"static": 1.0, "coulomb": 0.5, "v_stribeck": 0.3}
    )
    e = ss.simulate(m, 128, 0.01, 5.0, seed=0)
    assert e.immediate.all() and np.all(e.slip_time == 0) and np.all(e.slip_distance == 0)


class _Sticky(FrictionLaw):
    """A law whose kinetic force exceeds its static limit."""

    def force(self, V):
        return 2.0 + 0.0 * V

    @property
    def static_limit(self):
        return 1.0


GOOD = dict(k=1.0, v_b=0.5, D=0.01, tau=0.1, friction="velocity-weakening", friction_params=VW)
BAD = [
    (dict(k=0.0), "k", "must be > 0"),
    (dict(k="stiff"), "k", "must be a real number"),
    (dict(v_b=-1.0), "v_b", "must be > 0"),
    (dict(D=-0.1), "D", "must be >= 0"),
    (dict(tau=0.0), "tau", "must be > 0"),
    (dict(tau=math.inf), "tau", "must be finite"),
    (dict(friction="teflon"), "friction", "must be one of 'coulomb'"),
    (dict(friction_params=VW | {"sigma": 1.0}), "friction_params.sigma", r"in \[0, 1\)"),
    (dict(friction_params=VW | {"F0": -1.0}), "friction_params.F0", "must be > 0"),
    (dict(friction_params={"F0": 1.0}), "friction_params.alpha", "is required by the"),
    (dict(friction_params=VW | {"mu": 1}), "friction_params.mu", "is not a parameter of the"),
    (dict(friction_params=[1.0, 1.0]), "friction_params", "must be a dict"),
    (dict(friction_params={1: 1.0}), "friction_params", "must be a dict"),
    (dict(friction=VelocityWeakening(**VW)), "friction_params", "must be None"),
    (dict(friction=_Sticky(), friction_params=None), "friction", "exceeds static_limit"),
]


@pytest.mark.parametrize(
    "change, field, reason", BAD, ids=[f"{b[1]}-{i}" for i, b in enumerate(BAD)]
)
def test_bad_parameters_name_the_field(change, field, reason):
    with pytest.raises(ss.ParameterError, match=reason) as info:
        FrictionBlock(**(GOOD | change))
    msg = str(info.value)
    assert "\n" not in msg and info.value.parameter == field
    assert msg.startswith(f"friction-block: parameter '{field}' ")
