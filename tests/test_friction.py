"""The friction laws of `stickslip.friction`: forces against hand-written formulas, static
limits, `get_friction_law` and its one-line errors."""

import math
import re

import numpy as np
import pytest

import stickslip as ss
from stickslip._jax import jax, jnp
from stickslip.friction import (
    FRICTION_LAWS,
    Coulomb,
    FrictionLaw,
    LinearViscous,
    Stribeck,
    VelocityWeakening,
    get_friction_law,
)

V = [1e-3, 0.1, 0.7, 2.5]

# name -> (parameters, force(V) by hand, static limit, force as V -> 0+)
LAWS = {
    "coulomb": (dict(static=2.0, kinetic=1.5), lambda v: 1.5, 2.0, 1.5),
    "viscous": (dict(static=2.0, viscosity=0.4, kinetic=1.0), lambda v: 1.0 + 0.4 * v, 2.0, 1.0),
    "velocity-weakening": (
        dict(F0=2.0, alpha=0.5, sigma=0.1),
        lambda v: 2.0 * 0.9 / (1.0 + 2.0 * 0.5 * v / 0.9),
        2.0,
        1.8,
    ),
    "stribeck": (
        dict(static=2.0, coulomb=1.2, v_stribeck=0.3, delta=1.5, viscosity=0.1),
        lambda v: 1.2 + 0.8 * math.exp(-((v / 0.3) ** 1.5)) + 0.1 * v,
        2.0,
        2.0,
    ),
}


@pytest.mark.parametrize("name", sorted(LAWS))
def test_force_and_static_limit(name):
    params, by_hand, static, at_zero = LAWS[name]
    law = get_friction_law(name, **params)
    assert isinstance(law, FRICTION_LAWS[name]) and law.params() == params
    for v in V:
        assert float(law.force(v)) == pytest.approx(by_hand(v), rel=1e-14)
    assert law.static_limit == static
    assert float(law.force(0.0)) == pytest.approx(at_zero, rel=1e-14)
    # array-friendly, also under jit with the parameters as arrays (as the simulator has them)
    expected = np.array([by_hand(v) for v in V])
    np.testing.assert_allclose(law.force(jnp.asarray(V)), expected, rtol=1e-14)
    as_arrays = jax.tree_util.tree_map(jnp.asarray, law)
    jitted = jax.jit(lambda f, v: f.force(v))(as_arrays, jnp.asarray(V))
    np.testing.assert_allclose(jitted, expected, rtol=1e-14)


def test_force_at_slip_onset_holds_below_the_static_limit():
    """Near V -> 0+ the kinetic force is at most the static limit: strictly below it with a
    drop at onset (Coulomb, viscous with kinetic < static, velocity weakening with
    sigma > 0), equal to it for Stribeck, which then decays monotonically (no viscosity)."""
    small = np.logspace(-9, -2, 15)
    drops = [
        Coulomb(static=1.0, kinetic=0.6),
        LinearViscous(static=1.0, viscosity=2.0, kinetic=0.6),
        VelocityWeakening(F0=1.0, alpha=3.0, sigma=0.05),
    ]
    for law in drops:
        assert np.all(np.asarray(law.force(small)) < law.static_limit), law
    stribeck = Stribeck(static=1.0, coulomb=0.4, v_stribeck=0.2, delta=2.0)
    F = np.asarray(stribeck.force(np.concatenate([[0.0], small, [0.1, 1.0, 10.0]])))
    assert F[0] == stribeck.static_limit
    assert np.all(F[1:] <= stribeck.static_limit) and np.all(np.diff(F) <= 0)
    assert F[-1] == pytest.approx(0.4, rel=1e-12)  # the Coulomb level far from onset
    # velocity weakening decays from F0 (1 - sigma) towards 0
    vw = VelocityWeakening(F0=1.0, alpha=3.0, sigma=0.05)
    assert np.all(np.diff(np.asarray(vw.force(np.linspace(0.0, 50.0, 101)))) < 0)


def test_instances_and_user_laws():
    law = Stribeck(static=1.0, coulomb=0.5, v_stribeck=0.1)
    assert get_friction_law(law) is law
    with pytest.raises(ss.ParameterError, match=r"parameter 'law' is a FrictionLaw instance"):
        get_friction_law(law, static=2.0)

    class Exponential(FrictionLaw):  # a user's own law
        static: float
        drop: float

        def force(self, V):
            return self.static * (1.0 - self.drop) * jnp.exp(-V)

        @property
        def static_limit(self):
            return self.static

    mine = Exponential(static=2.0, drop=0.25)
    assert get_friction_law(mine) is mine and mine.params() == {"static": 2.0, "drop": 0.25}
    assert float(mine.force(0.0)) == 1.5

    class Incomplete(FrictionLaw):
        def force(self, V):
            return V

    with pytest.raises(TypeError):
        Incomplete()  # no static_limit


BAD = [
    ("coulomb", dict(static=-1.0, kinetic=0.0), "static", "must be > 0"),
    ("coulomb", dict(static=1.0, kinetic=-0.1), "kinetic", "must be >= 0"),
    ("coulomb", dict(static=1.0, kinetic=1.5), "kinetic", "must be <= static"),
    ("coulomb", dict(static="high", kinetic=0.5), "static", "must be a real number"),
    ("viscous", dict(static=1.0, viscosity=-0.2), "viscosity", "must be >= 0"),
    ("viscous", dict(static=1.0, viscosity=0.2, kinetic=1.5), "kinetic", "must be <= static"),
    ("viscous", dict(static=0.0, viscosity=0.2), "static", "must be > 0"),
    ("velocity-weakening", dict(F0=1.0, alpha=1.0, sigma=1.0), "sigma", r"must be in \[0, 1\)"),
    ("velocity-weakening", dict(F0=1.0, alpha=1.0, sigma=-0.1), "sigma", r"must be in \[0, 1\)"),
    ("velocity-weakening", dict(F0=1.0, alpha=-1.0), "alpha", "must be >= 0"),
    ("velocity-weakening", dict(F0=math.nan, alpha=1.0), "F0", "must be finite"),
    ("stribeck", dict(static=1.0, coulomb=1.2, v_stribeck=0.1), "coulomb", "must be <= static"),
    ("stribeck", dict(static=1.0, coulomb=0.5, v_stribeck=0.0), "v_stribeck", "must be > 0"),
    ("stribeck", dict(static=1.0, coulomb=0.5, v_stribeck=0.1, delta=0.0), "delta", "> 0"),
    ("stribeck", dict(static=1.0, coulomb=0.5, v_stribeck=0.1, viscosity=-1), "viscosity", ">= 0"),
    ("stribeck", dict(static=1.0, coulomb=0.5), "v_stribeck", "is required by the stribeck law"),
    ("coulomb", dict(static=1.0, kinetic=0.5, mu=0.1), "mu", "is not a parameter of the coulomb"),
    ("nope", {}, "law", "must be one of 'coulomb', 'viscous', 'velocity-weakening'"),
    (None, {}, "law", "must be one of"),
]


@pytest.mark.parametrize("name, params, parameter, reason", BAD)
def test_invalid_parameters_give_one_line_errors(name, params, parameter, reason):
    with pytest.raises(ss.ParameterError) as info:
        get_friction_law(name, **params)
    msg = str(info.value)
    assert "\n" not in msg
    assert info.value.parameter == parameter
    assert f"parameter '{parameter}'" in msg
    assert re.search(reason, msg), msg
