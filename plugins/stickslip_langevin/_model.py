"""Langevin slip phase with white or Ornstein-Uhlenbeck friction noise (paper eqs. 8-9)."""

from __future__ import annotations

import equinox as eqx
import numpy as np

from stickslip import FrictionModel, LinearGaussian, ParameterError
from stickslip.plugin import check_choice, check_nonnegative, check_positive, jax, jnp

from ._scales import check_noise, check_rate, check_speed

_NAME = "langevin"


class LangevinSlip(FrictionModel):
    r"""The slip phase of eqs. (8-9), shared by `langevin` and `random-threshold`: state
    `(x, v)` (white noise) or `(x, v, eta)` (OU noise), crossing variable v at level $v_b$.
    A concrete model gives the parameters, `threshold_at(key)` (the onset position x0 of one
    slip) and `mean_threshold()` (for the Gaussian description; `onset_mixture` gives the
    law of a random threshold)."""

    # The parameters `omega0`, `zeta`, `D`, `v_b`, `tau`, `eta0` are the concrete model's
    # fields (not declared here, so that each model keeps its own field order).

    def _check_slip(self, name):
        check_positive(name, "omega0", self.omega0)
        check_positive(name, "zeta", self.zeta)
        check_nonnegative(name, "D", self.D)
        check_positive(name, "v_b", self.v_b)
        check_positive(name, "tau", self.tau, allow_none=True)
        check_choice(name, "eta0", self.eta0, ("zero", "stationary"))
        if self.eta0 == "stationary" and self.tau is None:
            raise ParameterError(
                name, "eta0", "'stationary' needs Ornstein-Uhlenbeck noise (set tau > 0)"
            )

    def _check_scales(self, name):
        # The model's scales (see `_scales`): rates up to 1e12, a noise level D/(omega0^3 x0^2)
        # between 1e-100 and 1e12, with x0 the (typical) threshold.
        check_rate(name, "omega0", self.omega0, "omega0", self.omega0)
        check_rate(name, "zeta", self.zeta, "zeta", self.zeta)
        if self.tau is not None:
            check_rate(name, "tau", 1.0 / self.tau, "1/tau", self.tau)
        check_noise(name, self.D, self.omega0, self._length_scale(), "omega0^3 x0^2")
        check_speed(name, self.v_b, self.omega0, self._length_scale(), "omega0 x0")

    def _length_scale(self) -> float:
        """The slip's length scale: the (median) threshold x0."""
        raise NotImplementedError

    def threshold_at(self, key):
        """The onset position x0 of one slip (`key`: the onset's JAX PRNG key, also used for
        the initial noise: fold in a constant before drawing from it)."""
        raise NotImplementedError

    def mean_threshold(self):
        """The mean onset position (for the Gaussian description)."""
        raise NotImplementedError

    # -- slip-phase SDE ------------------------------------------------------------------
    @property
    def state_names(self):
        return ("x", "v") if self.tau is None else ("x", "v", "eta")

    @property
    def noise_dim(self):
        return 1

    def drift(self, y):
        x, v = y[0], y[1]
        a = -(self.omega0**2) * x - self.zeta * v
        if self.tau is None:
            return jnp.stack([v, a])
        eta = y[2]
        return jnp.stack([v, a + eta, -eta / self.tau])

    def diffusion(self, y):
        g = jnp.sqrt(2.0 * self.D)
        if self.tau is None:
            return jnp.stack([jnp.zeros_like(g), g]).reshape(2, 1)
        return jnp.stack([jnp.zeros_like(g), jnp.zeros_like(g), g / self.tau]).reshape(3, 1)

    # -- crossing, stick and release -------------------------------------------------------
    @property
    def stick_level(self):
        return self.v_b

    @property
    def crossing_is_smooth(self):
        return self.tau is not None or self.D == 0.0

    def onset_state(self, key):
        x0 = jnp.asarray(self.threshold_at(key), float)
        if self.tau is None:
            return jnp.stack([x0, jnp.asarray(self.v_b, float)])
        if self.eta0 == "zero":
            eta = jnp.zeros(())
        else:
            eta = jnp.sqrt(self.D / self.tau) * jax.random.normal(key, (), dtype=jnp.float64)
        return jnp.stack([x0, jnp.asarray(self.v_b, float), eta])

    def linear_gaussian(self):
        # NumPy unless a parameter is traced (a compiled caller, a gradient): each jax.numpy
        # operation outside a trace is compiled on its first use in a process, ~20 small
        # programs (0.3-0.5 s) for these few arrays in every new process.
        x0 = self.mean_threshold()
        params = (self.omega0, self.zeta, self.D, self.v_b, self.tau, x0)
        xp = jnp if any(isinstance(p, jax.core.Tracer) for p in params) else np
        w2, z = self.omega0**2, self.zeta
        if self.tau is None:
            A = xp.array([[0.0, 1.0], [-w2, -z]])
            B = xp.array([[0.0], [xp.sqrt(2.0 * self.D)]])
            m0 = xp.array([x0, self.v_b])
            P0 = xp.zeros((2, 2))
        else:
            A = xp.array([[0.0, 1.0, 0.0], [-w2, -z, 1.0], [0.0, 0.0, -1.0 / self.tau]])
            B = xp.array([[0.0], [0.0], [xp.sqrt(2.0 * self.D) / self.tau]])
            m0 = xp.array([x0, self.v_b, 0.0])
            eta_var = 0.0 if self.eta0 == "zero" else self.D / self.tau
            P0 = xp.diag(xp.array([0.0, 0.0, eta_var]))
        d = A.shape[0]
        return LinearGaussian(
            A=A,
            b=xp.zeros(d),
            B=B,
            crossing=xp.eye(d)[1],
            position=xp.eye(d)[0],
            m0=m0,
            P0=P0,
        )


class Langevin(LangevinSlip):
    r"""Block, spring and damper with friction noise, in the frame moving with the driver.

    Slip phase (eq. 8), while $\dot x < v_b$:
    $$\dot x = v, \qquad \dot v = -\omega_0^2 x - \zeta v + \eta(t).$$
    Stick phase (eq. 9): $\dot x = v_b$ until $x$ reaches the threshold $x_0$, then the next
    slip starts from $(x, v) = (x_0, v_b)$.

    Friction noise $\eta$:

    - `tau=None`: white noise, $\langle \eta(t)\eta(s)\rangle = 2D\,\delta(t-s)$, as printed in
      the paper. The noise then enters $\dot v$ directly: $v$ is not differentiable and a
      path started at $v_b$ re-crosses $v_b$ at once (see the docs on the white-noise
      degeneracy). State `(x, v)`.
    - `tau > 0`: Ornstein-Uhlenbeck noise,
      $\langle \eta(t)\eta(s)\rangle = (D/\tau)\,e^{-|t-s|/\tau}$, i.e.
      $d\eta = -\eta/\tau\,dt + \sqrt{2D}/\tau\,dW$; white noise of intensity $D$ is the
      limit $\tau \to 0$. State `(x, v, eta)`. `eta0="zero"` (default) starts each slip
      with $\eta(0) = 0$; `eta0="stationary"` draws $\eta(0) \sim \mathcal N(0, D/\tau)$.

    **Arguments:** `omega0` ($\omega_0 > 0$), `zeta` (damping $\zeta > 0$), `D` (noise
    intensity $D \ge 0$), `v_b` (driving speed $> 0$), `x0` (static threshold $> 0$; the
    paper does not state it), `tau` (None or $> 0$), `eta0` (`"zero"` or `"stationary"`).

    **Admissible scales** (refused on construction, with the reason): the rates $\omega_0$,
    $\zeta$ and $1/\tau$ at most 1e12 per time unit (faster rates overflow the exact
    propagators: rescale time), and $D = 0$ or a noise level
    $D / (\omega_0^3 x_0^2)$ between 1e-100 (the covariances underflow) and 1e12 (the
    noise swamps the slip).
    """

    omega0: float
    zeta: float
    D: float
    v_b: float
    x0: float
    tau: float | None = None
    eta0: str = eqx.field(default="zero", static=True)

    def __check_init__(self):
        # Runs on construction only (not on the array-valued copies made for jitted code).
        self._check_slip(_NAME)
        check_positive(_NAME, "x0", self.x0)
        self._check_scales(_NAME)

    def _length_scale(self):
        return self.x0

    def threshold_at(self, key):
        return self.x0

    def mean_threshold(self):
        return self.x0

    def slip_phase(self):
        # `eta0` decides only the noise drawn at release: a "stationary" model slips as the
        # "zero" one, and runs on its compiled programs.
        if self.eta0 == "zero":
            return self
        return Langevin(self.omega0, self.zeta, self.D, self.v_b, self.x0, tau=self.tau)

    def __init__(self, omega0, zeta, D, v_b, x0, tau=None, eta0="zero"):
        # Store plain floats (ints accepted); validation in __check_init__ names the field.
        def as_float(name, value):
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                return float(value)
            from stickslip.plugin import check_real

            return check_real(_NAME, name, value, allow_none=name == "tau")

        self.omega0 = as_float("omega0", omega0)
        self.zeta = as_float("zeta", zeta)
        self.D = as_float("D", D)
        self.v_b = as_float("v_b", v_b)
        self.x0 = as_float("x0", x0)
        self.tau = None if tau is None else as_float("tau", tau)
        self.eta0 = eta0

    @classmethod
    def example(cls):
        """The public reference set: OU friction noise."""
        return cls(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
