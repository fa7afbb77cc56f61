"""Friction laws: the kinetic friction force as a function of the slip velocity, and the
static limit that a stuck contact holds.

A law is a small equinox Module; models that take one (`burridge-knopoff`, the
`friction-block` example plugin) call `force(V)` for a slip velocity `V > 0` and compare the
driving force of a stuck contact with `static_limit`. `get_friction_law(name, **params)` builds
one by name (as a study file does).
"""

from __future__ import annotations

import abc

import equinox as eqx

from ._errors import ParameterError, build_named, check_nonnegative, check_positive, check_real

__all__ = [
    "FrictionLaw",
    "Coulomb",
    "LinearViscous",
    "VelocityWeakening",
    "Stribeck",
    "get_friction_law",
    "FRICTION_LAWS",
]


class FrictionLaw(eqx.Module):
    """A friction law: `force(V)` for the slip velocity `V > 0` and the `static_limit`."""

    @abc.abstractmethod
    def force(self, V):
        """Kinetic friction force opposing a slip at velocity `V > 0` (array-friendly)."""

    @property
    @abc.abstractmethod
    def static_limit(self):
        """Largest force a stuck contact holds before it slips."""

    def params(self) -> dict:
        import dataclasses

        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


def _floats(owner, **values):
    return {k: check_real(owner, k, v) for k, v in values.items()}


class Coulomb(FrictionLaw):
    """Coulomb friction: `static` while stuck, a constant `kinetic` force while slipping
    (`static >= kinetic >= 0`)."""

    static: float
    kinetic: float

    def __init__(self, static, kinetic):
        v = _floats("coulomb", static=static, kinetic=kinetic)
        self.static, self.kinetic = v["static"], v["kinetic"]

    def __check_init__(self):
        check_positive("coulomb", "static", self.static)
        check_nonnegative("coulomb", "kinetic", self.kinetic)
        if self.kinetic > self.static:
            raise ParameterError(
                "coulomb", "kinetic", f"must be <= static = {self.static}", self.kinetic
            )

    def force(self, V):
        return self.kinetic + 0.0 * V

    @property
    def static_limit(self):
        return self.static


class LinearViscous(FrictionLaw):
    """Kinetic force `kinetic + viscosity * V` (Coulomb plus viscous damping); with it a
    single block is the paper's Langevin model (`static >= kinetic >= 0`, `viscosity >= 0`)."""

    static: float
    viscosity: float
    kinetic: float = 0.0

    def __init__(self, static, viscosity, kinetic=0.0):
        v = _floats("viscous", static=static, viscosity=viscosity, kinetic=kinetic)
        self.static, self.viscosity, self.kinetic = v["static"], v["viscosity"], v["kinetic"]

    def __check_init__(self):
        check_positive("viscous", "static", self.static)
        check_nonnegative("viscous", "viscosity", self.viscosity)
        check_nonnegative("viscous", "kinetic", self.kinetic)
        if self.kinetic > self.static:
            raise ParameterError(
                "viscous", "kinetic", f"must be <= static = {self.static}", self.kinetic
            )

    def force(self, V):
        return self.kinetic + self.viscosity * V

    @property
    def static_limit(self):
        return self.static


class VelocityWeakening(FrictionLaw):
    r"""Carlson-Langer velocity weakening:
    $F(V) = F_0 (1 - \sigma) / (1 + 2\alpha V / (1 - \sigma))$, static limit $F_0$. A drop
    $\sigma F_0$ at the onset of slip and a decay with velocity set by $\alpha$."""

    F0: float
    alpha: float
    sigma: float = 0.01

    def __init__(self, F0, alpha, sigma=0.01):
        v = _floats("velocity-weakening", F0=F0, alpha=alpha, sigma=sigma)
        self.F0, self.alpha, self.sigma = v["F0"], v["alpha"], v["sigma"]

    def __check_init__(self):
        check_positive("velocity-weakening", "F0", self.F0)
        check_nonnegative("velocity-weakening", "alpha", self.alpha)
        if not 0.0 <= self.sigma < 1.0:
            raise ParameterError("velocity-weakening", "sigma", "must be in [0, 1)", self.sigma)

    def force(self, V):
        s = 1.0 - self.sigma
        return self.F0 * s / (1.0 + 2.0 * self.alpha * V / s)

    @property
    def static_limit(self):
        return self.F0


class Stribeck(FrictionLaw):
    r"""Stribeck curve: $F(V) = F_c + (F_s - F_c) e^{-(V/V_s)^\delta} + \mu V$, static limit
    $F_s$ (`static >= coulomb >= 0`, `v_stribeck > 0`, `delta > 0`, `viscosity >= 0`)."""

    static: float
    coulomb: float
    v_stribeck: float
    delta: float = 2.0
    viscosity: float = 0.0

    def __init__(self, static, coulomb, v_stribeck, delta=2.0, viscosity=0.0):
        v = _floats(
            "stribeck", static=static, coulomb=coulomb, v_stribeck=v_stribeck, delta=delta,
            viscosity=viscosity,
        )  # fmt: skip
        self.static, self.coulomb, self.v_stribeck = v["static"], v["coulomb"], v["v_stribeck"]
        self.delta, self.viscosity = v["delta"], v["viscosity"]

    def __check_init__(self):
        check_positive("stribeck", "static", self.static)
        check_nonnegative("stribeck", "coulomb", self.coulomb)
        if self.coulomb > self.static:
            raise ParameterError(
                "stribeck", "coulomb", f"must be <= static = {self.static}", self.coulomb
            )
        check_positive("stribeck", "v_stribeck", self.v_stribeck)
        check_positive("stribeck", "delta", self.delta)
        check_nonnegative("stribeck", "viscosity", self.viscosity)

    def force(self, V):
        import jax.numpy as jnp

        decay = jnp.exp(-((jnp.abs(V) / self.v_stribeck) ** self.delta))
        return self.coulomb + (self.static - self.coulomb) * decay + self.viscosity * V

    @property
    def static_limit(self):
        return self.static


FRICTION_LAWS = {
    "coulomb": Coulomb,
    "viscous": LinearViscous,
    "velocity-weakening": VelocityWeakening,
    "stribeck": Stribeck,
}


def get_friction_law(name: str | FrictionLaw, **params) -> FrictionLaw:
    """A friction law by name (`coulomb`, `viscous`, `velocity-weakening`, `stribeck`) and its
    parameters; an instance (with no parameters) is returned unchanged."""
    if isinstance(name, FrictionLaw):
        if params:
            raise ParameterError(
                "friction", "law", "is a FrictionLaw instance: give its parameters to it, not here"
            )
        return name
    return build_named("friction", "law", FRICTION_LAWS, name, params)
