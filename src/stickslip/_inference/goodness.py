r"""`goodness_of_fit`: does the fitted model reproduce the data it was fitted to?

A `FitResult` says which parameters fit best; it does not say whether the model fits at
all (exponential "slip times", which no stick-slip model makes, still get an estimate and
an interval). This module tests the fitted model against the data, one observable at a
time, with a p-value whose null distribution is simulated, the fit's own uncertainty
included.

The statistic, per observable $k$ with data $x_1, \dots, x_n$: the probability integral
transform (PIT) $u_i = F_{\hat\theta}(x_i)$ through the model's distribution function at
the estimate (the empirical one of a large reference sample simulated there), then a
distance of the $u_i$ from uniform (a `Statistic`; by default the Anderson-Darling
$A^2 = -n - \frac1n \sum_i (2i - 1) [\log u_{(i)} + \log(1 - u_{(n+1-i)})]$, which weighs
both tails). A distribution with an atom (stick times of zero length: a stick that ends
beyond the next threshold releases at once) gets the randomised PIT
$u_i = F(x_i^-) + V_i [F(x_i) - F(x_i^-)]$, $V_i$ uniform, which is exactly uniform for a
datum of the model's law, atom included; the atom's mass is compared with the model's
through it.

The null distribution: a parametric bootstrap. Each replicate is a data set of the data's
size simulated at $\hat\theta$ through the same observation rule as the fit (per-cycle
values, or, for a `Cycles`, the model's trace through the data's measurement: sampled,
noisy, extracted with the data's settings), whose statistic is taken
against the model at *its own* estimate $\hat\theta^*$, as the data's is against the model
at theirs: fitting pulls a model towards its data, so a statistic against a fitted model is
smaller than against a fixed one (Lilliefors), and a bootstrap without the refit would be
conservative. By default $\hat\theta^*$ is the fit's estimator linearised at $\hat\theta$
(one Newton step of the fit's own smoothed likelihood from $\hat\theta$, using the fit's
Hessian), plus a normal draw for the fit's simulation noise (what the fit's covariance
holds beyond the one-step estimates' scatter); the model's distribution function at
$\hat\theta^*$ is likewise linear in $\hat\theta^* - \hat\theta$, from reference samples at
$\hat\theta \pm \delta$ along each free axis (common random numbers). `refit=True` refits
every replicate with `fit` and simulates its reference at the new estimate: the exact
parametric bootstrap, about one fit's time per replicate.
$p = (1 + \#\{T^* \ge T\}) / (1 + n_{rep})$. Why this is calibrated, and where it is
conservative: docs/goodness.md.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from typing import Any

import numpy as np

from .._errors import DataError, ParameterError, check_int
from .._memory import check_memory
from ..quantities import get
from .data import to_fit_scale
from .diagnostics import FitDiagnostics
from .forward import simulate_values
from .intervals import concave
from .likelihood import KDE_BINS, density_table, log_density_at
from .params import SIM_BYTES_PER_STATE, from_fit_coords, model_kwargs, to_fit_coords
from .statistics import AndersonDarling, Statistic

ALPHA = 0.01  # below this p-value the data reject the model (the verdict's level)
# the fewest replicates whose smallest p-value, 1 / (n_rep + 1), is below ALPHA
MIN_VERDICT_REP = math.floor(1 / ALPHA)
DIFF_STEP = 0.1  # the linearisation's step (fit coordinates): the fit's own design step
# a replicate's estimate moves at most this far: past the references' reach the linearised
# distribution function is a guess (at the null, 2 steps are many standard errors)
MAX_STEP = 2 * DIFF_STEP
# the reference sample: at least this many times the data's size, so its own sampling error
# (common to the data's and the replicates' statistics) is a small part of the data's
REF_FACTOR = 20
# ... through a measurement, 5 times (a measured cycle costs ~40 per-cycle ones: at 20 times
# the reference samples alone took a minute for 3000 cycles); the reference's own error is
# common to the data's statistic and the replicates', so the calibration holds, a little
# less sharp
MEASURED_REF_FACTOR = 5
MAX_BATCH = 400_000  # simulated cycles per simulate call while making replicates (memory)
# ... through a measurement: a recorded trace holds every slip step and sample (~1 s and
# some 10 MB per 5000 cycles); batches of this size keep the memory of one near 100 MB
MAX_MEASURED_BATCH = 50_000


@dataclasses.dataclass(frozen=True)
class GoodnessOfFit:
    """The result of `goodness_of_fit`.

    - `p_values`: `{observable: p}`, each simulation-calibrated (small: the data are unlike
      the fitted model's);
    - `p_value`: all observables at once (the smallest of `p_values`, calibrated over the
      same replicates); equal to the single one when there is one;
    - `statistics`: `{observable: T}`, the data's statistic (`statistic`: which one);
    - `replicates`: `{observable: array}`, the statistic of each simulated replicate;
    - `warnings`: what was said (a rejection, a p-value floor above 0.01);
    - `method`: what was done, in words.
    """

    p_values: dict[str, float]
    p_value: float
    statistics: dict[str, float]
    replicates: dict[str, np.ndarray] = dataclasses.field(repr=False)
    warnings: list[str]
    method: str
    n_rep: int
    data: dict[str, np.ndarray] = dataclasses.field(repr=False)
    reference: dict[str, np.ndarray] = dataclasses.field(repr=False)
    statistic: Statistic = dataclasses.field(default_factory=AndersonDarling)

    @property
    def rejected(self) -> bool:
        """True when some observable's p-value is below 0.01."""
        return any(p < ALPHA for p in self.p_values.values())

    def summary(self) -> str:
        lines = [self.method]
        for k, p in self.p_values.items():
            lines.append(f"  {k}: {self.statistic.symbol} = {self.statistics[k]:.3g}, p = {p:.3g}")
        if len(self.p_values) > 1:
            lines.append(f"  all at once: p = {self.p_value:.3g}")
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def plot(self, path=None):
        """Data against the fitted model, per observable: histograms (top) and
        distribution functions (bottom) of the data and of the model at the estimate, the
        p-value in the title; durations on a log axis, their zero-length share in the
        legend. Returns the figure; saves it to `path`."""
        import matplotlib

        if path is not None:
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        kinds = list(self.data)
        fig, axes = plt.subplots(2, len(kinds), figsize=(3.8 * len(kinds), 6.0), squeeze=False)
        for j, k in enumerate(kinds):
            x, ref = self.data[k], self.reference[k]
            log = get(k).positive  # a positive duration: on a log axis
            xp, rp = (x[x > 0], ref[ref > 0]) if log else (x, ref)
            zeros = ""
            if log and (x.size > xp.size or ref.size > rp.size):
                zeros = (
                    f"; zero: data {1 - xp.size / x.size:.0%}, model {1 - rp.size / ref.size:.0%}"
                )
            lo, hi = np.percentile(np.r_[xp, rp], [0.05, 99.95])
            edges = (
                np.geomspace(lo, hi, 41) if log and lo > 0 else np.linspace(lo, hi, 41)
            )  # fmt: skip
            top, bottom = axes[0, j], axes[1, j]
            top.hist(xp, edges, density=True, alpha=0.5, label=f"data ({x.size})")
            top.hist(rp, edges, density=True, histtype="step", lw=1.5, label="fitted model")
            top.set_title(f"{k}: p = {self.p_values[k]:.3g}", fontsize=9)
            top.legend(fontsize=7)
            bottom.step(np.sort(x), np.arange(1, x.size + 1) / x.size, where="post",
                        label="data")  # fmt: skip
            bottom.step(np.sort(ref), np.arange(1, ref.size + 1) / ref.size, where="post",
                        label=f"fitted model{zeros}")  # fmt: skip
            bottom.set_xlabel(k)
            bottom.set_ylabel("fraction below")
            bottom.legend(fontsize=7)
            if log and lo > 0:
                top.set_xscale("log")
                bottom.set_xscale("log")
                bottom.set_xlim(lo, hi)
        fig.tight_layout()
        if path is not None:
            fig.savefig(path, dpi=110)
            plt.close(fig)
        return fig


def goodness_of_fit(
    result,
    *,
    n_rep: int = 200,
    seed: int = 1,
    refit: bool = False,
    n_ref: int | None = None,
    statistic: Statistic | None = None,
) -> GoodnessOfFit:
    r"""Test a fitted model against its data: a simulation-calibrated p-value per observable.

    **Arguments:**

    - `result`: a `FitResult` (from `fit`).
    - `n_rep`: simulated replicates of the data set (p-values are multiples of
      $1/(n_{rep} + 1)$: 100 or more for a verdict at 0.01).
    - `seed`: seed of the replicates and the reference samples (take one other than the
      fit's and the data's).
    - `refit`: refit every replicate with `fit` (the exact parametric bootstrap, about one
      fit's time each) instead of the fit's estimator linearised at the estimate.
    - `n_ref`: cycles of the reference samples that stand for the model's distribution
      (default: the larger of the fit's `n_sim` and 20 times the data's size; 5 times for
      a fit through a measurement, whose cycles cost ~40 times more).
    - `statistic`: the distance from uniform of the data's probability integral transform
      (a `Statistic`: `AndersonDarling()`, the default, `CramerVonMises()`,
      `KolmogorovSmirnov()` or a subclass of your own).

    Warns ("the data reject the model: ...") when a p-value is below 0.01.

    **Returns:** a `GoodnessOfFit`.
    """
    from .result import FitResult

    owner = "goodness_of_fit"
    if not isinstance(result, FitResult):
        raise ParameterError(owner, "result", "must be a FitResult (from fit)", type(result))
    n_rep = check_int(owner, "n_rep", n_rep, minimum=1)
    seed = check_int(owner, "seed", seed, minimum=0)
    if seed >= 2**63:
        raise ParameterError(owner, "seed", "must be < 2**63", seed)
    if not isinstance(refit, (bool, np.bool_)):
        raise ParameterError(owner, "refit", "must be True or False", refit)
    statistic = AndersonDarling() if statistic is None else statistic
    if not isinstance(statistic, Statistic):
        raise ParameterError(
            owner, "statistic", "must be a Statistic (AndersonDarling(), CramerVonMises(), "
            "KolmogorovSmirnov() or a subclass)", type(statistic),
        )  # fmt: skip
    d = result.diagnostics
    if d.runs:
        raise ParameterError(
            owner, "result", "is a fit of several runs: its check is each run's KS p-values "
            "(fit(..., check=True): diagnostics.runs)",
        )  # fmt: skip
    data = {k: np.asarray(v, float) for k, v in result.data.items()}
    kinds = list(data)
    n = next(iter(data.values())).size
    factor = REF_FACTOR if d.measurement is None else MEASURED_REF_FACTOR
    n_ref = max(d.n_sim, factor * n) if n_ref is None else n_ref
    n_ref = check_int(owner, "n_ref", n_ref, minimum=1000)
    setting = Setting.of(result)
    _check_memory(setting, n, n_rep, n_ref)
    rng = np.random.default_rng([seed, 0])
    ref_seed = int(rng.integers(2**62))
    said: list[str] = []

    # the reference samples: at the estimate, and one step either side along each free axis
    reference = {k: _sorted(v) for k, v in setting.simulate(setting.u_hat, n_ref, ref_seed).items()}
    shifted = None if refit else setting.shifted_references(n_ref, ref_seed)
    observed = {k: statistic(_pit(data[k], [reference[k]], [1.0], rng)) for k in kinds}

    reps = simulate_replicates(setting, n, n_rep, int(rng.integers(2**62)))
    if refit:
        stats = _refitted_statistics(setting, reps, n_ref, ref_seed, statistic, rng)
    else:
        stats = _linearised_statistics(setting, reps, data, reference, shifted, statistic, rng,
                                       said)  # fmt: skip

    p_values = {k: float((1 + np.sum(stats[k] >= observed[k])) / (1 + n_rep)) for k in kinds}
    p_value = _joint_p(observed, stats, p_values) if len(kinds) > 1 else p_values[kinds[0]]
    how = (
        "each replicate refitted (exact parametric bootstrap)"
        if refit
        else "the fit's estimator linearised at the estimate, plus its simulation noise"
    )
    method = (
        f"{statistic.name} of the randomised probability integral transform through "
        f"the fitted model ({n_ref} reference cycles), against {n_rep} parametric-bootstrap "
        f"replicates of {n} cycles simulated at the estimate ({how})"
    )
    if not refit and d.warnings:
        said.append(
            "the fit warned (see its diagnostics.warnings): the linearised bootstrap assumes "
            "a regular maximum inside the box, so these p-values are rough; refit=True is exact"
        )
    if 1 / (n_rep + 1) >= ALPHA:  # the smallest p-value, 1 / (n_rep + 1), is not below ALPHA
        said.append(
            f"with n_rep = {n_rep} no p-value is below {1 / (n_rep + 1):.3g}: take n_rep >= "
            f"{MIN_VERDICT_REP} for a verdict at {ALPHA}"
        )
    low = {k: p for k, p in p_values.items() if p < ALPHA}
    if low:
        shown = ", ".join(f"{k} p = {p:.3g}" for k, p in low.items())
        said.append(
            f"the data reject the model: {shown} < {ALPHA} (the data's distribution is unlike "
            f"the fitted {type(result.model).__name__}'s; see GoodnessOfFit.plot)"
        )
    for text in said:
        warnings.warn(f"goodness_of_fit: {text}", stacklevel=2)
    return GoodnessOfFit(
        p_values=p_values, p_value=float(p_value), statistics=observed, replicates=stats,
        warnings=said, method=method, n_rep=n_rep, data=data, reference=reference,
        statistic=statistic,
    )  # fmt: skip


def _refitted_statistics(setting, reps, n_ref, ref_seed, statistic, rng) -> dict:
    """Each replicate's statistic against the model at its own refitted estimate (the exact
    parametric bootstrap)."""
    kinds = list(setting.kinds)
    stats = {k: np.empty(len(reps)) for k in kinds}
    for r, rep in enumerate(reps):
        u_star = setting.refit(rep, seed=int(rng.integers(2**62)))
        ref = setting.simulate(u_star, n_ref, ref_seed)
        for k in kinds:
            stats[k][r] = statistic(_pit(rep[k], [_sorted(ref[k])], [1.0], rng))
    return stats


def _linearised_statistics(setting, reps, data, reference, shifted, statistic, rng,
                           said) -> dict:  # fmt: skip
    """Each replicate's statistic against the model at its linearised estimate (one Newton
    step of the fit's likelihood, plus the fit's simulation noise), the model's distribution
    function linear in the step (the references either side of the estimate); what limits
    it is said in `said`."""
    kinds, n_rep = list(data), len(reps)
    stats = {k: np.empty(n_rep) for k in kinds}
    newton = setting.newton()
    p = len(setting.names)
    if newton is None:
        said.append(
            "the fit's log-likelihood has no finite curvature at the estimate: replicates "
            "are compared with the model at the estimate itself, without their own fit, so "
            "these p-values are conservative (too large); refit=True is exact"
        )
        steps = np.zeros((n_rep, p))
    else:
        tables = setting.gradient_tables(shifted, reps, data)
        steps = np.array([setting.one_step(rep, tables, newton) for rep in reps])
    if concave(setting.hessian):
        noise = setting.simulation_noise(steps)
    else:
        # the fit's covariance is then a regularised inverse (sds of 1e5-1e10): as the
        # simulation noise it threw every replicate to MAX_STEP, and every p-value to 1
        noise = np.zeros((p, p))
        said.append(
            "the fit's log-likelihood is not concave at the estimate: the replicates "
            "leave out the fit's own simulation noise (its covariance is not usable), "
            "so these p-values are rough, somewhat small"
        )
    steps = steps + rng.multivariate_normal(np.zeros(p), noise, size=n_rep)
    # sorted once, not per replicate (a quarter of the time at 3000 cycles, 2 free)
    ordered = [({k: _sorted(plus[k]) for k in kinds}, {k: _sorted(minus[k]) for k in kinds},
                step) for (plus, minus), step in shifted]  # fmt: skip
    for r, rep in enumerate(reps):
        du = np.clip(steps[r], -MAX_STEP, MAX_STEP)
        for k in kinds:
            samples, weights = [reference[k]], [1.0]
            for j, (plus, minus, step) in enumerate(ordered):
                c = du[j] / step
                samples += [plus[k], minus[k]]
                weights += [c, -c]
            stats[k][r] = statistic(_pit(rep[k], samples, weights, rng))
    return stats


# -- pieces -----------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Setting:
    """What a replicate needs from the fit: the model at fit coordinates `u` (log for
    positive parameters), the simulation settings and observation rule, the estimator's
    Hessian, bandwidths and covariance."""

    Model: Any
    params: dict
    names: list
    scales: dict
    u_hat: np.ndarray
    hessian: np.ndarray
    covariance: np.ndarray
    n_sim: int
    n_data: int
    dt: float | None
    t_max: float | None
    observe: Any  # the data's `Measurement` (None: per-cycle values)
    bandwidth: Any  # per column (a list of those, per run, for a joint fit)
    kinds: list
    fit_seed: int
    diagnostics: FitDiagnostics

    @classmethod
    def of(cls, result) -> Setting:
        d = result.diagnostics
        names = list(result.estimate)
        scales = dict(d.scales)
        u_hat = np.array([to_fit_coords(scales[k], result.estimate[k]) for k in names])
        return cls(
            Model=type(result.model), params=model_kwargs(result.model), names=names,
            scales=scales, u_hat=u_hat, hessian=np.atleast_2d(np.asarray(d.hessian, float)),
            covariance=np.atleast_2d(np.asarray(d.covariance, float)), n_sim=int(d.n_sim),
            n_data=next(iter(result.data.values())).size, dt=_float(d.dt),
            t_max=_float(d.t_max), observe=d.measurement,
            bandwidth=_bandwidths(d.bandwidth),
            kinds=list(result.data), fit_seed=int(d.seed), diagnostics=d,
        )  # fmt: skip

    def model(self, u):
        kwargs = dict(self.params)
        for k, x in zip(self.names, u, strict=True):
            head, _, entry = k.partition(".")  # "threshold_params.sd": an entry of a dict
            value = from_fit_coords(self.scales[k], x)
            kwargs[head] = {**kwargs[head], entry: value} if entry else value
        return self.Model(**kwargs)

    def simulate(self, u, n, seed) -> dict[str, np.ndarray]:
        sim = simulate_values(self.model(u), n, self.dt, self.t_max, seed, self.observe)
        return {k: np.asarray(sim[k], float) for k in self.kinds}

    def shifted_references(self, n_ref, seed):
        """Reference samples one step either side of the estimate along each axis (one
        side and the estimate where the model refuses the other), with the step between."""
        out = []
        for j in range(len(self.names)):
            e = np.zeros(len(self.names))
            e[j] = DIFF_STEP
            sides = []
            for u in (self.u_hat + e, self.u_hat - e):
                try:
                    self.model(u)
                    sides.append(u)
                except (ValueError, ArithmeticError):  # outside the model's range
                    sides.append(self.u_hat)
            if sides[0] is sides[1]:
                raise ParameterError(
                    "goodness_of_fit", "result", f"has a model that refuses {self.names[j]} "
                    f"within {DIFF_STEP} of its estimate on either side",
                )  # fmt: skip
            step = float(sides[0][j] - sides[1][j])
            out.append(([self.simulate(u, n_ref, seed) for u in sides], step))
        return out

    def newton(self) -> np.ndarray | None:
        """$(-H)^{-1}$, the one-step estimator's matrix, from the fit's Hessian; `None` when
        the fit's surface has no finite curvature to use."""
        info = -0.5 * (self.hessian + self.hessian.T)
        if not np.all(np.isfinite(info)):
            return None
        w, v = np.linalg.eigh(info)
        if np.min(w) <= 0:
            # a surface that is not concave at the estimate (the fit warned): its flat
            # directions get the curvature of the steepest one, or of the fit's covariance
            diag = np.diag(self.covariance)
            if np.max(w) > 0:
                top = float(np.max(w))
            elif np.all(np.isfinite(diag)) and np.max(diag) > 0:
                top = 1.0 / float(np.max(diag))
            else:
                return None
            w = np.where(w > 0, w, top)
        return (v / w) @ v.T

    def gradient_tables(self, shifted, reps, data) -> list:
        """The shifted references' smoothed log-densities (`likelihood.density_table`),
        tabulated once for all replicates: on a grid over every replicate's values and the
        data's (8 bandwidths beyond), its bins no wider than those `_log_density` takes for
        the narrowest replicate alone, the defensive normal the data's. Per replicate and
        axis this replaced two binned kernel estimates of the reference sample (the
        goodness check's largest cost, 60 % of it at 3000 cycles, 2 free) by a look-up."""
        out = []
        for (plus, minus), step in shifted:
            tables = {}
            for k in self.kinds:
                h = self.bandwidth[k]
                ys = [to_fit_scale(k, r[k]) for r in reps] + [to_fit_scale(k, data[k])]
                lo = min(float(y.min()) for y in ys) - 8 * h
                hi = max(float(y.max()) for y in ys) + 8 * h
                narrowest = min(float(y.max() - y.min()) for y in ys) + 16 * h
                bins = int(math.ceil(KDE_BINS * (hi - lo) / narrowest))
                y0 = ys[-1]
                mu, sd = float(np.mean(y0)), 3.0 * max(float(np.std(y0)), h)
                tables[k] = tuple(density_table(k, side[k], h, lo, hi, bins, mu, sd)
                                  for side in (plus, minus))  # fmt: skip
            out.append((tables, step))
        return out

    def one_step(self, rep, tables, newton) -> np.ndarray:
        """$\\hat\\theta^* - \\hat\\theta$ for replicate data `rep`: one Newton step of the
        fit's smoothed log-likelihood from the estimate, $(-H)^{-1} g$, its gradient $g$ by
        central differences over the shifted references (the fit's bandwidths; their
        densities tabulated by `gradient_tables`)."""
        g = np.zeros(len(self.names))
        for j, (table, step) in enumerate(tables):
            for k in self.kinds:
                plus, minus = table[k]
                up = np.sum(log_density_at(k, rep[k], plus))
                down = np.sum(log_density_at(k, rep[k], minus))
                g[j] += (up - down) / step
        return newton @ g

    def simulation_noise(self, steps) -> np.ndarray:
        """The fit's own simulation noise in its estimate: what its covariance holds beyond
        the scatter of the replicates' one-step estimates `steps` (the sampling part), so
        that the replicates' estimates scatter as the fit says its own does (zero where
        the fit's covariance is not finite)."""
        cov = 0.5 * (self.covariance + self.covariance.T)
        if not np.all(np.isfinite(cov)):
            return np.zeros_like(cov)
        if len(steps) > 1:
            cov = cov - np.atleast_2d(np.cov(steps, rowvar=False))
        w, v = np.linalg.eigh(cov)
        return (v * np.clip(w, 0.0, None)) @ v.T

    def refit(self, rep, seed) -> np.ndarray:
        """The replicate refitted as the data were; returns its estimate (fit coordinates)."""
        from .estimator import simulated_mle

        free = self._box()
        fixed = {k: v for k, v in self.params.items() if k not in self.names}
        for k in self.names:  # a dict parameter keeps its other entries in fixed
            head, _, entry = k.partition(".")
            if entry:
                fixed[head] = {j: v for j, v in fixed[head].items() if f"{head}.{j}" not in free}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = simulated_mle(
                self.Model, rep, free, fixed, seed=seed % 2**63, n_sim=self.n_sim, dt=self.dt,
                t_max=None if self.observe is not None else self.t_max,
                measurement=self.observe,
            )  # fmt: skip
        return np.array([to_fit_coords(self.scales[k], r.estimate[k]) for k in self.names])

    def _box(self) -> dict:
        """A search box for a refit, about the estimate the replicates were simulated at
        (not the data's box, `diagnostics.box`, which may be far wider): 8 standard errors
        either side of the estimate, at least 0.5, in fit coordinates; a linear-scale
        parameter keeps a box through 0 so that `fit` keeps its scale."""
        se = np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))
        out = {}
        for j, k in enumerate(self.names):
            w = max(8.0 * se[j], 0.5)
            if self.scales[k] == "log":
                out[k] = (math.exp(self.u_hat[j] - w), math.exp(self.u_hat[j] + w))
            else:
                out[k] = (min(self.u_hat[j] - w, 0.0), max(self.u_hat[j] + w, 0.0) + 1e-12)
        return out


def _check_memory(setting: Setting, n: int, n_rep: int, n_ref: int) -> None:
    """The replicates (8 B a value, a column each, held at once) and one reference
    simulation (the fit's 160 B a cycle and state component) against the fit's limit."""
    dim = setting.model(setting.u_hat).state_dim
    for name, value, need in (
        ("n_rep", n_rep, 8 * n * n_rep * len(setting.kinds)),
        ("n_ref", n_ref, SIM_BYTES_PER_STATE * dim * n_ref),
    ):
        check_memory("goodness_of_fit", f"parameter '{name}'", need, f"take fewer (got {value})")


def simulate_replicates(setting: Setting, n: int, n_rep: int, seed: int) -> list[dict]:
    """`n_rep` data sets of `n` cycles each at the estimate, through the fit's observation
    rule: consecutive cycles of batches of simulated ones (a trace's visible cycles are
    fewer than those simulated; batches grow until there are enough)."""
    need = n * n_rep
    got: dict[str, list] = {k: [] for k in setting.kinds}
    have, batch, ratio = 0, 0, 1.0
    cap = MAX_BATCH if setting.observe is None else MAX_MEASURED_BATCH
    while have < need:
        ask = int(min(cap, max(1000, math.ceil((need - have) * ratio * 1.1) + 100)))
        try:
            sim = setting.simulate(setting.u_hat, ask, seed + batch)
        except DataError:  # the measured trace shows no cycles
            sim = {k: np.array([]) for k in setting.kinds}
        size = next(iter(sim.values())).size
        if size == 0 and batch >= 3:
            raise ParameterError(
                "goodness_of_fit", "result", "has a model whose simulation shows no cycles "
                "through the fit's observation rule",
            )  # fmt: skip
        ratio = max(ratio, ask / max(size, 1))
        for k in setting.kinds:
            got[k].append(sim[k])
        have += size
        batch += 1
    cols = {k: np.concatenate(v)[:need] for k, v in got.items()}
    return [{k: v[r * n : (r + 1) * n] for k, v in cols.items()} for r in range(n_rep)]


def _bandwidths(given):
    """A fit's bandwidths per column (a list of them, one per run, for a joint fit)."""
    return dict(given) if hasattr(given, "items") else [dict(b) for b in given]


def _float(x) -> float | None:
    return None if x is None else float(x)


def _sorted(x) -> np.ndarray:
    x = np.asarray(x, float)
    return np.sort(x[np.isfinite(x)])


def _pit(x, samples, weights, rng) -> np.ndarray:
    r"""The randomised probability integral transform of `x` through the distribution
    function $F = \sum_s w_s \hat F_s$ (empirical ones of the sorted `samples`; the weights
    sum to 1, a linearisation in the parameters): $F(x^-) + V [F(x) - F(x^-)]$, $V$
    uniform, so that an atom (zero-length sticks) is spread over its mass. Clipped to
    $[1/2m, 1 - 1/2m]$ ($m$ reference cycles): a datum beyond every reference value would
    otherwise give $\log 0$."""
    below = np.zeros(x.size)
    upto = np.zeros(x.size)
    for s, w in zip(samples, weights, strict=True):
        below += w * np.searchsorted(s, x, "left") / s.size
        upto += w * np.searchsorted(s, x, "right") / s.size
    u = below + rng.random(x.size) * (upto - below)
    m = samples[0].size
    return np.clip(u, 0.5 / m, 1 - 0.5 / m)


def _joint_p(observed, stats, p_values) -> float:
    """All observables at once: the data's smallest p-value against the replicates'
    smallest (each replicate's p-values taken among the other replicates)."""
    n_rep = next(iter(stats.values())).size
    smallest = np.ones(n_rep)
    for T in stats.values():
        rank = np.sum(T[None, :] >= T[:, None], axis=1) - 1  # others at least as large
        smallest = np.minimum(smallest, (1 + rank) / n_rep)
    return float((1 + np.sum(smallest <= min(p_values.values()))) / (1 + n_rep))
