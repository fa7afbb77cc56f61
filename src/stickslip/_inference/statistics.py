r"""Goodness-of-fit statistics: how far a sample's probability integral transform is from
uniform.

`goodness_of_fit` transforms each observable's data through the fitted model's distribution
function, $u_i = F_{\hat\theta}(x_i)$ (uniform when the model is right), and scores the
$u_i$ with a `Statistic`: larger is a worse fit. Its p-value comes from the same statistic
on simulated replicates, so any statistic is calibrated; they differ in what they see
(Anderson-Darling weighs the tails; Cramér-von Mises the body; Kolmogorov-Smirnov the
largest gap). A new statistic is one subclass:

    class Watson(stickslip.Statistic):
        name, symbol = "Watson", "U^2"

        def __call__(self, u):
            u = np.sort(u)
            n = u.size
            w2 = 1 / (12 * n) + np.sum((u - (2 * np.arange(1, n + 1) - 1) / (2 * n)) ** 2)
            return float(w2 - n * (np.mean(u) - 0.5) ** 2)

    stickslip.goodness_of_fit(result, statistic=Watson())
"""

from __future__ import annotations

import abc

import numpy as np

__all__ = ["Statistic", "AndersonDarling", "CramerVonMises", "KolmogorovSmirnov"]


class Statistic(abc.ABC):
    """A distance of a sample `u` in (0, 1) from the uniform law: a float, larger for a
    worse fit. `name` (words, for a method's description) and `symbol` (for a summary)
    are class attributes."""

    name: str = "statistic"
    symbol: str = "T"

    @abc.abstractmethod
    def __call__(self, u: np.ndarray) -> float:
        """The statistic of the sample `u` (1-D, values strictly between 0 and 1)."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def __eq__(self, other) -> bool:  # (two instances of one class with one state are one)
        return type(other) is type(self) and vars(other) == vars(self)

    def __hash__(self) -> int:
        return hash((type(self), tuple(sorted(vars(self).items()))))


class AndersonDarling(Statistic):
    r"""$A^2 = -n - \frac1n \sum_i (2i - 1) [\log u_{(i)} + \log(1 - u_{(n+1-i)})]$: the
    squared distance of the empirical distribution function from uniform, weighted by
    $1 / [u (1 - u)]$, so both tails count (the default)."""

    name, symbol = "Anderson-Darling distance", "A^2"

    def __call__(self, u) -> float:
        u = np.sort(u)
        n = u.size
        i = np.arange(1, n + 1)
        return float(-n - np.sum((2 * i - 1) * (np.log(u) + np.log1p(-u[::-1]))) / n)


class CramerVonMises(Statistic):
    r"""$W^2 = \frac{1}{12 n} + \sum_i \left(u_{(i)} - \frac{2i - 1}{2n}\right)^2$: the
    unweighted squared distance (the body of the distribution more than its tails)."""

    name, symbol = "Cramér-von Mises distance", "W^2"

    def __call__(self, u) -> float:
        u = np.sort(u)
        n = u.size
        return float(1 / (12 * n) + np.sum((u - (2 * np.arange(1, n + 1) - 1) / (2 * n)) ** 2))


class KolmogorovSmirnov(Statistic):
    r"""$D = \max_i \max(i/n - u_{(i)}, u_{(i)} - (i - 1)/n)$: the largest gap between the
    empirical distribution function and uniform."""

    name, symbol = "Kolmogorov-Smirnov distance", "D"

    def __call__(self, u) -> float:
        u = np.sort(u)
        n = u.size
        i = np.arange(1, n + 1)
        return float(max(np.max(i / n - u), np.max(u - (i - 1) / n)))


class _Saved(Statistic):
    """A statistic of a class stickslip does not define, as a saved fit keeps it: its name
    and symbol (for a summary), not its code."""

    def __init__(self, kind: str, name: str, symbol: str):
        self.kind, self.name, self.symbol = kind, name, symbol

    def __call__(self, u) -> float:
        raise TypeError(
            f"the statistic {self.kind} of a saved goodness of fit: only its name was kept; "
            "pass an instance of the class to goodness_of_fit"
        )

    def __repr__(self) -> str:
        return f"{self.kind}() (saved: name only)"


def saved_statistic(saved: dict | None) -> Statistic:
    """The statistic of a saved goodness of fit (`{kind, name, symbol}`; None: saved before
    the statistic was a choice, so the Anderson-Darling)."""
    if saved is None:
        return AndersonDarling()
    known = {c.__name__: c for c in (AndersonDarling, CramerVonMises, KolmogorovSmirnov)}
    if saved["kind"] in known:
        return known[saved["kind"]]()
    return _Saved(saved["kind"], saved["name"], saved["symbol"])


# The rows' dependence in `dependent_ks`: lags summed until the rank autocorrelation
# falls below two of its standard errors under independence (2 / sqrt(n)), at most
# MAX_LAG; a creeping slider's cycles at k = 1400 N/m, 300 um/s reach 0.6 at lag 1 and
# ~0 by lag 5.
MAX_LAG = 20


def dependence_factor(x) -> float:
    r"""How much the rows' dependence inflates the variance of an empirical distribution
    function: $1 + 2 \sum_{l \ge 1} \rho_l$, with $\rho_l$ the lag-$l$ autocorrelation of
    the indicators $1\{x_i \le \mathrm{median}\}$ (the factor of $F_n$'s variance there,
    where a KS statistic's largest gaps mostly fall; in the tails it is smaller, so the
    factor errs on the side of the level), summed over the lags until it falls below
    $2/\sqrt n$ (at most `MAX_LAG`); at least 1: a negative dependence is not taken to
    sharpen a test."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    n = x.size
    if n < 10:
        return 1.0
    r = (x <= np.median(x)).astype(float)
    r -= r.mean()
    var = float(np.dot(r, r))
    total = 0.0
    for lag in range(1, min(MAX_LAG, n // 4) + 1):
        rho = float(np.dot(r[:-lag], r[lag:])) / var
        if rho < 2.0 / np.sqrt(n):
            break
        total += rho
    return max(1.0, 1.0 + 2.0 * total)


def dependent_ks(data, sim) -> float:
    """The two-sample Kolmogorov-Smirnov p-value of `data` against `sim` (each in the
    order its rows came: successive cycles), the samples' sizes taken as their effective
    sizes, each over its `dependence_factor`. Successive cycles of a slider with memory
    are dependent (a creeping slider's stick times: lag-1 autocorrelation 0.6 on a stiff
    spring), and the plain test then rejects a true model far more often than its level
    says (at the truth, 23 % of 40 runs of 459 cycles at p < 0.05; docs/fit.md)."""
    from scipy import stats

    x, y = np.asarray(data, float), np.asarray(sim, float)
    x, y = x[np.isfinite(x)], y[np.isfinite(y)]
    if x.size == 0 or y.size == 0:
        return float("nan")
    d = float(stats.ks_2samp(x, y).statistic)
    n, m = x.size / dependence_factor(x), y.size / dependence_factor(y)
    en = n * m / (n + m)
    return float(stats.kstwo.sf(d, max(1, int(round(en)))))
