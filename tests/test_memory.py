"""Models with memory across cycles (`FrictionModel.carries_state`, `release`): a block whose
static threshold grows with the time it stayed stuck (contact aging), written against the
public plugin surface, checked against an independent integration of its cycle map."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import stickslip as ss
from stickslip.plugin import (
    FrictionModel,
    LinearGaussian,
    check_nonnegative,
    check_positive,
    jax,
    jnp,
)


class AgingBlock(FrictionModel):
    r"""The Langevin slip (eq. 8, OU friction noise) with a threshold that ages during the
    stick: after $t$ stuck, the static threshold is $x_s(t) = x_s + \beta \ln(1 + t/t_0)$.
    The stick ends when the stretch $x_{sl} + v_b t$ reaches it; the next slip starts there."""

    omega0: float = 1.0
    zeta: float = 0.05
    D: float = 0.0
    v_b: float = 1.0
    x_s: float = 2.0
    beta: float = 0.3
    t0: float = 0.5
    tau: float = 0.1

    carries_state = True

    def __check_init__(self):
        for name in ("omega0", "zeta", "v_b", "x_s", "t0", "tau"):
            check_positive("aging-block", name, getattr(self, name))
        check_nonnegative("aging-block", "D", self.D)
        check_nonnegative("aging-block", "beta", self.beta)

    state_names = ("x", "v", "eta")
    noise_dim = 1

    def drift(self, y):
        x, v, eta = y
        return jnp.stack([v, -(self.omega0**2) * x - self.zeta * v + eta, -eta / self.tau])

    def diffusion(self, y):
        g = jnp.sqrt(2.0 * self.D) / self.tau
        return jnp.stack([0.0 * g, 0.0 * g, g]).reshape(3, 1)

    @property
    def stick_level(self):
        return self.v_b

    @property
    def crossing_is_smooth(self):
        return True

    def onset_state(self, key):
        return jnp.stack([jnp.asarray(self.x_s, float), jnp.asarray(self.v_b, float), 0.0])

    def linear_gaussian(self):  # (the exact solver: no step error in the slips)
        A = np.array([[0.0, 1.0, 0.0], [-(self.omega0**2), -self.zeta, 1.0], [0, 0, -1 / self.tau]])
        B = np.array([[0.0], [0.0], [np.sqrt(2.0 * self.D) / self.tau]])
        e = np.eye(3)
        m0 = np.array([self.x_s, self.v_b, 0.0])
        return LinearGaussian(A, np.zeros(3), B, e[1], e[0], m0, np.zeros((3, 3)))

    def release(self, key, y_stick):
        x_sl = y_stick[0]
        # x_sl + v_b t - x_s(t) is convex and increasing once positive: bisection on a bracket
        # [0, hi] with hi past the root (60 halvings: to the last bit of hi).
        gap = lambda t: x_sl + self.v_b * t - self.x_s - self.beta * jnp.log1p(t / self.t0)  # noqa: E731
        hi = jnp.maximum(2.0 * (self.x_s - x_sl) / self.v_b, 0.0) + 4.0 * self.beta / self.v_b
        hi = hi + 4.0 * self.t0

        def halve(_, bounds):
            lo, hi = bounds
            mid = 0.5 * (lo + hi)
            up = gap(mid) > 0.0
            return jnp.where(up, lo, mid), jnp.where(up, mid, hi)

        lo, hi = jax.lax.fori_loop(0, 60, halve, (jnp.zeros(()), hi))
        t = jnp.where(gap(0.0) >= 0.0, 0.0, 0.5 * (lo + hi))
        x0 = x_sl + self.v_b * t
        return t, jnp.stack([x0, jnp.asarray(self.v_b, float), 0.0])


def _cycle_map(m, x0):
    """One deterministic cycle, independently: the slip by Radau to v = v_b, the stick by
    Brent's root of the aged threshold."""

    def rhs(t, y):
        x, v = y
        return [v, -(m.omega0**2) * x - m.zeta * v]

    ev = lambda t, y: y[1] - m.v_b  # noqa: E731
    ev.terminal, ev.direction = True, 1.0
    # (v starts at v_b and falls: look for the upcrossing after the first instants)
    sol = solve_ivp(rhs, (1e-12, 100.0), [x0, m.v_b], method="Radau", events=ev,
                    rtol=1e-12, atol=1e-14, first_step=1e-9)  # fmt: skip
    T_sl, x_sl = sol.t_events[0][0], sol.y_events[0][0][0]
    gap = lambda t: x_sl + m.v_b * t - m.x_s - m.beta * np.log1p(t / m.t0)  # noqa: E731
    T_st = 0.0 if gap(0.0) >= 0 else brentq(gap, 0.0, 1e3, xtol=1e-15, rtol=1e-15)
    return T_sl, x_sl, T_st, x_sl + m.v_b * T_st


def test_deterministic_cycles_follow_the_independent_map():
    m = AgingBlock()
    series = ss.simulate_cycles(m, 1, 0.01, 80.0, seed=0, record=False)
    c = series.cycles
    assert c["slip_time"].size >= 6
    x0 = m.x_s
    for i in range(c["slip_time"].size - 1):
        T_sl, x_sl, T_st, x0_next = _cycle_map(m, x0)
        # The exact flow is exact at the grid; the stick is located by the cubic check on
        # it (to ~1e-9 at dt 0.01), the stick time by 60 bisections.
        assert c["slip_time"][i] == pytest.approx(T_sl, rel=1e-7)
        assert c["stick_position"][i] == pytest.approx(x_sl, rel=1e-7, abs=1e-9)
        assert c["stick_time"][i] == pytest.approx(T_st, rel=1e-6, abs=1e-8)
        assert c["slip_distance"][i] == pytest.approx(x0 - x_sl, rel=1e-7, abs=1e-9)
        x0 = x0_next
    # Memory: the thresholds aged by different sticks differ from cycle to cycle (the
    # memoryless model would restart each at x_s).
    onsets = c["stick_position"][:-1] + m.v_b * c["stick_time"][:-1]
    assert np.ptp(onsets[:3]) > 1e-3


def test_simulate_keeps_its_first_passage_meaning():
    """`simulate`: every first slip starts from `onset_state`; the stick time and the next
    onset come from `release`."""
    m = AgingBlock(D=0.05)
    e = ss.simulate(m, 2000, 0.05, 60.0, seed=1)
    assert e.fraction_stuck > 0.99
    np.testing.assert_allclose(e.onset_state[:, 0], m.x_s)
    s = e.stuck
    x_sl = e.stick_position[s]
    gap = x_sl + m.v_b * e.stick_time[s] - m.x_s - m.beta * np.log1p(e.stick_time[s] / m.t0)
    np.testing.assert_allclose(gap, 0.0, atol=1e-10)
    np.testing.assert_allclose(e.next_onset_state[s, 0], x_sl + m.v_b * e.stick_time[s])


def test_noisy_cycles_carry_the_threshold():
    """With noise, each slip starts at the threshold its stick aged to: the onset of cycle
    n + 1 equals the stick position of cycle n plus v_b times its stick time."""
    m = AgingBlock(D=0.05)
    series = ss.simulate_cycles(m, 2, 0.05, 60.0, seed=2, record=True)
    c = series.cycles
    for p in range(2):
        rows = np.nonzero(c["path"] == p)[0]
        t, states, slipping = series.trajectory(p)
        starts = states[np.r_[True, ~slipping[:-1]] & slipping][:, 0]
        expect = c["stick_position"][rows[:-1]] + m.v_b * c["stick_time"][rows[:-1]]
        np.testing.assert_allclose(starts[1 : rows.size], expect, rtol=1e-12)


@pytest.mark.parametrize("name", ["langevin", "random-threshold"])
def test_a_memoryless_stick_is_the_release_contracts_default(name):
    """One contract for every model's stick: what `release(key, y_stick)` returns. A
    memoryless model (`carries_state = False`) is not a second kind of model: its stick is
    `release`'s default (the next onset drawn with the cycle's key, the stick time to it),
    which the simulator evaluates inside its onset program. The stick times and next onsets
    of `simulate` are `release` called on its stick states with the cycle's keys, to
    rounding (two programs compiled apart; a random threshold draws its next threshold
    there: another key would move it by its sd)."""
    from stickslip import _rng
    from stickslip._simulate.host import HostRun

    params = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, tau=0.1)
    if name == "langevin":
        model = ss.get_model(name)(**params, x0=1.0)
    else:
        model = ss.get_model(name)(**params, threshold="normal",
                                   threshold_params={"mean": 1.0, "sd": 0.3})  # fmt: skip
    assert not model.carries_state
    ens = ss.simulate(model, 500, 0.1, 40.0, seed=4)
    stuck = ens.stuck
    run = HostRun("simulate", model, "auto", "continuous", 0.1, 40.0, _rng.seed_key(4))
    keys = _rng.path_keys(run.keys["onset"], np.arange(500, dtype=np.uint32)[stuck], 1)
    T_st, y_next = jax.vmap(model.release)(keys, jnp.asarray(ens.stick_state[stuck]))
    np.testing.assert_allclose(np.asarray(y_next), ens.next_onset_state[stuck], rtol=1e-13,
                               atol=1e-13)  # fmt: skip
    np.testing.assert_allclose(np.asarray(T_st), ens.stick_time[stuck], rtol=1e-13, atol=1e-13)
