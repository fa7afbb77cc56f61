"""The Langevin slip phase with a static threshold drawn afresh at every release."""

from __future__ import annotations

import equinox as eqx
import numpy as np

from stickslip import FrictionModel, ParameterError
from stickslip._errors import check_choice, check_nonnegative, check_positive, check_real
from stickslip._jax import jax, jnp

from ._laws import ThresholdLaw, make_law

_NAME = "random-threshold"


class RandomThreshold(FrictionModel):
    r"""Langevin model with a static threshold drawn afresh at every release.

    The `langevin` slip phase (eqs. 8-9), with the threshold $x_0$ drawn for each cycle from a
    law chosen by name: asperity size and contact aging make the static friction vary from
    one stick to the next.

    The slip starts at $(x_0, v_b)$ with $x_0$ drawn for that cycle; the stick lasts until the
    position reaches the *next* cycle's threshold, $T_{st} = \max(0, (x_0' - x_{sl})/v_b)$.
    The exact estimator integrates over $x_0$ by quadrature (a mixture of exact Gaussian
    results).

    **Arguments:** `omega0`, `zeta`, `D`, `v_b`, `tau`, `eta0` as for `langevin`;
    `threshold`, the law's name: `"normal"` (`mean`, `sd`; truncated to $x_0 > 0$),
    `"lognormal"` (`median`, `sigma`), `"uniform"` (`low`, `high` with $0 < $ low), or
    `"weibull"` (`shape`, `scale`); `threshold_params`, a dict of the law's parameters.
    """

    omega0: float
    zeta: float
    D: float
    v_b: float
    threshold: ThresholdLaw
    tau: float | None = None
    eta0: str = eqx.field(default="zero", static=True)

    def __init__(
        self, omega0, zeta, D, v_b, threshold, threshold_params=None, tau=None, eta0="zero"
    ):
        self.omega0 = check_real(_NAME, "omega0", omega0)
        self.zeta = check_real(_NAME, "zeta", zeta)
        self.D = check_real(_NAME, "D", D)
        self.v_b = check_real(_NAME, "v_b", v_b)
        self.tau = check_real(_NAME, "tau", tau, allow_none=True)
        self.eta0 = eta0
        self.threshold = make_law(threshold, threshold_params)

    def __check_init__(self):
        check_positive(_NAME, "omega0", self.omega0)
        check_positive(_NAME, "zeta", self.zeta)
        check_nonnegative(_NAME, "D", self.D)
        check_positive(_NAME, "v_b", self.v_b)
        check_positive(_NAME, "tau", self.tau, allow_none=True)
        check_choice(_NAME, "eta0", self.eta0, ("zero", "stationary"))
        if self.eta0 == "stationary" and self.tau is None:
            raise ParameterError(
                _NAME, "eta0", "'stationary' needs Ornstein-Uhlenbeck noise (set tau > 0)"
            )

    def params(self):
        from ._laws import THRESHOLD_LAWS, describe

        out = {k: getattr(self, k) for k in ("omega0", "zeta", "D", "v_b", "tau", "eta0")}
        name = next(k for k, v in THRESHOLD_LAWS.items() if isinstance(self.threshold, v))
        import dataclasses

        out["threshold"] = name
        out["threshold_params"] = {
            f.name: getattr(self.threshold, f.name) for f in dataclasses.fields(self.threshold)
        }
        out["threshold_description"] = describe(self.threshold)
        return out

    @classmethod
    def parameters(cls):
        import dataclasses

        return {
            "omega0": dataclasses.MISSING, "zeta": dataclasses.MISSING, "D": dataclasses.MISSING,
            "v_b": dataclasses.MISSING, "threshold": dataclasses.MISSING,
            "threshold_params": dataclasses.MISSING, "tau": None, "eta0": "zero",
        }  # fmt: skip

    @classmethod
    def example(cls):
        return cls(1.0, 0.1, 0.4, 1.0, "lognormal", {"median": 1.0, "sigma": 0.25}, tau=0.1)

    # The slip phase is the Langevin one.
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
        z = jnp.zeros_like(g)
        if self.tau is None:
            return jnp.stack([z, g]).reshape(2, 1)
        return jnp.stack([z, z, g / self.tau]).reshape(3, 1)

    @property
    def stick_level(self):
        return self.v_b

    @property
    def crossing_is_smooth(self):
        return self.tau is not None or self.D == 0.0

    def onset_state(self, key):
        k_x0, k_eta = jax.random.split(key)
        x0 = self.threshold.sample(k_x0)
        if self.tau is None:
            return jnp.stack([jnp.asarray(x0, float), jnp.asarray(self.v_b, float)])
        if self.eta0 == "zero":
            eta = jnp.zeros(())
        else:
            eta = jnp.sqrt(self.D / self.tau) * jax.random.normal(k_eta, (), dtype=jnp.float64)
        return jnp.stack([jnp.asarray(x0, float), jnp.asarray(self.v_b, float), eta])

    def linear_gaussian(self):
        from stickslip import LinearGaussian

        w2, z = self.omega0**2, self.zeta
        x0 = self.threshold.average()
        if self.tau is None:
            A = jnp.array([[0.0, 1.0], [-w2, -z]])
            B = jnp.array([[0.0], [jnp.sqrt(2.0 * self.D)]])
            m0, P0 = jnp.array([x0, self.v_b]), jnp.zeros((2, 2))
        else:
            A = jnp.array([[0.0, 1.0, 0.0], [-w2, -z, 1.0], [0.0, 0.0, -1.0 / self.tau]])
            B = jnp.array([[0.0], [0.0], [jnp.sqrt(2.0 * self.D) / self.tau]])
            m0 = jnp.array([x0, self.v_b, 0.0])
            P0 = jnp.diag(jnp.array([0.0, 0.0, 0.0 if self.eta0 == "zero" else self.D / self.tau]))
        d = A.shape[0]
        # m0, P0: the Gaussian part at the law's mean threshold; onset_mixture gives the law.
        return LinearGaussian(
            A=A, b=jnp.zeros(d), B=B, crossing=jnp.eye(d)[1], position=jnp.eye(d)[0], m0=m0, P0=P0
        )

    def onset_mixture(self, nodes=32):
        lg = self.linear_gaussian()
        m0, P0 = np.asarray(lg.m0, float), np.asarray(lg.P0, float)
        values, weights = self.threshold.quadrature(nodes)
        m0s = np.repeat(m0[None], values.size, axis=0)
        m0s[:, 0] = values
        return m0s, np.repeat(P0[None], values.size, axis=0), weights
