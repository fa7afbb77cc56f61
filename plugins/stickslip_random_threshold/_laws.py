"""Distributions of the static threshold x0 > 0, chosen by name."""

from __future__ import annotations

import abc
import dataclasses
import functools
import math

import equinox as eqx
import numpy as np

from stickslip import ParameterError
from stickslip.plugin import build_named, check_nonnegative, check_positive, check_real, jax, jnp

_NAME = "random-threshold"


class ThresholdLaw(eqx.Module):
    """A law of the static threshold: sampling (JAX, per path), its density and quantiles
    (for quadrature), and whether it is a point mass (zero spread)."""

    @abc.abstractmethod
    def sample(self, key):
        """One draw (a JAX scalar) from a PRNG key."""

    @abc.abstractmethod
    def frozen(self):
        """The SciPy distribution (for density and quantiles)."""

    @property
    @abc.abstractmethod
    def point(self) -> float | None:
        """The value, if the law has zero spread; else None (Python-level: concrete
        parameters only)."""

    @abc.abstractmethod
    def average(self):
        """The mean threshold (JAX-traceable)."""

    def spread(self) -> tuple[float, float, float]:
        """The thresholds' `SPREAD_TAIL` and 1 - `SPREAD_TAIL` quantiles and median (without
        NumPy warnings: an extreme law gives 0 or inf here, which `check_spread` refuses)."""
        if self.point is not None:
            return (self.point,) * 3
        values = tuple(getattr(self, f.name) for f in dataclasses.fields(self))
        try:
            return _spread(type(self), values)
        except TypeError:  # (a parameter that cannot be hashed: an array)
            return _spread.__wrapped__(type(self), values)

    def quadrature(self, nodes: int):
        """Gauss-Hermite nodes in the normal score z = Phi^-1(F(x0)): `(values, weights)`,
        weights summing to 1. Smooth functions of x0 are smooth in z, so the rule converges
        fast (exact for the lognormal's log-polynomials; the moments of the other laws to
        1e-8 or better with 32 nodes), and its nodes reach the tails (|z| up to 7)."""
        if self.point is not None:
            return np.array([self.point]), np.ones(1)
        dist = self.frozen()
        z, w = np.polynomial.hermite_e.hermegauss(nodes)
        # the upper tail through the survival function, for precision
        from scipy import special  # scipy.stats and special load lazily: they take ~0.6 s

        values = np.where(z > 0, dist.isf(special.ndtr(-z)), dist.ppf(special.ndtr(z)))
        return values, w / w.sum()


class TruncatedNormal(ThresholdLaw):
    """Normal with `mean` and `sd`, truncated to x0 > 0."""

    mean: float
    sd: float

    def __check_init__(self):
        check_positive(_NAME, "threshold_params.mean", self.mean)
        check_nonnegative(_NAME, "threshold_params.sd", self.sd)

    def sample(self, key):
        # Inverse distribution function on (P(x0 <= 0), 1): exact truncation. Written without
        # branches (the parameters may be traced); with sd = 0 it returns the mean exactly.
        sd = jnp.asarray(self.sd, float)
        safe = jnp.where(sd > 0, sd, 1.0)
        lo = jnp.where(sd > 0, jax.scipy.special.ndtr(-self.mean / safe), 0.0)
        u = jax.random.uniform(key, (), dtype=jnp.float64)
        u = lo + (1.0 - lo) * jnp.clip(u, 1e-300, 1.0 - 1e-16)
        return self.mean + sd * jax.scipy.special.ndtri(u)

    def average(self):
        sd = jnp.asarray(self.sd, float)
        safe = jnp.where(sd > 0, sd, 1.0)
        a = -self.mean / safe
        lam = jax.scipy.stats.norm.pdf(a) / jnp.maximum(jax.scipy.special.ndtr(-a), 1e-300)
        return self.mean + jnp.where(sd > 0, sd * lam, 0.0)

    def frozen(self):
        from scipy import stats

        return stats.truncnorm(-self.mean / self.sd, np.inf, loc=self.mean, scale=self.sd)

    @property
    def point(self):
        return self.mean if self.sd == 0.0 else None


class LogNormal(ThresholdLaw):
    """Lognormal: `median` and `sigma` (the standard deviation of log x0)."""

    median: float
    sigma: float

    def __check_init__(self):
        check_positive(_NAME, "threshold_params.median", self.median)
        check_nonnegative(_NAME, "threshold_params.sigma", self.sigma)

    def sample(self, key):
        return self.median * jnp.exp(self.sigma * jax.random.normal(key, (), dtype=jnp.float64))

    def average(self):
        return self.median * jnp.exp(0.5 * jnp.asarray(self.sigma, float) ** 2)

    def frozen(self):
        from scipy import stats

        return stats.lognorm(self.sigma, scale=self.median)

    @property
    def point(self):
        return self.median if self.sigma == 0.0 else None


class Uniform(ThresholdLaw):
    """Uniform on [`low`, `high`], `0 < low <= high` (no mass at or below zero)."""

    low: float
    high: float

    def __check_init__(self):
        if not self.low > 0:
            raise ParameterError(
                _NAME, "threshold_params.low", "must be > 0: the law may not put mass at x0 <= 0",
                self.low,
            )  # fmt: skip
        if self.high < self.low:
            raise ParameterError(
                _NAME, "threshold_params.high", f"must be >= low = {self.low}", self.high
            )

    def sample(self, key):
        u = jax.random.uniform(key, (), dtype=jnp.float64)
        return self.low + (self.high - self.low) * u  # exactly `low` when high == low

    def average(self):
        return 0.5 * (jnp.asarray(self.low, float) + self.high)

    def frozen(self):
        from scipy import stats

        return stats.uniform(self.low, self.high - self.low)

    @property
    def point(self):
        return self.low if self.high == self.low else None


class Weibull(ThresholdLaw):
    """Weibull with `shape` k > 0 and `scale` lambda > 0 (the asperity-strength law)."""

    shape: float
    scale: float

    def __check_init__(self):
        check_positive(_NAME, "threshold_params.shape", self.shape)
        check_positive(_NAME, "threshold_params.scale", self.scale)

    def sample(self, key):
        u = jax.random.uniform(key, (), dtype=jnp.float64, minval=1e-300)
        return self.scale * (-jnp.log(u)) ** (1.0 / self.shape)

    def average(self):
        return self.scale * jnp.exp(
            jax.scipy.special.gammaln(1.0 + 1.0 / jnp.asarray(self.shape, float))
        )

    def frozen(self):
        from scipy import stats

        return stats.weibull_min(self.shape, scale=self.scale)

    @property
    def point(self):
        return None


@functools.lru_cache(maxsize=256)
def _spread(cls, values: tuple) -> tuple[float, float, float]:
    """`ThresholdLaw.spread` of the law `cls(*values)`, kept for the laws last asked about:
    a model is built, and its scales checked, several times at each point of a fit (SciPy's
    frozen law and its quantiles cost ~1 ms a call)."""
    import warnings

    dist = cls(*values).frozen()
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lo, med = (float(dist.ppf(p)) for p in (SPREAD_TAIL, 0.5))
        hi = float(dist.isf(SPREAD_TAIL))
    return lo, med, hi


# The spread of a threshold law: its quantiles at SPREAD_TAIL and 1 - SPREAD_TAIL (|z| = 7 in
# the normal score, as far as the estimator's quadrature nodes reach) must be positive, finite
# and within SPREAD_DECADES decades of the median. Wider laws draw thresholds of 0 or inf
# (lognormal sigma = 1e3: 24 % nan slip times, inf stick times). The limits allow, e.g.,
# lognormal sigma <= 9.8 and Weibull shape >= 0.4.
SPREAD_TAIL = 1e-12
SPREAD_DECADES = 30.0


def check_spread(law: ThresholdLaw) -> None:
    """Refuse a law whose thresholds would be 0, negative or non-finite with any
    appreciable probability (see `SPREAD_TAIL`), naming its parameters."""
    lo, med, hi = law.spread()
    ok = all(math.isfinite(q) and q > 0 for q in (lo, med, hi))
    if ok:
        ok = math.log10(hi) - math.log10(med) <= SPREAD_DECADES
        ok = ok and math.log10(med) - math.log10(lo) <= SPREAD_DECADES
    if not ok:
        name = next(k for k, v in THRESHOLD_LAWS.items() if isinstance(law, v))
        param = _SPREAD_PARAMETER[name]
        raise ParameterError(
            _NAME,
            f"threshold_params.{param}",
            f"makes the {name} law too wide: its {SPREAD_TAIL:g} and 1 - {SPREAD_TAIL:g} "
            f"quantiles ({lo:.3g}, {hi:.3g}) are not within {SPREAD_DECADES:g} decades of its "
            f"median ({med:.3g}), so thresholds of 0 or inf would be drawn",
            getattr(law, param),
        )


THRESHOLD_LAWS = {
    "normal": TruncatedNormal,
    "lognormal": LogNormal,
    "uniform": Uniform,
    "weibull": Weibull,
}

_SPREAD_PARAMETER = {"normal": "sd", "lognormal": "sigma", "uniform": "high", "weibull": "shape"}


def make_law(name, params) -> ThresholdLaw:
    """A threshold law from its name and parameters (a dict), with one-line errors."""
    if isinstance(name, ThresholdLaw):
        return name
    return build_named(_NAME, "threshold", THRESHOLD_LAWS, name, params,
                       params_field="threshold_params", check_value=check_real)  # fmt: skip


def describe(law: ThresholdLaw) -> str:
    name = next(k for k, v in THRESHOLD_LAWS.items() if isinstance(law, v))
    import dataclasses

    args = ", ".join(f"{f.name}={getattr(law, f.name)}" for f in dataclasses.fields(law))
    return f"{name}({args})"
