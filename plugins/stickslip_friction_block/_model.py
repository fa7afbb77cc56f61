"""A block on a moving belt, held by a spring, with a friction law and Ornstein-Uhlenbeck
friction noise."""

from __future__ import annotations

import dataclasses
import math

from stickslip_langevin import check_noise, check_rate, check_speed

from stickslip import FrictionModel, ParameterError
from stickslip.friction import FRICTION_LAWS, FrictionLaw
from stickslip.plugin import build_named, check_nonnegative, check_positive, check_real, jnp

_NAME = "friction-block"


class FrictionBlock(FrictionModel):
    r"""A block of unit mass on a belt moving at speed $v_b$, tied to a wall by a spring.

    `x` is the spring's stretch and `v` the block's velocity; the block slides over the belt
    at $V = v_b - v$. The friction law pulls the block along with the belt:

    $$\dot x = v, \qquad \dot v = -k x + F(v_b - v) + \eta, \qquad
    d\eta = -\eta/\tau\,dt + \sqrt{2D}/\tau\,dW.$$

    The slip ends when $v$ reaches $v_b$. During the stick the block rides the belt and the
    spring stretches at $v_b$ until $k x$ reaches the law's static limit $F_s$: the next slip
    starts from $(F_s/k,\ v_b,\ 0)$.

    The law is used for $V > 0$. Where $V \le 0$ (the end of the step in which the block
    sticks, and the free run past the stick that `simulate(record_upcrossings=K)` records)
    the force is held at $F(0^+)$, so every law stays finite there. A law with
    $F(0^+) = F_s$ (Stribeck, Coulomb with kinetic = static) starts each slip with
    $\dot v(0) = 0$: with the noise, $v$ re-crosses $v_b$ at once and every slip has zero
    length (an immediate re-stick). A slip needs a drop at onset, $F(0^+) < F_s$.

    With `LinearViscous(static=Fs, viscosity=mu, kinetic=Fk)` this is the `langevin` model
    with $\omega_0^2 = k$, $\zeta = \mu$, shifted by $(F_k + \mu v_b)/k$ in $x$.

    **Arguments:** `k` (spring stiffness $> 0$), `v_b` (belt speed $> 0$), `D` (noise
    intensity $\ge 0$), `tau` (noise correlation time $> 0$), `friction` (a
    `stickslip.friction.FrictionLaw`, or a law's name: `"coulomb"`, `"viscous"`,
    `"velocity-weakening"`, `"stribeck"`), `friction_params` (a dict of the named law's
    parameters).

    **Admissible scales** (as for `langevin`, with $\omega_0 = \sqrt k$ and the length
    $F_s/k$): $\sqrt k$ and $1/\tau$ at most 1e12 per time unit, and $D = 0$ or a noise
    level $D / (k^{3/2} (F_s/k)^2)$ between 1e-100 and 1e12.
    """

    k: float
    v_b: float
    D: float
    tau: float
    friction: FrictionLaw

    def __init__(self, k, v_b, D, tau, friction, friction_params=None):
        self.k = check_real(_NAME, "k", k)
        self.v_b = check_real(_NAME, "v_b", v_b)
        self.D = check_real(_NAME, "D", D)
        self.tau = check_real(_NAME, "tau", tau)
        self.friction = _make_law(friction, friction_params)

    def __check_init__(self):
        # Runs on construction only (not on the array-valued copies made for jitted code).
        check_positive(_NAME, "k", self.k)
        check_positive(_NAME, "v_b", self.v_b)
        check_nonnegative(_NAME, "D", self.D)
        check_positive(_NAME, "tau", self.tau)
        static = check_real(_NAME, "friction", self.friction.static_limit)
        if static <= 0:
            raise ParameterError(_NAME, "friction", "needs a static_limit > 0", static)
        kinetic = float(self.friction.force(0.0))
        if not kinetic <= static:  # the slip would end at once, every time
            raise ParameterError(
                _NAME, "friction", f"force(0+) = {kinetic:g} exceeds static_limit = {static:g}"
            )
        # The scales of `langevin` (stickslip_langevin._scales), with omega0 = sqrt(k) and the
        # onset stretch F_s / k as the length.
        omega0 = math.sqrt(self.k)
        check_rate(_NAME, "k", omega0, "sqrt(k)", self.k)
        check_rate(_NAME, "tau", 1.0 / self.tau, "1/tau", self.tau)
        check_noise(_NAME, self.D, omega0, static / self.k, "k^1.5 (F_s/k)^2")
        check_speed(_NAME, self.v_b, omega0, static / self.k, "k^0.5 F_s/k")

    # -- slip-phase SDE ------------------------------------------------------------------
    @property
    def state_names(self):
        return ("x", "v", "eta")

    @property
    def noise_dim(self):
        return 1

    def drift(self, y):
        x, v, eta = y[0], y[1], y[2]
        force = self.friction.force(jnp.maximum(self.v_b - v, 0.0))
        return jnp.stack([v, -self.k * x + force + eta, -eta / self.tau])

    def diffusion(self, y):
        g = jnp.sqrt(2.0 * self.D) / self.tau
        z = jnp.zeros_like(g)
        return jnp.stack([z, z, g]).reshape(3, 1)

    # -- crossing, stick and release -----------------------------------------------------
    @property
    def stick_level(self):
        return self.v_b

    @property
    def crossing_is_smooth(self):
        return True  # the noise enters through eta: v is differentiable

    def onset_state(self, key):
        x0 = jnp.asarray(self.friction.static_limit, float) / self.k
        return jnp.stack([x0, jnp.asarray(self.v_b, float), jnp.zeros(())])

    # -- conveniences --------------------------------------------------------------------
    @classmethod
    def example(cls):
        """Carlson-Langer velocity weakening with a 20% drop at onset."""
        return cls(
            k=1.0, v_b=0.5, D=0.01, tau=0.1,
            friction="velocity-weakening", friction_params={"F0": 1.0, "alpha": 1.0, "sigma": 0.2},
        )  # fmt: skip

    @classmethod
    def parameters(cls):
        M = dataclasses.MISSING
        return {"k": M, "v_b": M, "D": M, "tau": M, "friction": M, "friction_params": None}

    def params(self):
        """The constructor's arguments: `FrictionBlock(**m.params())` rebuilds `m`."""
        out = {name: getattr(self, name) for name in ("k", "v_b", "D", "tau")}
        name = next((n for n, c in FRICTION_LAWS.items() if type(self.friction) is c), None)
        if name is None:  # a user's own law: passed as an instance
            return out | {"friction": self.friction, "friction_params": None}
        return out | {"friction": name, "friction_params": self.friction.params()}


def _make_law(friction, friction_params):
    """The friction law from an instance or a name and its parameters; errors name the
    model's field (`friction`, `friction_params`, or `friction_params.<law parameter>`)."""
    if isinstance(friction, FrictionLaw):
        if friction_params is not None:
            raise ParameterError(
                _NAME, "friction_params", "must be None when friction is a FrictionLaw instance"
            )
        return friction
    return build_named(_NAME, "friction", FRICTION_LAWS, friction, friction_params,
                       params_field="friction_params")  # fmt: skip
