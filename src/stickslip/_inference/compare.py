r"""`compare_fits`: of several fitted models, the simplest one the data do not reject.

The criterion has to be valid for the likelihood `fit` maximises, which is not a plain
likelihood: a kernel-smoothed, simulated one (its Bartlett identity fails: the sandwich
$H^{-1} J H^{-1}$ is not $H^{-1}$), a composite one when there are several columns (the
columns of one cycle are dependent), noisy (every value carries the simulation's noise)
and, for the nestings that matter here, tested on the boundary of the richer model (a
normal threshold of $sd = 0$ is the fixed threshold). Neither $\chi^2_q$ nor AIC holds for
it. So the null distribution is not taken from asymptotics but simulated:

- **Order**: candidates by their number of free parameters, fewest first (ties: the larger
  log-likelihood first).
- **Test** of a candidate $A$ against each richer one $B$: the statistic is the likelihood
  ratio $T = 2[\tilde\ell_B(y) - \tilde\ell_A(y)]$, where $\tilde\ell_M(y)$ is the maximum
  near $M$'s estimate of $M$'s own smoothed log-likelihood (its fit's bandwidths,
  observation rule, `dt`, `t_max`, `n_sim` and seed: `likelihood._per_cycle`): evaluated
  at the fit's own design (`surface.local_surface`: the centre, $\pm 1$ and $\pm 2$
  steps along each axis, $\pm 1$ along each diagonal pair, clipped at the box), the fit's
  polynomial through them (quadratic, a cubic term per axis), its largest value over the
  region the design spans (`_polynomial_max`, `_region`). Its null distribution
  is a parametric bootstrap: `n_boot` data sets of the data's size simulated from $A$ at
  its estimate through the fit's observation rule (`goodness.simulate_replicates`), each scored by
  the *same* $T$: the same design points and the same simulated samples;
  $p = (1 + \#\{T^* \ge T\}) / (1 + n_{boot})$. With several richer candidates, the
  smallest $p$ times their number (Bonferroni).
- **Nesting**: where $B$'s family holds $A$'s fitted model (the same class with $A$'s
  values inside $B$'s box, or a class that says how it reproduces $A$'s, `embed`: a
  normal threshold of sd 0 is the fixed threshold), $\tilde\ell_B \ge \tilde\ell_A$ in
  truth; a simulated $T < 0$ is the fits' or the simulations' error, and $T$ is taken as
  $\max(T, 0)$, for the data and every replicate alike (the test stays calibrated: the
  same statistic on both); a data $T$ below `-NESTED_SLACK` is said in a warning.
- **Choice**: the first candidate, in that order, that no test rejects at `alpha`.

Why this is valid. A parametric bootstrap calibrates *any* statistic computed the same way
on the data and on the replicates, so none of the asymptotic conditions the smoothed,
composite, boundary case breaks is needed: the boundary ($\bar\chi^2$), the composite
likelihood's weighted $\chi^2$ and the smoothing bias are all inside the simulated null
law. The simulation's own noise is conditioned on rather than averaged over: the design's
simulated samples are drawn once and used for the data and every replicate, so under the
null the data's $T$ and the replicates' $T^*$ share one law *given those samples*, and the
test keeps its level whatever the noise (noise can only cost power). It is then repeated
with each fit's second seed (`diagnostics.design.seeds`, independent samples), and
a candidate is rejected only when both reject: the larger $p$ counts, which keeps the
level, and a warning says when the two disagree (the choice then hangs on the simulation:
raise `n_sim`). A polynomial's maximum rather than the largest design value, because the
design is centred on the data's own estimate: the data's maximum sits near a design point
while a replicate's falls between points, which the largest design value underrates (the
test would reject too often); a polynomial's maximum does not depend on where in the
design it falls.

Why the fit's design. The fit has simulated it already, at both seeds, and keeps those
cycles where they are small (`estimator.KEEP_SAMPLES_BYTES`: every fit through a
measurement): a comparison then costs its replicates and the scoring alone (on the measured
slider ~70 s, where a design of its own, 132 simulations through the measurement, took
~160 s more). Where the fit did not keep them (per-cycle values at 10^5 cycles a point)
they are simulated again: the same cycles, a function of the point and the seed. The
fit's steps are where its polynomial is a good local model of the surface (each step
falls by at most `surface.MAX_STEP_DROP`): the replicates' maxima, within a few standard
errors of the estimate, lie inside its $\pm 2$ steps. A refit of every replicate would
cost `2 n_boot` fits.

Several runs (fits of one slider to several runs, `joint`): the log-likelihood is the sum
of the runs', so is $T$; a replicate is a set of runs, each drawn from the null's fitted
slider on that run's spring and speed, through that run's measurement, at its number of
cycles (run 0 from the test's stream, the others from streams of their own), scored
against each run's design cycles as the fit kept them. $T$ is not clipped at 0 there
(nesting is not checked in SI values).

Fits in other units (a creeping slider in SI, a slider in its reference `Slider`'s):
the richer candidate scores the sets converted into its units, and each set's statistic
is that of its values in SI (`si_shift`: $-\log u$ for each value a density scores).

What it assumes: the replicates' cycles are dependent as the data's are (through a
measurement a replicate is a stretch of the model's own successive cycles: a random
threshold couples neighbouring rows in both; per-cycle values given as a dict are
simulated as independent cycles, so rows of a dict should be independent too); the
candidates are fitted to the same data with the same measurement (refused otherwise); each
fit's estimate and standard errors are sound (the fit
warns when not). A test against a non-nested richer candidate is valid the same way (the
bootstrap draws from the simpler one), so white against Ornstein-Uhlenbeck noise, or with
against without a velocity-dependent friction, need no nesting. The chosen model can still
be wrong: its goodness of fit (`FitResult.p_values`) says whether it reproduces the data.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from typing import Any

import numpy as np

from .._errors import DataError, ParameterError, check_int
from .data import LOG_KINDS
from .forward import simulate_values
from .goodness import ALPHA as GOODNESS_ALPHA
from .goodness import Setting, simulate_replicates
from .likelihood import sample, scored_samples
from .params import from_fit_coords, model_kwargs
from .surface import polynomial_terms

# The level of each choice: a simpler model is kept unless p < ALPHA. The issue asks that a
# model which holds be kept in >= 90 % of data sets: at 0.05 a calibrated test keeps it in
# 95 % on average, so 20 sets fall below 90 % (3 rejections) 7.5 % of the time; at 0.01
# 0.1 % of the time. goodness_of_fit's verdict level is 0.01 too. Against a threshold
# spread of 0.2 of its mean the likelihood ratio is ~80 (150 cycles): no power is lost.
ALPHA = 0.01
GRID_BUDGET = 4096  # points of the grid a fitted polynomial is maximised over
# A nested pair's 2 dlogL below -NESTED_SLACK is worth a warning (a richer model holds the
# nested one's fit: its own maximum cannot lie lower but for its fit's or its simulation's
# error); the statistic is taken as at least 0 whatever it is.
NESTED_SLACK = 2.0


@dataclasses.dataclass(frozen=True)
class Comparison:
    """The result of `compare_fits`.

    - `chosen`: the `FitResult` of the simplest candidate the data do not reject;
    - `table`: one dict per candidate, ranked (the chosen first, then the richer ones it
      was preferred to, then the rejected ones): `rank`, `name`, `model`, `free` (the
      names), `n_free`, `log_likelihood` (the fit's), `statistic` ($2\\Delta\\ell$ of the
      test that decided the row: for a rejected candidate, against the candidate that
      rejected it; for a richer one, the chosen against it), `p_value` (of that test;
      `None` where no test was run), `verdict` (in words);
    - `tests`: every test run: `null`, `alternative` (names), `statistic` at each of the two
      simulation seeds, `p_values` at each, `p_value` (the larger);
    - `alpha`, `n_boot`, `method`, `warnings`.
    """

    chosen: Any
    table: list[dict]
    tests: list[dict]
    alpha: float
    n_boot: int
    method: str
    warnings: list[str]
    fits: dict[str, Any] = dataclasses.field(repr=False)

    @property
    def chosen_name(self) -> str:
        return self.table[0]["name"]

    def summary(self) -> str:
        """The table as text, the choice, and the warnings."""
        head = ("rank", "candidate", "free", "log-lik", "2 dlogL", "p", "verdict")
        rows = [head]
        for r in self.table:
            stat = "" if r["statistic"] is None else f"{r['statistic']:.2f}"
            p = "" if r["p_value"] is None else f"{r['p_value']:.3g}"
            rows.append(
                (str(r["rank"]), r["name"], str(r["n_free"]), f"{r['log_likelihood']:.2f}",
                 stat, p, r["verdict"])
            )  # fmt: skip
        widths = [max(len(row[c]) for row in rows) for c in range(len(head) - 1)]
        lines = [self.method, ""]
        for row in rows:
            cells = [c.ljust(w) for c, w in zip(row[:-1], widths, strict=True)]
            lines.append("  ".join(cells + [row[-1]]))
        lines += ["", f"chosen: {self.chosen_name}"]
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


@dataclasses.dataclass(frozen=True)
class Replicates:
    """Parametric-bootstrap data sets of one fit, drawn ahead of `compare_fits`
    (`draw_replicates`): `n_boot` data sets of the fit's data size, simulated from its
    fitted model at its estimate through its fit's observation rule, with `seed`; `sets`
    holds, per run (one for a fit of one data set), each column's values of every set one
    after another (`n_boot` times the run's cycles). `fit` says whose they are (its model,
    estimate and log-likelihood)."""

    fit: tuple
    n_boot: int
    seed: int
    sets: tuple = dataclasses.field(repr=False)


def draw_replicates(fit, n_boot: int | None = None, *, seed: int = 0) -> Replicates:
    r"""The parametric-bootstrap data sets `compare_fits` draws from a simpler candidate,
    drawn ahead: for candidates fitted side by side, the simpler one's replicates (most of
    a comparison's cost, where the fit is through a measurement) can be drawn as soon as
    its own fit ends, beside the richer fits, and handed to `compare_fits(...,
    replicates=[...])`.

    **Arguments:**

    - `fit`: a `FitResult` (from `fit`; a fit of several runs too: each replicate is then
      a set of runs, each through its own measurement).
    - `n_boot`: how many data sets; by default `compare_fits`'s for a candidate with one
      richer rival (199 at its default level 0.01).
    - `seed`: their seed (take one other than the data's and the fits'). The sets depend
      on the fit and the seed alone: drawn here or inside `compare_fits` with the same
      seed, they are the same cycles.

    **Returns:** `Replicates`, to pass to `compare_fits` with the fits (a process of its
    own can draw them: they pickle).
    """
    owner = "draw_replicates"
    from .result import FitResult

    if not isinstance(fit, FitResult):
        raise ParameterError(owner, "fit", "must be a FitResult (from fit)", type(fit))
    n_boot = check_int(owner, "n_boot", _default_n_boot(1, ALPHA) if n_boot is None else n_boot,
                       minimum=1)  # fmt: skip
    seed = check_int(owner, "seed", seed, minimum=0)
    if seed >= 2**63:
        raise ParameterError(owner, "seed", "must be < 2**63", seed)
    if _loaded_joint(fit):
        raise ParameterError(owner, "fit", _LOADED_JOINT)
    return _drawn(_Candidate.of("fit", fit), n_boot, seed)


def _drawn(null, n_boot: int, seed: int) -> Replicates:
    """`n_boot` replicates of candidate `null` with `seed`: each run's from its own stream
    (run 0 from `seed` itself)."""
    sets = []
    for r, (setting, data) in enumerate(zip(null.parts, null.columns, strict=True)):
        n = next(iter(data.values())).size
        reps = simulate_replicates(setting, n, n_boot, seed if r == 0 else _stream(seed, 1000 + r))
        sets.append({k: np.concatenate([x[k] for x in reps]) for k in data})
    return Replicates(fit=_fingerprint(null.result), n_boot=n_boot, seed=seed,
                      sets=tuple(sets))  # fmt: skip


def _fingerprint(result) -> tuple:
    """What identifies a fit across processes (a pickled copy is another object): its
    model, estimate, log-likelihood and simulation seeds."""
    design = result.diagnostics.design
    seeds = tuple(int(x) for x in (design.seeds or ())) if design is not None else ()
    return (_model_name(type(result.model)), tuple(sorted(result.estimate.items())),
            float(result.log_likelihood), seeds)  # fmt: skip


def _default_n_boot(rivals: int, alpha: float) -> int:
    """The replicates that put the smallest (Bonferroni-adjusted) p-value of a candidate
    with `rivals` richer rivals at alpha / 2."""
    return max(1, math.ceil(2 * rivals / alpha) - 1)


def _loaded_joint(result) -> bool:
    """A fit of several runs loaded from disk (`load_fit`): its map to each run's model is
    not saved."""
    return bool(result.diagnostics.runs) and result.diagnostics.joint is None


_LOADED_JOINT = ("is a loaded fit of several runs: the map from its SI values to each run's "
                 "model is not saved; use a fit made by fit(model, [run, ...]) in this "
                 "session")  # fmt: skip


def compare_fits(
    fits, *, alpha: float = ALPHA, n_boot: int | None = None, seed: int = 0, replicates=None
) -> Comparison:
    r"""Choose, among models fitted to the same data, the simplest one the data do not
    reject.

    **Arguments:**

    - `fits`: two or more `FitResult`s (from `fit`) of one data set, or of the same runs
      (`fit(model, [run, ...])`: a replicate is then a set of runs, each through its own
      measurement), as a list (each named by its model and free parameters) or a dict
      `{name: FitResult}`. Candidates for a
      slider: a fixed against a random static threshold (`langevin` with `x0` free against
      `random-threshold` with `"threshold_params.sd"` free), white against
      Ornstein-Uhlenbeck noise, with or without a velocity-dependent kinetic friction.
    - `alpha`: the level: a simpler candidate is kept unless a test rejects it at `alpha`.
    - `n_boot`: parametric-bootstrap replicates per test; by default enough that the
      smallest p-value is half of `alpha` (199 for two candidates at 0.01; with $k$
      richer rivals, Bonferroni's $k$ times more); refused where no p-value could fall
      below `alpha`.
    - `seed`: seed of the replicates (take one other than the data's and the fits').
    - `replicates`: a list of `Replicates` (`draw_replicates`) drawn ahead from some of the
      fits: a candidate's given replicates stand for its own as the null (their seed, not
      one of `seed`'s streams; their number is `n_boot`, which all given must share).

    A simpler candidate is tested against each richer one by a likelihood ratio of the
    fits' own smoothed log-likelihoods, calibrated by a parametric bootstrap from the
    simpler one (see the module's docstring, and docs/compare.md for why this is valid for
    `fit`'s likelihood and what it assumes). Fits of different data (columns, values or
    measurement) raise a `DataError`; fewer than two fits, or the same one twice, a
    `ParameterError`. Fits in different physical units (a creeping slider in SI against a
    slider in its reference `Slider`'s units) are compared on the data in SI: the same
    values and measurement in SI, each log-likelihood that of the SI values (`si_shift`:
    the table's log-likelihoods are then in SI).

    **Returns:** a `Comparison`: `chosen` (one of the given fits), `table`, `summary()`.
    """
    owner = "compare_fits"
    named = _named(fits, owner)
    if not 0.0 < _real(alpha, owner, "alpha") < 1.0:
        raise ParameterError(owner, "alpha", "must be between 0 and 1", alpha)
    seed = check_int(owner, "seed", seed, minimum=0)
    if seed >= 2**63:
        raise ParameterError(owner, "seed", "must be < 2**63", seed)
    names = list(named)
    for k, r in named.items():
        if _loaded_joint(r):
            raise ParameterError(owner, "fits", f"holds {k}, which {_LOADED_JOINT}")
    _check_same_data(named)
    given = _given(replicates, named, owner)
    if given:
        counts = {x.n_boot for x in given.values()}
        if len(counts) > 1 or (n_boot is not None and n_boot not in counts):
            raise ParameterError(
                owner, "replicates", f"hold {' and '.join(map(str, sorted(counts)))} data sets"
                f"{'' if n_boot is None else f' against n_boot = {n_boot}'}: draw every "
                "candidate's as many as n_boot",
            )  # fmt: skip
        n_boot = counts.pop()
    cands = {k: _Candidate.of(k, r) for k, r in named.items()}
    if len({repr(c.units) for c in cands.values()}) > 1:  # their log-likelihoods in SI
        cands = {k: c.in_si() for k, c in cands.items()}
    order = sorted(names, key=lambda k: (cands[k].n_free, -cands[k].log_likelihood))
    # the most richer rivals a candidate has: its smallest p-value is that many times
    # 1 / (n_boot + 1) (Bonferroni), which must fall below alpha for a rejection
    rivals_max = max(sum(c.n_free > cands[k].n_free for c in cands.values()) for k in names)
    if n_boot is None:
        n_boot = _default_n_boot(rivals_max, alpha)
    n_boot = check_int(owner, "n_boot", n_boot, minimum=1)
    if rivals_max and rivals_max / (n_boot + 1) >= alpha:
        raise ParameterError(
            owner, "n_boot", f"gives no p-value below alpha = {alpha:g} (with {rivals_max} "
            f"richer rival(s) the smallest is {rivals_max} / (n_boot + 1)): take at least "
            f"{math.ceil(rivals_max / alpha)}",
            n_boot,
        )  # fmt: skip
    chosen, tests, rejected = _tested(order, cands, given, n_boot, seed, names, alpha)
    said = _cautions(tests, alpha, chosen, named[chosen].p_values)
    table = _table(order, cands, chosen, rejected, tests, alpha)
    method = (
        f"simplest of {len(names)} candidates not rejected at alpha = {alpha:g}: likelihood "
        "ratios of the fits' smoothed simulated log-likelihoods (each the maximum of the "
        "fit's polynomial through its design, +-2 steps around the estimate), calibrated by "
        f"{n_boot} parametric-bootstrap replicates from the simpler model; rejected only if "
        "rejected with both of the fits' seeds; Bonferroni over richer rivals"
    )
    for text in said:
        warnings.warn(f"compare_fits: {text}", stacklevel=2)
    return Comparison(
        chosen=named[chosen], table=table, tests=list(tests.values()), alpha=float(alpha),
        n_boot=n_boot, method=method, warnings=said, fits=named,
    )  # fmt: skip


def _tested(order, cands, given, n_boot, seed, names, alpha):
    """The sequence of tests: from the simplest candidate up, each against its richer
    rivals, until one is not rejected (Bonferroni over its rivals). Returns the chosen
    name, the tests by (null, alternative) and the rejected ones (name -> (by whom, p))."""
    tests: dict[tuple[str, str], dict] = {}
    designs: dict[str, tuple] = {}
    drawn: dict[str, Replicates] = {}
    rejected: dict[str, tuple[str, float]] = {}
    # the loop stops at the latest at the first of the richest: no richer rival rejects it
    chosen = order[-1]
    for i, a in enumerate(order):
        rivals = [b for b in order[i + 1 :] if cands[b].n_free > cands[a].n_free]
        for b in rivals:
            if a not in drawn:  # (each null's replicates drawn once, for all its rivals)
                drawn[a] = given.get(a) or _drawn(cands[a], n_boot,
                                                  _stream(seed, names.index(a)))  # fmt: skip
            tests[a, b] = _test(cands[a], cands[b], drawn[a], designs)
        p = [tests[a, b]["p_value"] for b in rivals]
        p_adj = min(1.0, len(rivals) * min(p)) if rivals else 1.0
        if p_adj >= alpha:
            chosen = a
            break
        rejected[a] = (rivals[int(np.argmin(p))], p_adj)
    return chosen, tests, rejected


def _cautions(tests, alpha, chosen, goodness) -> list[str]:
    """What a comparison says besides its choice: a nested model scored above the model
    that holds it, a decision that hangs on the seed, a chosen model its own goodness of fit
    rejects (`goodness`: its p-values)."""
    said: list[str] = []
    for t in tests.values():
        below = min(t["raw_statistic"])
        if t["nested"] and below < -NESTED_SLACK:
            said.append(
                f"{t['alternative']} holds {t['null']}'s fitted model, yet its simulated "
                f"log-likelihood came out below it (2 dlogL = {below:.3g}): its fit did not "
                "reach the maximum its family holds, or the simulations' noise is that large "
                "(refit it with a larger n_sim, or a box that reaches the nested model); the "
                "statistic is taken as at least 0, for the data and every replicate"
            )
        decisions = {p < alpha for p in t["p_values"]}
        if len(decisions) > 1:
            said.append(
                f"{t['null']} against {t['alternative']}: p = {t['p_values'][0]:.3g} with the "
                f"fits' seeds and {t['p_values'][1]:.3g} with their second seeds, either side "
                f"of alpha = {alpha:g}: the choice hangs on the simulation; refit with a "
                "larger n_sim"
            )
    if goodness:
        low = {k: p for k, p in goodness.items() if p < GOODNESS_ALPHA}
        if low:
            shown = ", ".join(f"{k} p = {p:.3g}" for k, p in low.items())
            said.append(
                f"the chosen model, {chosen}, is itself rejected by its goodness of fit "
                f"({shown} < {GOODNESS_ALPHA}): no candidate reproduces the data"
            )
    return said


# -- pieces -----------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class _Candidate:
    """One fit, as the tests need it: the model at fit coordinates, the fit's own design
    of points around its estimate, its two simulation seeds; for a fit of several runs,
    each run's model, data, measurement and bandwidths (`parts`, `columns`: one entry per
    run; a fit of one data set has one)."""

    name: str
    result: Any
    setting: Any  # goodness.Setting: the model at u, the simulation and observation rule
    n_free: int
    log_likelihood: float
    seeds: tuple[int, int]
    parts: tuple = ()  # per run: the model at u, its simulation and observation rule
    columns: tuple = ()  # per run: its data
    units: tuple = ()  # per run: {column: SI value of its unit} (None: no physical units)

    @classmethod
    def of(cls, name, result) -> _Candidate:
        setting = Setting.of(result)  # (the constructor's arguments: `model_kwargs`)
        design = result.diagnostics.design
        if design is None or design.points is None or design.seeds is None:
            raise ParameterError(
                "compare_fits", "fits", f"holds {name}, a fit without its design of points "
                "(from another version of stickslip): fit it again",
            )  # fmt: skip
        first, second = (int(x) for x in design.seeds)
        runs = result.diagnostics.joint
        if runs is None:
            parts, columns = (setting,), (result.data,)
        else:
            parts = tuple(_RunSetting.of(setting, runs, i) for i in range(len(runs.columns)))
            columns = tuple(runs.columns)
        units = _units_of(result)
        return cls(
            name=name, result=result, setting=setting, n_free=len(result.estimate),
            log_likelihood=float(result.log_likelihood), seeds=(first, second), parts=parts,
            columns=columns, units=units,
        )  # fmt: skip

    def in_si(self) -> _Candidate:
        """This candidate with its log-likelihood that of the data in SI (`si_shift`)."""
        shift = float(si_shift(self.columns, self.units)[0])
        return dataclasses.replace(self, log_likelihood=self.log_likelihood + shift)

    def design(self) -> tuple[list, np.ndarray, list]:
        """The fit's own design (`surface.local_surface`: the centre, +-1 and +-2 steps
        along each axis, +-1 step along each pair's diagonals, clipped at the box) less
        the points where the fit's log-likelihood is not finite at either seed: the models
        there (one per run), their offsets from the centre in steps, and, per seed, the
        cycles the fit simulated there (`None` where the fit did not keep them: simulated
        again, the same cycles)."""
        d = self.result.diagnostics.design
        centre, steps = np.asarray(d.centre, float), np.asarray(d.steps, float)
        points = np.atleast_2d(np.asarray(d.points, float))
        finite = np.all(np.isfinite(np.asarray(d.values, float)), axis=0)
        kept = d.samples
        models, offsets, samples = [], [], ([], [])
        for i, u in enumerate(points):
            m = [_built(s, u) for s in self.parts] if finite[i] else [None]
            if any(x is None for x in m):
                continue
            models.append(m)
            offsets.append((u - centre) / steps)
            for j in range(2):
                cycles = None if kept is None else kept[j][i]  # (several runs: a list)
                if cycles is None:  # (not kept: simulated again)
                    cycles = [None] * len(m)
                samples[j].append([cycles] if isinstance(cycles, dict) else list(cycles))
        if not models:
            raise ParameterError(
                "compare_fits", "fits", f"holds {self.name}, whose fit has no design point "
                "with a finite log-likelihood",
            )  # fmt: skip
        return models, np.array(offsets), list(samples)

    def best(self, design, pooled, n_sets: int, which: int) -> np.ndarray:
        """$\\tilde\\ell$ of each of the `n_sets` data sets stacked in `pooled` (one dict
        per run): the fit's smoothed log-likelihood (its bandwidths, observation rule and
        simulation settings, seed number `which`; the sum of the runs') at each design
        point, the fit's polynomial fitted through them, and its largest value over the
        design's region (`_polynomial_max`)."""
        models, offsets, samples = design
        seed = self.seeds[which]
        values = np.zeros((len(models), n_sets))
        for i, per_run in enumerate(models):
            for r, (s, m, data) in enumerate(zip(self.parts, per_run, pooled, strict=True)):
                sim = samples[which][i][r]
                if sim is None:
                    sim = sample(m, s.n_sim, s.dt, s.t_max, seed, s.observe)
                terms = scored_samples(data, sim, s.bandwidth, s.observe)
                if terms is None:  # (the fit found cycles there: the same simulation)
                    values[i] = -np.inf
                    break
                per_row = np.sum([terms[k] for k in data], axis=0)
                values[i] += per_row.reshape(n_sets, -1).sum(axis=1)
        ok = np.all(np.isfinite(values), axis=1)
        return _polynomial_max(offsets[ok], values[ok])


@dataclasses.dataclass(frozen=True)
class _RunSetting:
    """What `simulate_replicates` and a design need of run `index` of a fit of several runs: its
    model at fit coordinates `u` (the SI values mapped into its units: `joint.Runs`), its
    measurement and bandwidths; `goodness.Setting`'s names."""

    runs: Any  # joint.Runs
    index: int
    names: list
    scales: dict
    u_hat: np.ndarray
    n_sim: int
    observe: Any
    bandwidth: dict
    kinds: list
    dt: None = None  # (a measurement sets its own step)
    t_max: None = None

    @classmethod
    def of(cls, setting, runs, index: int) -> _RunSetting:
        return cls(
            runs=runs, index=index, names=setting.names, scales=setting.scales,
            u_hat=setting.u_hat, n_sim=setting.n_sim, observe=runs.measurements[index],
            bandwidth=dict(setting.diagnostics.bandwidth[index]),
            kinds=list(runs.columns[index]),
        )  # fmt: skip

    def model(self, u):
        values = {k: from_fit_coords(self.scales[k], float(x)) for k, x in zip(self.names, u,
                                                                         strict=True)}  # fmt: skip
        return self.runs.build(values)[self.index]

    def simulate(self, u, n, seed) -> dict[str, np.ndarray]:
        sim = simulate_values(self.model(u), n, None, None, seed, self.observe)
        return {k: np.asarray(sim[k], float) for k in self.kinds}


def _built(setting, u):
    try:
        return setting.model(u)
    except (ValueError, ArithmeticError):  # outside the model's range
        return None


def _polynomial_max(offsets: np.ndarray, values: np.ndarray) -> np.ndarray:
    """The largest value, over the region the design's points span (`_region`), of the
    fit's polynomial (`surface.polynomial_vertex`: quadratic plus a cubic term per axis)
    fitted to each data set's values at the design points (`values`: points x sets): its
    curvature and cubic terms are fitted once to the sets' mean surface (nearly the same
    for every data set of one size; fitted per set they would carry each set's simulation
    noise), the level and gradient per set.

    Why not the largest value at a design point: the design is centred on the data's own
    estimate, so the data's maximum sits near a point while a replicate's falls between
    points and is underrated: the replicates' ratios, and the p-values, would be pulled
    down. A polynomial's maximum does not depend on where in the design it falls."""
    p = offsets.shape[1]
    terms = polynomial_terms(offsets)  # 1, linear | curvature, cubic (the fit's own)
    linear, shape_terms = terms[:, : 1 + p], terms[:, 1 + p :]
    shape = np.linalg.lstsq(terms, values.mean(axis=1), rcond=None)[0][1 + p :]
    ag = np.linalg.lstsq(linear, values - (shape_terms @ shape)[:, None],
                         rcond=None)[0]  # (1 + p) x sets  # fmt: skip
    x = polynomial_terms(_region(offsets))
    surface = x[:, : 1 + p] @ ag + (x[:, 1 + p :] @ shape)[:, None]
    return surface.max(axis=0)


def _region(offsets: np.ndarray) -> np.ndarray:
    r"""Points filling the region a design spans, where its polynomial interpolates: the
    convex hull of its points along the axes (+-2 steps, or where the box clipped them;
    one-sided where the model refuses the other side), $\sum_i x_i / e_i \le 1$ over the
    extents $e_i$ on each side, which holds the diagonal points (+-1, +-1) on its faces. Not
    the box they span: its corners (+-2 along every axis at once) lie far from every point,
    where a polynomial fitted on steps wide against the surface's curvature (falls of up to
    `surface.MAX_STEP_DROP` a step) extrapolates: 15 log-likelihood units above every design
    value, measured on the slider's random threshold (4 free). A grid of up to 33 points
    a side (about `GRID_BUDGET` inside the hull from three free parameters; steps of 1/8
    for one or two), and the design's points themselves."""
    p = offsets.shape[1]
    lo, hi = np.minimum(offsets.min(axis=0), 0.0), np.maximum(offsets.max(axis=0), 0.0)
    # the hull holds 1 / p! of the box: a grid of GRID_BUDGET p! points in the box, up to
    # 33 a side and 2^20 in all
    per_axis = (GRID_BUDGET * math.factorial(p)) ** (1.0 / p)
    per_axis = int(max(3, min(33, per_axis, 2 ** (20 / p))))
    axes = [np.linspace(a, b, per_axis) for a, b in zip(lo, hi, strict=True)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        scaled = np.where(grid > 0, grid / hi, np.where(grid < 0, grid / lo, 0.0))
    inside = grid[np.sum(scaled, axis=1) <= 1.0 + 1e-12]
    return np.vstack([inside, offsets])


def _test(a: _Candidate, b: _Candidate, reps: Replicates, designs) -> dict:
    """The parametric-bootstrap likelihood-ratio test of `a` (null) against `b`, with each
    fit's two simulation seeds (the same replicates `reps` of `a` for both); `designs`
    caches each candidate's design (the fit's: it does not depend on the null). Of several
    runs, each run's replicates are drawn through its own measurement."""
    n_boot = reps.n_boot
    pooled = [{k: np.concatenate([data[k], drawn[k]]) for k in data}
              for data, drawn in zip(a.columns, reps.sets, strict=True)]  # fmt: skip
    for c in (a, b):
        if c.name not in designs:
            designs[c.name] = c.design()
    designs = (designs[a.name], designs[b.name])
    nested = _nested(a, b)
    # candidates in other units (a creeping slider in SI against a slider in its reference
    # slider's): b scores the sets in its own units, and each set's log-likelihoods are
    # those of its values in SI (0 where the units agree)
    pooled_b, shift = pooled, 0.0
    if a.units != b.units:
        pooled_b = [{k: x[k] * (ua[k] / ub[k]) for k in x}
                    for x, ua, ub in zip(pooled, a.units, b.units, strict=True)]  # fmt: skip
        shift = si_shift(pooled, b.units, n_boot + 1) - si_shift(pooled, a.units, n_boot + 1)
    stats, raw, p_values = [], [], []
    for s in range(2):
        t = 2.0 * (
            b.best(designs[1], pooled_b, n_boot + 1, s)
            - a.best(designs[0], pooled, n_boot + 1, s)
            + shift
        )
        raw.append(float(t[0]))
        if nested:  # b holds a's fitted model: its maximum is at least a's (data and replicates)
            t = np.maximum(t, 0.0)
        stats.append(float(t[0]))
        p_values.append(float((1 + np.sum(t[1:] >= t[0])) / (1 + n_boot)))
    return dict(
        null=a.name, alternative=b.name, statistic=stats, p_values=p_values,
        p_value=max(p_values), n_design=(len(designs[0][0]), len(designs[1][0])),
        nested=nested, raw_statistic=raw, replicate_seed=reps.seed,
    )  # fmt: skip


def _runs_of(result) -> tuple:
    """Per run of a fit (one for a single data set): `(data, measurement, scales)`, the
    `Scales` of its units (`None` without physical units)."""
    runs = result.diagnostics.joint
    if runs is None:
        given = ((result.data, result.diagnostics.measurement, result.diagnostics.units),)
    else:
        given = zip(runs.columns, runs.measurements, runs.sliders, strict=True)
    return tuple((d, m, getattr(u, "scales", u)) for d, m, u in given)


def _units_of(result) -> tuple:
    """Per run of a fit, its columns' units in SI (`column_units`)."""
    return tuple(column_units(u, d) for d, _, u in _runs_of(result))


def column_units(scales, columns) -> dict | None:
    """`{column: the SI value of its unit}` for a fit's data columns in the units `scales`
    (a `Slider`, its `Scales`, or `Scales.si` for a creeping slider): times in
    `scales.time`, lengths in `scales.length`, forces in `scales.force`; `None` where the
    fit has no physical units (per-cycle values of the model)."""
    from ..quantities import get

    s = getattr(scales, "scales", scales)
    if s is None or not hasattr(s, "time"):
        return None
    unit = {"time": s.time, "length": s.length, "force": s.force}
    try:
        return {k: float(unit[get(k).dimension]) for k in columns}
    except (KeyError, ValueError):  # a column without a physical dimension
        return None


def si_shift(columns, units, n_sets: int = 1) -> np.ndarray:
    r"""What turns each of `n_sets` stacked data sets' log-likelihood in a fit's units into
    that of its values in SI: a density of $x$ in units $u$ is $u$ times its density in SI,
    so each value the density scores adds $-\log u$ (a duration's zeros, an atom, add
    nothing: `likelihood.log_density_at`). One entry a set; `columns`, `units` one entry a
    run (`None` units: 0)."""
    out = np.zeros(n_sets)
    for data, unit in zip(columns, units, strict=True):
        if unit is None:
            continue
        for k, x in data.items():
            x = np.asarray(x, float).reshape(n_sets, -1)
            scored = x > 0 if k in LOG_KINDS else np.ones(x.shape, bool)
            out -= scored.sum(axis=1) * math.log(unit[k])
    return out


def _nested(a: _Candidate, b: _Candidate) -> bool:
    """Whether `b`'s fitted family holds `a`'s fitted model: the same model class whose
    parameters fixed in `b` equal `a`'s and whose free ones hold `a`'s values inside `b`'s
    box, or another class that says how it reproduces `a`'s model (a classmethod
    `embed(model)`, such as `random-threshold` for `langevin`: a normal threshold of sd 0)
    with those arguments inside `b`'s box alike."""
    box = b.result.diagnostics.box
    if box is None:  # a fit from an earlier version: its box is not known
        return False
    if b.result.diagnostics.joint is not None:  # (SI boxes: not checked; the test is
        return False  # valid unclipped, as for a pair that is not nested)
    if a.units != b.units:  # (values in other units: not compared, unclipped alike)
        return False
    Mb = type(b.result.model)
    if isinstance(a.result.model, Mb):
        target = model_kwargs(a.result.model)
    else:
        embed = getattr(Mb, "embed", None)
        try:
            target = embed(a.result.model) if callable(embed) else None
        except (TypeError, ValueError, AttributeError, KeyError):
            target = None
        if target is None:
            return False
    mine, theirs = _flat(model_kwargs(b.result.model)), _flat(target)
    if set(mine) != set(theirs):
        return False
    for k, value in theirs.items():
        if k in box:
            lo, hi = box[k]
            if not (isinstance(value, (int, float)) and lo <= value <= hi):
                return False
        elif not _same(mine[k], value):
            return False
    return True


def _flat(kwargs: dict) -> dict:
    """A model's arguments with dict entries as dotted names (`threshold_params.sd`)."""
    out = {}
    for k, v in kwargs.items():
        if isinstance(v, dict):
            out.update({f"{k}.{e}": x for e, x in v.items()})
        else:
            out[k] = v
    return out


def _same(x, y) -> bool:
    if isinstance(x, (int, float)) and isinstance(y, (int, float)):
        return math.isclose(float(x), float(y), rel_tol=1e-9, abs_tol=1e-300)
    return x == y


def _table(order, cands, chosen, rejected, tests, alpha) -> list[dict]:
    rows = []
    for k in order:
        c = cands[k]
        row = dict(
            name=k, model=_model_name(c.setting.Model), free=list(c.result.estimate),
            n_free=c.n_free, log_likelihood=c.log_likelihood, statistic=None, p_value=None,
        )  # fmt: skip
        if k == chosen:
            done = [t for (a, _), t in tests.items() if a == k]
            if done:
                worst = min(done, key=lambda t: t["p_value"])
                row.update(statistic=worst["statistic"][0], p_value=worst["p_value"])
                row["verdict"] = (
                    f"chosen: not rejected against {worst['alternative']} "
                    f"(p = {worst['p_value']:.3g} >= {alpha:g})"
                )
            elif rejected:
                row["verdict"] = (
                    f"chosen: every simpler candidate is rejected ({', '.join(rejected)}) and "
                    "none has more free parameters"
                )
            else:
                row["verdict"] = "chosen: no candidate with more free parameters"
        elif k in rejected:
            by, p = rejected[k]
            t = tests[k, by]
            row.update(statistic=t["statistic"][0], p_value=p)
            row["verdict"] = f"rejected against {by} (p = {p:.3g} < {alpha:g})"
        elif (chosen, k) in tests:
            t = tests[chosen, k]
            row.update(statistic=t["statistic"][0], p_value=t["p_value"])
            row["verdict"] = f"not needed: {chosen} is not rejected against it"
        else:
            row["verdict"] = f"not tested: no more free parameters than {chosen}"
        rows.append(row)
    first = [r for r in rows if r["name"] == chosen]
    richer = [r for r in rows if r["name"] != chosen and r["name"] not in rejected]
    worse = sorted(
        (r for r in rows if r["name"] in rejected), key=lambda r: -rejected[r["name"]][1]
    )  # fmt: skip
    ranked = first + richer + worse
    for i, r in enumerate(ranked):
        r["rank"] = i + 1
    return [{"rank": r.pop("rank"), **r} for r in ranked]


def _given(replicates, named: dict, owner: str) -> dict:
    """`{name: Replicates}` of the candidates whose replicates are given (`None`: none),
    each matched to its fit by `_fingerprint`."""
    if replicates is None:
        return {}
    if isinstance(replicates, Replicates) or not isinstance(replicates, (list, tuple)):
        raise ParameterError(owner, "replicates", "must be a list of Replicates (from "
                             "draw_replicates)", type(replicates))  # fmt: skip
    prints = {_fingerprint(r): k for k, r in named.items()}
    out: dict[str, Replicates] = {}
    for i, x in enumerate(replicates):
        if not isinstance(x, Replicates):
            raise ParameterError(owner, f"replicates[{i}]", "must be Replicates (from "
                                 "draw_replicates)", type(x))  # fmt: skip
        name = prints.get(x.fit)
        if name is None:
            raise ParameterError(
                owner, f"replicates[{i}]", f"were drawn from a fit that is not among the fits "
                f"({x.fit[0]} at {dict(x.fit[1])})",
            )  # fmt: skip
        if name in out:
            raise ParameterError(owner, f"replicates[{i}]", f"are {name}'s again: give each "
                                 "candidate's once")  # fmt: skip
        out[name] = x
    return out


def _named(fits, owner) -> dict:
    """`{name: FitResult}` from a list (named by model and free parameters) or a dict."""
    from .result import FitResult

    if hasattr(fits, "items"):
        items = [(str(k), v) for k, v in fits.items()]
        where = [f"fits[{k!r}]" for k, _ in items]
    elif isinstance(fits, (list, tuple)):
        items = [(None, v) for v in fits]
        where = [f"fits[{i}]" for i in range(len(items))]
    else:
        raise ParameterError(
            owner, "fits", "must be a list or dict of FitResults (from fit)", type(fits)
        )
    if len(items) < 2:
        raise ParameterError(
            owner, "fits", "must hold at least two fits to choose from", len(items)
        )
    for w, (_, r) in zip(where, items, strict=True):
        if not isinstance(r, FitResult):
            raise ParameterError(owner, w, "must be a FitResult (from fit)", type(r))
    seen: dict[int, str] = {}
    for w, (_, r) in zip(where, items, strict=True):
        if id(r) in seen:
            raise ParameterError(owner, w, f"is {seen[id(r)]} again: give each candidate once")
        seen[id(r)] = w
    out: dict[str, Any] = {}
    for _, r in items:
        if _ is None:
            base = f"{_model_name(type(r.model))} ({', '.join(r.estimate)})"
            name, k = base, 2
            while name in out:
                name, k = f"{base} #{k}", k + 1
        else:
            name = _
        out[name] = r
    return out


def _check_same_data(named: dict) -> None:
    """One data set and one measurement for every fit, else a `DataError` naming the first
    fit that differs and how."""
    (ref_name, ref), *rest = named.items()
    d0 = ref.diagnostics
    for name, r in rest:
        if list(r.data) != list(ref.data):
            raise DataError(
                f"compare_fits: {name} was fitted to {', '.join(r.data)} and {ref_name} to "
                f"{', '.join(ref.data)}: likelihoods compare models on one data set"
            )
        runs = [[x["name"] for x in f.diagnostics.runs or []] for f in (r, ref)]
        if runs[0] != runs[1]:
            raise DataError(
                f"compare_fits: {name} was fitted to {_runs_text(runs[0])} and {ref_name} to "
                f"{_runs_text(runs[1])}: likelihoods compare models on one data set"
            )
        units = (_units_of(r), _units_of(ref))
        if units[0] != units[1]:  # in other units: the same data and measurement in SI
            _check_same_in_si((name, r), (ref_name, ref), units)
            continue
        for k in ref.data:
            x, y = np.asarray(r.data[k]), np.asarray(ref.data[k])
            if x.shape != y.shape or not np.array_equal(x, y):
                how = (
                    f"{x.size} cycles against {y.size}"
                    if x.shape != y.shape
                    else f"first at row {int(np.flatnonzero(x != y)[0])}"
                )
                raise DataError(
                    f"compare_fits: {name} and {ref_name} were fitted to different data "
                    f"({k}: {how}): likelihoods compare models on one data set"
                )
        d = r.diagnostics
        for key in ("trace", "sampling", "observe"):
            mine, theirs = getattr(d, key), getattr(d0, key)
            if _plain(mine) != _plain(theirs):
                raise DataError(
                    f"compare_fits: {name} and {ref_name} model the data's measurement "
                    f"differently ({key}: {mine!r} against {theirs!r}): fit both "
                    "to the same data, Cycles or trace settings"
                )


# Data in two fits' units are the same in SI to this (their scales' rounding)
SI_RTOL = 1e-9


def _check_same_in_si(one, other, units) -> None:
    """Two fits in other units (a creeping slider's SI against a slider's reference units)
    compare only where both units are physical and their data, runs and measurements'
    sampling intervals and noise agree in SI; else a `DataError` saying which."""
    (name, r), (ref_name, ref) = one, other
    if any(u is None for per in units for u in per):
        raise DataError(
            f"compare_fits: {name} and {ref_name} were fitted in different units, and one "
            "has no physical units (per-cycle values of the model): fit both to the same "
            "Cycles of a force trace (scales= a Slider, or a creeping slider in SI)"
        )
    if len(units[0]) != len(units[1]):
        raise DataError(f"compare_fits: {name} and {ref_name} were fitted to different runs: "
                        "likelihoods compare models on one data set")  # fmt: skip
    for i, ((d1, _, _), (d2, _, _), u1, u2) in enumerate(zip(_runs_of(r), _runs_of(ref),
                                                             *units, strict=True)):  # fmt: skip
        where = f" (run {i})" if len(units[0]) > 1 else ""
        for k in d2:
            x, y = np.asarray(d1[k], float) * u1[k], np.asarray(d2[k], float) * u2[k]
            if x.shape != y.shape:
                how = f"{x.size} cycles against {y.size}"
            elif not np.allclose(x, y, rtol=SI_RTOL, atol=0.0):
                row = int(np.flatnonzero(~np.isclose(x, y, rtol=SI_RTOL, atol=0.0))[0])
                how = f"first at row {row}: {x[row]:.6g} against {y[row]:.6g}"
            else:
                continue
            raise DataError(
                f"compare_fits: {name} and {ref_name} were fitted to different data{where} "
                f"({k} in SI, {how}): likelihoods compare models on one data set"
            )
    for i, ((_, m1, s1), (_, m2, s2)) in enumerate(zip(_runs_of(r), _runs_of(ref),
                                                        strict=True)):  # fmt: skip
        where = f" (run {i})" if len(units[0]) > 1 else ""
        # the sampling interval in s; the noise on the force in N (a force trace's signal
        # is the force over scales.force in either units)
        for what, x, y, unit in (
            ("sampling interval", m1.sampling_interval * s1.time, m2.sampling_interval * s2.time,
             "s"),
            ("noise sd", m1.noise_sd * s1.force, m2.noise_sd * s2.force, "N"),
        ):  # fmt: skip
            if not math.isclose(float(x), float(y), rel_tol=SI_RTOL, abs_tol=0.0):
                raise DataError(
                    f"compare_fits: {name} and {ref_name} model the data's measurement{where} "
                    f"differently ({what} {float(x):.6g} {unit} against {float(y):.6g} "
                    f"{unit}): fit both to the same Cycles"
                )


def _runs_text(names: list) -> str:
    return f"the runs {', '.join(names)}" if names else "one data set"


def _plain(value):
    """A measurement setting in a comparable form (dicts and lists of numbers)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _model_name(Model) -> str:
    """The registry's name of a model class (its class name where it is not registered)."""
    from .._registry import list_models

    for name, cls in list_models().items():
        if cls is Model:
            return name
    return Model.__name__


def _real(value, owner, name) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ParameterError(owner, name, "must be a number", value)
    return float(value)


def _stream(seed: int, index: int) -> int:
    """The replicates' seed for the candidate at `index` as the null: one stream of
    `seed`, far from the small seeds data and fits are usually given."""
    return int(np.random.default_rng([seed, 0xC0FFEE, index]).integers(2**62))
