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
