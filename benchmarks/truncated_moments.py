"""An experiment: the random threshold's normal law in its truncated moments. The
plugin's `"normal"` law is an untruncated normal's `mean` and `sd`, truncated to x0 > 0;
where the mean is a couple of sds above zero, a lower mean with a larger sd draws nearly
the same thresholds, and a fit's surface in those coordinates is a curved ridge. This law,
`"normal-moments"`, is the same family parametrised by the truncated law's own `mean` and
coefficient of variation `cv` = sd / mean (0 <= cv < 1: every normal truncated to x0 > 0
has it, so that a box of `cv` is one rectangle), registered in the plugin's public
`THRESHOLD_LAWS` as a user would. Importing this module registers it.

    python benchmarks/fit_independent.py --case random --release stick --coords moments ...
"""

from __future__ import annotations

import math

import numpy as np
import stickslip_random_threshold as rt

from stickslip import ParameterError
from stickslip.plugin import jax, jnp

_BISECTIONS = 200


def _ratio(alpha):
    """mean / sd of a unit normal's part above `alpha` (shifted to start at 0), as a
    function of the truncation point alpha = -mu / sigma: falls from inf to 1."""
    lam = jnp.exp(jax.scipy.stats.norm.logpdf(alpha) - jax.scipy.special.log_ndtr(-alpha))
    return (lam - alpha) / jnp.sqrt(jnp.maximum(1.0 + alpha * lam - lam**2, 1e-300)), lam


def underlying(mean, sd):
    """The untruncated (mu, sigma) of the normal whose part above 0 has this mean and sd
    (JAX-traceable: a bisection on the truncation point over [-40, 40])."""
    mean = jnp.asarray(mean, float)
    sd = jnp.asarray(sd, float)
    r = mean / jnp.where(sd > 0, sd, 1.0)

    def step(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        above = _ratio(mid)[0] > r  # the ratio falls with alpha: the root is above mid
        return jnp.where(above, mid, lo), jnp.where(above, hi, mid)

    lo, hi = jax.lax.fori_loop(0, _BISECTIONS, step, (jnp.asarray(-40.0), jnp.asarray(40.0)))
    alpha = 0.5 * (lo + hi)
    _, lam = _ratio(alpha)
    sigma = sd / jnp.sqrt(jnp.maximum(1.0 + alpha * lam - lam**2, 1e-300))
    mu = -alpha * sigma
    return jnp.where(sd > 0, mu, mean), jnp.where(sd > 0, sigma, 0.0)


class TruncatedNormalMoments(rt.ThresholdLaw):
    """Normal truncated to x0 > 0, by its own `mean` and `cv` = sd / mean (0 <= cv < 1)."""

    mean: float
    cv: float

    def __check_init__(self):
        if not (isinstance(self.mean, jax.Array) or isinstance(self.cv, jax.Array)):
            if not self.mean > 0:
                raise ParameterError("random-threshold", "threshold_params.mean", "must be > 0",
                                     self.mean)  # fmt: skip
            if not 0 <= self.cv < 1:
                raise ParameterError(
                    "random-threshold", "threshold_params.cv", "must be in [0, 1): a normal "
                    "truncated to x0 > 0 has sd < mean", self.cv,
                )  # fmt: skip

    @property
    def sd(self):
        return self.mean * self.cv

    def sample(self, key):
        # inverse distribution function on (P(x0 <= 0), 1), as the plugin's normal law
        # (whose own check refuses the traced, possibly negative, underlying mean)
        mu, sigma = underlying(self.mean, self.sd)
        safe = jnp.where(sigma > 0, sigma, 1.0)
        lo = jnp.where(sigma > 0, jax.scipy.special.ndtr(-mu / safe), 0.0)
        u = jax.random.uniform(key, (), dtype=jnp.float64)
        u = lo + (1.0 - lo) * jnp.clip(u, 1e-300, 1.0 - 1e-16)
        return mu + sigma * jax.scipy.special.ndtri(u)

    def average(self):
        return jnp.asarray(self.mean, float)

    def frozen(self):
        from scipy import stats

        mu, sigma = (float(v) for v in underlying(self.mean, self.sd))
        return stats.truncnorm(-mu / sigma, np.inf, loc=mu, scale=sigma)

    @property
    def point(self):
        return self.mean if self.cv == 0.0 else None


rt.THRESHOLD_LAWS.setdefault("normal-moments", TruncatedNormalMoments)


def moments(mu: float, sigma: float) -> tuple[float, float]:
    """The mean and sd of N(mu, sigma) truncated to x > 0 (closed form)."""
    from scipy import stats

    a = -mu / sigma
    lam = stats.norm.pdf(a) / stats.norm.sf(a)
    return mu + sigma * lam, sigma * math.sqrt(1 + a * lam - lam**2)
