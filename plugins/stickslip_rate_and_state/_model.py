r"""A slider of mass $M$ on a spring $k$ driven at $V$, with Dieterich-Ruina rate-and-state
friction and optional Ornstein-Uhlenbeck friction noise, in SI units."""

from __future__ import annotations

import math

import numpy as np

from stickslip import ParameterError
from stickslip.plugin import (
    CreepingSlider,
    check_choice,
    check_nonnegative,
    check_positive,
    check_real,
    jnp,
)

_NAME = "rate-and-state"


class RateAndState(CreepingSlider):
    r"""A slider on a spring driven at `v_b`, with rate-and-state friction.

    $$M \dot v = k e - N \mu(v, \theta) + M \eta, \qquad \dot e = v_b - v,$$

    $e$ the spring's extension (force $k e$), $v > 0$ the slider's velocity, and

    $$\mu = \mu_0 + a \ln\frac{v}{v_{ref}} + b \ln\frac{v_{ref}\,\theta}{d_c},$$

    with Dieterich's aging law $\dot\theta = 1 - v\theta/d_c$ (`law="aging"`) or Ruina's slip
    law $\dot\theta = -(v\theta/d_c) \ln(v\theta/d_c)$ (`law="slip"`). Steady sliding at $V$
    has $\theta = d_c / V$ and $\mu_{ss} = \mu_0 + (a - b) \ln(V / v_{ref})$; it weakens with
    speed where $b > a$. Friction noise: $d\eta = -\eta/\tau\,dt + \sqrt{2D}/\tau\,dW$ (an
    acceleration, as in the `langevin` model; `D` in m²/s³).

    **As $v \to 0$.** $\mu$ is the regularised form of earthquake-cycle codes,
    $\mu = a\,\mathrm{asinh}\!\left(\frac{v}{2 v_{ref}} e^{(\mu_0 + b \ln(v_{ref}\theta/d_c))/a}
    \right)$: equal to the logarithmic law to $O(e^{-2\mu/a})$ (1e-26 for paper-like
    $\mu/a = 30$) and finite as $v \to 0$. The state holds $\ln(v / v_b)$, so the
    velocity stays positive: the slider creeps rather than stops, and a stick is the creep
    where the force rises (see `stickslip.plugin.CreepingSlider`).

    **Arguments** (SI): `mass` (kg), `stiffness` (N/m), `v_b` (m/s), `normal_force` (N),
    `mu0`, `a`, `b` (> 0), `d_c` (m), `v_ref` (m/s), `law` (`"aging"` or `"slip"`), `D`
    (>= 0) and `tau` (s, needed when D > 0), and `v_init` (m/s): a run starts in steady
    sliding at `v_init` (default 1.5 `v_b`) with the drive stepped to `v_b` at t = 0 (a
    velocity step: its response, and a perturbation that grows into stick-slip or
    oscillation, or decays, as the regime has it).
    """

    mass: float
    stiffness: float
    v_b: float
    normal_force: float
    mu0: float
    a: float
    b: float
    d_c: float
    v_ref: float
    law: str = "aging"
    D: float = 0.0
    tau: float | None = None
    v_init: float | None = None

    def __check_init__(self):
        for name in ("mass", "stiffness", "v_b", "normal_force", "a", "b", "d_c", "v_ref"):
            check_positive(_NAME, name, getattr(self, name))
        check_real(_NAME, "mu0", self.mu0)
        check_choice(_NAME, "law", self.law, ("aging", "slip"))
        check_nonnegative(_NAME, "D", self.D)
        check_positive(_NAME, "tau", self.tau, allow_none=True)
        if self.D > 0 and self.tau is None:
            raise ParameterError(
                _NAME, "tau", "is needed with friction noise (D > 0): its correlation time"
            )
        check_positive(_NAME, "v_init", self.v_init, allow_none=True)

    # -- the motion ------------------------------------------------------------------------
    # The state in units that make every component O(1) for the integrator's tolerances:
    # x = k e / (N a) (the spring's force in units of N a), u = ln(v / v_b) (the slider's
    # log velocity, 0 at the drive's: the creep is a few units below), w = ln(v_ref theta /
    # d_c), q = M eta / (N a). In u the creep's velocity follows the force linearly, where
    # v itself follows it exponentially: 10.6 k implicit steps for 15 s of the paper-like
    # slider at 1e-8, against 63 k in v / v_b (at 1e-9: 68 k).
    @property
    def state_names(self):
        return ("x", "u", "w", "q")

    @property
    def noise_dim(self):
        return 1

    def friction(self, v, w):
        r"""The friction coefficient at slider velocity `v` (m/s) and $w = \ln(v_{ref}
        \theta/d_c)$: $a\,\mathrm{asinh}(\frac{v}{2 v_{ref}} e^{(\mu_0 + b w)/a})$."""
        # a asinh(z), z = sign(v) e^L: for L > 0 as L + log(1 + sqrt(1 + e^-2L)) (no
        # overflow at e^L ~ 1e13 and beyond), else directly.
        L = jnp.log(jnp.abs(v) / (2.0 * self.v_ref) + 1e-300) + (self.mu0 + self.b * w) / self.a
        big, small = jnp.maximum(L, 0.0), jnp.minimum(L, 0.0)
        mag = jnp.where(
            L > 0.0,
            big + jnp.log1p(jnp.sqrt(1.0 + jnp.exp(-2.0 * big))),
            jnp.arcsinh(jnp.exp(small)),
        )
        return self.a * jnp.sign(v) * mag

    def drift(self, y):
        x, u, w, q = y[0], y[1], y[2], y[3]
        Na = self.normal_force * self.a
        v = self.v_b * jnp.exp(u)
        net = Na * x - self.normal_force * self.friction(v, w) + Na * q  # M dv/dt
        du = net / (self.mass * v)
        dx = self.stiffness * (self.v_b - v) / Na
        if self.law == "aging":
            dw = (self.v_ref * jnp.exp(-w) - v) / self.d_c
        else:
            dw = -(v / self.d_c) * (u + jnp.log(self.v_b / self.v_ref) + w)
        dq = -q / self.tau if self.tau is not None else 0.0 * q
        return jnp.stack([dx, du, dw, dq])

    def diffusion(self, y):
        # q = M eta / (N a): d q = -q / tau dt + (M / (N a)) sqrt(2 D) / tau dW
        g = 0.0
        if self.tau is not None:
            g = self.mass / (self.normal_force * self.a) * jnp.sqrt(2.0 * self.D) / self.tau
        z = jnp.zeros((), dtype=jnp.float64)
        return jnp.stack([z, z, z, z + g]).reshape(4, 1)

    def slider_velocity(self, y):
        return self.v_b * jnp.exp(y[1])

    def crossing(self, y):
        """$v/v_b - 1$, from the log velocity."""
        return jnp.expm1(y[1])

    def spring_force(self, y):
        return self.normal_force * self.a * y[0]

    def position(self, y):
        """The spring's extension $e$ (the force over the stiffness)."""
        return self.normal_force * self.a * y[0] / self.stiffness

    def steady_state(self, v=None):
        r"""The state of steady sliding at `v` (default `v_b`): $\theta = d_c / v$ and the
        spring's force $N \mu(v, d_c/v)$."""
        v = float(self.v_b if v is None else v)
        w = math.log(self.v_ref / v)
        mu = float(self.friction(jnp.asarray(v), jnp.asarray(w)))
        return jnp.array([mu / self.a, math.log(v / float(self.v_b)), w, 0.0])

    def onset_state(self, key):
        """Steady sliding at `v_init` (default 1.5 `v_b`), the drive stepping to `v_b` at
        t = 0: a velocity step, which grows into stick-slip or oscillation, or decays."""
        return self.steady_state(1.5 * self.v_b if self.v_init is None else self.v_init)

    # -- closed forms ----------------------------------------------------------------------
    def steady_friction(self, v=None):
        """$\\mu_{ss}(v) = \\mu_0 + (a - b) \\ln(v / v_{ref})$ (the logarithmic law)."""
        v = self.v_b if v is None else v
        return self.mu0 + (self.a - self.b) * np.log(v / self.v_ref)

    def critical_stiffness(self) -> float:
        r"""The stiffness below which steady sliding at `v_b` is unstable, with inertia
        (Rice and Ruina 1983): $k_c = \frac{N(b-a)}{d_c}\left(1 + \frac{M v_b^2}{N a d_c}
        \right)$, for either law (they linearise alike); nan where $b \le a$ (velocity
        strengthening: stable at any stiffness)."""
        if self.b <= self.a:
            return math.nan
        N, M, V = self.normal_force, self.mass, self.v_b
        return N * (self.b - self.a) / self.d_c * (1.0 + M * V**2 / (N * self.a * self.d_c))

    @classmethod
    def example(cls):
        """Paper on paper at the rig's softest spring and slowest drive (orientation values:
        M 30.7 g, N 0.301 N, a 0.01, b 0.015, d_c 1 um): stick-slip, k below k_c."""
        return cls(
            mass=0.0307, stiffness=168.0, v_b=42e-6, normal_force=0.301, mu0=0.3,
            a=0.01, b=0.015, d_c=1e-6, v_ref=1e-6,
        )  # fmt: skip
