"""The `langevin` plugin: parameters, validation, and consistency of its descriptions."""

import math

import equinox as eqx
import numpy as np
import pytest

import stickslip
from stickslip._jax import jax, jnp

GOOD = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)


@pytest.mark.parametrize(
    "change, match",
    [
        ({"zeta": 0.0}, r"'zeta' must be > 0"),
        ({"zeta": -0.1}, r"'zeta' must be > 0"),
        ({"D": -1e-3}, r"'D' must be >= 0"),
        ({"v_b": 0.0}, r"'v_b' must be > 0"),
        ({"omega0": -1.0}, r"'omega0' must be > 0"),
        ({"x0": 0.0}, r"'x0' must be > 0"),
        ({"tau": 0.0}, r"'tau' must be > 0"),
        ({"tau": -2.0}, r"'tau' must be > 0"),
        ({"D": float("nan")}, r"'D' must be finite"),
        ({"omega0": float("inf")}, r"'omega0' must be finite"),
        ({"zeta": "fast"}, r"'zeta' must be a real number"),
        ({"v_b": True}, r"'v_b' must be a real number"),
        ({"eta0": "random"}, r"'eta0' must be one of 'zero', 'stationary'"),
        ({"eta0": "stationary"}, r"'eta0' 'stationary' needs Ornstein-Uhlenbeck noise"),
    ],
)
def test_invalid_parameters_name_the_parameter(Langevin, change, match):
    with pytest.raises(stickslip.ParameterError, match=match) as info:
        Langevin(**(GOOD | change))
    assert "\n" not in str(info.value)
    assert info.value.parameter == next(iter(change))


def test_missing_parameter_is_an_error(Langevin):
    with pytest.raises(TypeError, match="x0"):
        Langevin(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0)


def test_ints_and_numpy_scalars_become_floats(Langevin):
    m = Langevin(omega0=1, zeta=np.float32(0.5), D=np.int64(0), v_b=2, x0=1)
    assert all(type(v) is float for k, v in m.params().items() if k in GOOD)


@pytest.mark.parametrize("tau", [None, 0.1])
def test_linear_gaussian_matches_drift_and_diffusion(Langevin, tau):
    m = Langevin(**GOOD, tau=tau)
    lg = m.linear_gaussian()
    d = len(m.state_names)
    rng = np.random.default_rng(0)
    for _ in range(5):
        y = jnp.asarray(rng.normal(size=d))
        np.testing.assert_allclose(m.drift(y), lg.A @ y + lg.b, rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(m.diffusion(y), lg.B, rtol=0, atol=1e-15)
        assert float(m.crossing(y)) == float(lg.crossing @ y)
        assert float(m.position(y)) == float(lg.position @ y)
    y0 = m.onset_state(jax.random.key(0))
    np.testing.assert_array_equal(y0, lg.m0)
    assert float(m.crossing(y0)) == m.stick_level == GOOD["v_b"]


@pytest.mark.parametrize("tau", [None, 0.1])
def test_linear_gaussian_is_numpy_for_numbers_and_traceable(Langevin, tau):
    """Of given parameters the description is plain NumPy (nothing for JAX to compile: the
    simulator then reads it without a compiled call), and of traced ones (a compiled caller,
    a gradient) it is the same arrays: the drift and diffusion at a traced omega0."""
    from stickslip._simulate.config import traces_nothing

    m = Langevin(**GOOD, tau=tau)
    lg = m.linear_gaussian()
    fields = ("A", "b", "B", "crossing", "position", "m0", "P0")
    assert all(type(getattr(lg, f)) is np.ndarray for f in fields)
    assert traces_nothing(m.linear_gaussian)
    assert not traces_nothing(lambda: jnp.eye(2))  # (a plugin's in JAX: one compiled call)

    @jax.jit
    def traced(omega0):  # (as the simulator's compiled calls see a model: arrays as leaves)
        lg = eqx.tree_at(lambda model: model.omega0, m, omega0).linear_gaussian()
        return [getattr(lg, f) for f in fields]

    for f, x in zip(fields, traced(jnp.asarray(GOOD["omega0"])), strict=True):
        np.testing.assert_array_equal(x, getattr(lg, f), err_msg=f)
    # d(A)/d(omega0): only the spring term, -2 omega0, depends on it
    dA = jax.jacfwd(lambda w: traced(w)[0])(jnp.asarray(1.5))
    expect = np.zeros_like(lg.A)
    expect[1, 0] = -3.0
    np.testing.assert_array_equal(dA, expect)


def test_ou_noise_has_the_stated_correlation(Langevin):
    """<eta(t) eta(s)> = (D/tau) exp(-|t-s|/tau): stationary variance and decay rate."""
    m = Langevin(**GOOD, tau=0.25)
    lg = m.linear_gaussian()
    a, g = float(lg.A[2, 2]), float(lg.B[2, 0])
    assert math.isclose(-1.0 / a, 0.25)
    assert math.isclose(g**2 / (2 * -a), GOOD["D"] / 0.25)  # OU stationary variance


def test_crossing_smoothness(Langevin):
    assert not Langevin(**GOOD).crossing_is_smooth  # white noise enters dv
    assert Langevin(**GOOD, tau=0.1).crossing_is_smooth
    assert Langevin(**(GOOD | {"D": 0.0})).crossing_is_smooth
    # The base class's generic rule agrees with the model's own statement.
    for m in (Langevin(**GOOD), Langevin(**GOOD, tau=0.1), Langevin(**(GOOD | {"D": 0.0}))):
        assert stickslip.FrictionModel.crossing_is_smooth.fget(m) == m.crossing_is_smooth


def test_stationary_onset_draws_eta(Langevin):
    m = Langevin(**GOOD, tau=0.1, eta0="stationary")
    keys = jax.random.split(jax.random.key(3), 20000)
    eta = np.asarray(jax.vmap(m.onset_state)(keys))[:, 2]
    var = GOOD["D"] / 0.1
    se = var * math.sqrt(2 / eta.size)
    assert abs(np.var(eta) - var) < 4 * se
    assert abs(np.mean(eta)) < 4 * math.sqrt(var / eta.size)


def test_stick_duration_is_clipped_at_zero(Langevin):
    m = Langevin(**GOOD, tau=0.1)
    onset = m.onset_state(jax.random.key(0))
    behind = onset.at[0].set(0.4)  # stuck at x = 0.4 < x0: sticks (1 - 0.4) / v_b
    beyond = onset.at[0].set(1.3)  # stuck beyond the threshold: releases at once
    assert math.isclose(float(m.stick_duration(behind, onset)), 0.6)
    assert float(m.stick_duration(beyond, onset)) == 0.0


def test_parameters_listing(Langevin):
    import dataclasses

    p = Langevin.parameters()
    assert p["tau"] is None and p["eta0"] == "zero"
    assert p["omega0"] is dataclasses.MISSING
