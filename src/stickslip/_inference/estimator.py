r"""The simulated maximum-likelihood estimator behind `fit`, a composition of the
subpackage's pieces:

1. the data and their measurement (`data`), the parameters, their box and the fit
   coordinates (`params`), the simulation settings (`forward.simulation_settings`);
2. the simulated smoothed likelihood (`likelihood`), maximised by a coarse grid and
   Nelder-Mead (`surface.search`), then a polynomial fitted around the maximum
   (`surface.local_surface`): its vertex the estimate; the information that polynomial's
   curvature at the vertex and a plain quadratic's through both seeds' values
   (`intervals.with_plain_bread`), the sandwich the larger of the two
   (`intervals.larger_covariance`);
3. the sandwich covariance, the Monte Carlo noise check with a second seed, and the Wald
   intervals (`intervals`).

`fit` adds the goodness-of-fit check; a parametric bootstrap's refit (`goodness`) calls
`simulated_mle` itself.
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

from .._errors import DataError, ParameterError, check_int, check_positive
from .._model import CreepingSlider
from .data import LOG_KINDS, check_data, looks_sampled, measurement_of, to_fit_scale
from .diagnostics import Design, FitDiagnostics
from .forward import simulate_values, simulation_settings
from .intervals import (
    combine_seeds,
    concave,
    larger_covariance,
    mc_noise_report,
    sandwich_covariance,
    structural_lag,
    wald,
    with_plain_bread,
)
from .likelihood import JACKKNIFE_BLOCKS, bandwidth_of, jackknife_values, sample, scored_samples
from .params import (
    ToFit,
    check_box,
    check_fixed,
    check_free,
    check_n_sim_memory,
    creeping_scales,
    from_fit_coords,
    kwargs_of,
    model_class,
    to_fit_coords,
)
from .profile import profile_intervals
from .result import FitResult
from .surface import DESIGN_STEP, evaluate, local_surface, polynomial_vertex, search

# warnings point at the line that called `fit` (fit -> simulated_mle -> warnings.warn)
STACKLEVEL = 3
# Simulated cycles per evaluated point. Per-cycle values: 10^5 (about 0.3 s on 2 cores). A
# measured trace costs ~40 times more a cycle (recorded slips, sampling, extraction: 0.15-0.2
# ms a model cycle, ~1 s for 5000 on 2 cores), so ~4000 model cycles (~2500 measured ones
# after the joins) keep one evaluation near a second and a fit of ~100 points near minutes.
N_SIM_PER_CYCLE = 100_000
N_SIM_MEASURED = 4000
# The polynomial's design step through a measurement (fit coordinates; per-cycle data take
# surface.DESIGN_STEP, 0.1). The measured surface is rough whatever the common random
# numbers: the extraction's joins come and go with the parameters, and a datum in a sparse
# stretch of the simulated law (a rare short cycle) moves by 2-4 log-likelihood units when
# one simulated cycle near it does (measured: 5 of 320 data made 13 of a 15-unit jump
# between D 0.4 % apart). Against that noise (sd ~4 units a point at n_sim 4000) the
# curvature over steps of 0.1 (~1-2 units, SE of log D ~0.06) gave a vertex whose Monte
# Carlo sd was 2-6 standard errors (3 sets); over steps of 0.3 it was 0-1.1 (3 sets). (Those
# measurements predate the kernel estimate's floor, `likelihood.FLOOR_POINTS`, which takes
# most of that noise out; 0.3 is where the design starts, narrowed along an axis that falls
# by more than `surface.MAX_STEP_DROP` over a step.)
MEASURED_DESIGN_STEP = 0.3


@dataclasses.dataclass
class Problem:
    """A fit's checked arguments, in the form its pieces use.

    - `Model`, `fixed`, `free`: the model class, the known values and the boxes;
    - `names`, `coords` (`"log"` or `"linear"` per free parameter), `lo`, `hi`: the fit
      coordinates and the box in them;
    - `data`, `measured`: the columns in the model's units and their `Measurement` (None
      for per-cycle values); `parts`: per run, (its columns, its measurement, its kernel
      bandwidths) (one run unless `runs`);
    - `seed`, `n_sim`, `dt`, `t_max`: the simulation's settings; `centre`: the model at the
      box's centre; `build(values)`: the models (one a run) at parameter values;
    - `sampled`: what was said of data that look sampled (or None); `units`: the SI
      mapping given; `runs`: a joint fit's `joint.Runs` (or None).
    """

    Model: type
    fixed: dict
    free: dict
    names: list
    coords: dict
    lo: np.ndarray
    hi: np.ndarray
    data: dict
    measured: object
    parts: list
    seed: int
    n_sim: int
    dt: float | None
    t_max: float | None
    centre: object
    build: object
    sampled: str | None
    units: object
    runs: object

    def params(self, u) -> dict:
        """The free parameters' values at fit coordinates `u`."""
        return _values(self.names, self.coords, u)

    @property
    def bandwidth(self):
        """The kernel bandwidths: one dict (a list of them, one a run, for a joint fit)."""
        return self.parts[0][2] if self.runs is None else [b for _, _, b in self.parts]


def _values(names, coords, u) -> dict:
    """The free parameters' values at fit coordinates `u`."""
    return {k: from_fit_coords(coords[k], float(x)) for k, x in zip(names, u, strict=True)}


def problem(
    model, data, free, fixed=None, *, seed=0, n_sim=None, dt=None, t_max=None, scales=None,
    trace=None, sampling=None, measurement=None, runs=None,
) -> Problem:  # fmt: skip
    """`fit`'s arguments checked, each refusal one line naming the argument (see
    `simulated_mle`)."""
    owner = "fit"
    Model = model_class(model)
    if issubclass(Model, CreepingSlider) and runs is None:  # in SI: forces over its stiffness
        scales = creeping_scales(Model, data, fixed, free, scales)
    units = scales  # (a Slider or Scales)
    if runs is None:
        data, measured = measurement_of(data, trace, sampling, scales, owner)
        if measurement is not None:
            measured = measurement
        fixed = check_fixed(fixed, Model)
        free = check_free(free, fixed, Model)
    else:
        fixed, free = runs.checked(fixed, free)
        data, measured = runs.data, runs.measurements[0]
        units = runs.sliders[0]  # (the estimate is in SI; `predict` reads it in these units)
    seed = check_int(owner, "seed", seed, minimum=0)
    if seed >= 2**64:
        raise ParameterError(owner, "seed", "must be < 2**64", seed)
    if n_sim is None:
        n_sim = N_SIM_PER_CYCLE if measured is None else N_SIM_MEASURED
    n_sim = check_int(owner, "n_sim", n_sim, minimum=1000)
    dt = check_positive(owner, "dt", dt, allow_none=True)
    t_max = check_positive(owner, "t_max", t_max, allow_none=True)
    if measured is not None and t_max is not None:
        raise ParameterError(
            owner, "t_max", "applies to per-cycle data (a dict) only: a measured trace's "
            "length follows from n_sim", t_max,
        )  # fmt: skip
    names = list(free)
    coords = {k: "log" if free[k][0] > 0 else "linear" for k in names}
    lo = np.array([to_fit_coords(coords[k], free[k][0]) for k in names])
    hi = np.array([to_fit_coords(coords[k], free[k][1]) for k in names])

    mid = _values(names, coords, 0.5 * (lo + hi))
    if runs is None:
        # The model at the box's centre and at each end of each axis: a value the model
        # refuses is the box's fault, said here in one line rather than as points that
        # quietly fail.
        centre = check_box(Model, fixed, free, mid)
    else:
        centre = runs.check_box(free, mid)
    check_n_sim_memory(n_sim, centre)
    sampled = None
    if runs is None:
        given = data
        data = check_data(data, measured=measured is not None)
        sampled = None if measured is not None else looks_sampled(given, data)
        if sampled is not None:  # said now: the fit may take minutes
            warnings.warn(f"fit: {sampled}", stacklevel=STACKLEVEL + 1)
    if measured is None:
        dt, t_max = simulation_settings(centre, data, dt, t_max, owner)
    else:
        missing = [k for k in data if k not in measured.columns]
        if missing:
            raise ParameterError(
                owner, "data", f"has columns the measurement does not extract: "
                f"{', '.join(missing)}", sorted(data),
            )  # fmt: skip
    if runs is None:
        parts = [(data, measured, {k: bandwidth_of(to_fit_scale(k, data[k]), n_sim) for k in data})]

        def build(values):
            return [Model(**kwargs_of(fixed, values))]
    else:
        parts = [(d, m, {k: bandwidth_of(to_fit_scale(k, d[k]), n_sim) for k in d})
                 for d, m in zip(runs.columns, runs.measurements, strict=True)]  # fmt: skip
        build = runs.build
    return Problem(
        Model=Model, fixed=fixed, free=free, names=names, coords=coords, lo=lo, hi=hi,
        data=data, measured=measured, parts=parts, seed=seed, n_sim=n_sim, dt=dt,
        t_max=t_max, centre=centre, build=build, sampled=sampled, units=units, runs=runs,
    )  # fmt: skip


class Likelihood:
    """The simulated log-likelihood of a `Problem` at fit coordinates `u` (clipped to the
    box): `likelihood(u, at_seed=problem.seed)` is `(value, per-cycle terms)`, terms
    `None` where the model refuses `u` (a joint constraint inside the box).

    - `points`: every point evaluated at the fit's seed, with its value;
    - the best point so far is kept per seed, not simulated again (Nelder-Mead starts at
      the best grid point, the surface's design at Nelder-Mead's best point: common random
      numbers make the value a function of the point and the seed; only the best, for
      memory: its per-cycle terms are a data set's size);
    - during the surface's design (`design()`): each point's log-likelihood with a block of
      its simulated cycles left out in turn (`likelihood.jackknife_values`, for the
      simulation's noise in the estimate) and, where `keep`, the simulated cycles (for
      `compare_fits`, which scores its bootstrap replicates against them).
    """

    def __init__(self, problem: Problem, *, progress: bool = False, keep: bool = False):
        self.p, self.progress, self.keep = problem, progress, keep
        self.points: list = []
        self.best: dict = {}
        self.recording: dict | None = None
        self.blocks: dict | None = None

    def design(self) -> None:
        """From here on, record the design's blocks (and cycles, where kept)."""
        self.recording = {} if self.keep else None
        self.blocks = {}

    def design_records(self, design, seeds):
        """The design's cycles (`_DesignSamples`, or None where not kept) and, per seed, the
        jackknife's block values at each design point; the recording stops."""
        lo, hi = self.p.lo, self.p.hi
        samples = None
        if self.recording is not None:
            samples = _DesignSamples(
                [self.recording[np.clip(u, lo, hi).tobytes(), at] for u in design]
                for at in seeds
            )  # fmt: skip
            self.recording = None
        block_values = [np.array([self.blocks[np.clip(u, lo, hi).tobytes(), at] for u in design])
                        for at in seeds]  # fmt: skip
        self.blocks = None
        return samples, block_values

    def __call__(self, u, at_seed=None):
        at_seed = self.p.seed if at_seed is None else at_seed
        u = np.clip(u, self.p.lo, self.p.hi)
        key = u.tobytes()
        kept = self.best.get(at_seed)
        if (
            kept is not None
            and kept[0] == key
            and (self.blocks is None or (key, at_seed) in self.blocks)
        ):
            out = kept[1]
        else:
            out = self._evaluate(u, at_seed)
            if kept is None or out[0] > kept[1][0]:
                self.best[at_seed] = (key, out)
        if self.recording is not None:
            self.recording[key, at_seed] = out[2]
        return out[:2]

    def _evaluate(self, u, at_seed):
        p = self.p
        try:
            models = p.build(p.params(u))
        except (ValueError, ArithmeticError):
            models = [None] * len(p.parts)
        per_run, sims, left_out = [], [], 0.0
        for m, (d, measure, h) in zip(models, p.parts, strict=True):
            try:
                sim = None if m is None else sample(m, p.n_sim, p.dt, p.t_max, at_seed, measure)
                sims.append(sim)
            except ParameterError as err:  # simulate's names are fit's arguments
                name = {"n_paths": "n_sim"}.get(err.parameter, err.parameter)
                raise ParameterError("fit", name, err.reason, err.value) from None
            per_run.append(scored_samples(d, sim, h, measure))
            if per_run[-1] is None:
                break
            if self.blocks is not None:  # (several runs: their blocks' values add up)
                left_out = left_out + jackknife_values(d, sim, h, measure)
        if self.blocks is not None:
            whole = all(t is not None for t in per_run)
            self.blocks[u.tobytes(), at_seed] = (
                left_out if whole else np.full(JACKKNIFE_BLOCKS, -np.inf)
            )  # fmt: skip
        # (several runs: each column's terms one run after the other, the rows of `data`)
        if any(t is None for t in per_run):
            terms = None
        elif len(per_run) == 1:
            terms = per_run[0]
        else:
            terms = {k: np.concatenate([t[k] for t in per_run]) for k in p.data}
        kept = None
        if self.keep and terms is not None:  # (one run: its cycles; several: a list, per run)
            kept = [{k: np.asarray(s[k], float) for k in d}
                    for s, (d, _, _) in zip(sims, p.parts, strict=True)]  # fmt: skip
            kept = kept[0] if p.runs is None else kept
        value = -np.inf if terms is None else float(sum(np.sum(v) for v in terms.values()))
        if at_seed == p.seed:  # the surface's points (the second seed's are in mc_noise)
            self.points.append((np.array([p.params(u)[k] for k in p.names]), value))
        if self.progress:
            import sys

            shown = ", ".join(f"{k}={v:.4g}" for k, v in p.params(u).items())
            print(f"fit: {shown}: log-likelihood {value:.2f}", file=sys.stderr, flush=True)
        return value, terms, kept


def simulated_mle(
    model, data, free, fixed=None, *, seed=0, n_sim=None, dt=None, t_max=None, scales=None,
    trace=None, sampling=None, progress=False, measurement=None, runs=None, intervals="wald",
) -> FitResult:  # fmt: skip
    """`fit` without its goodness-of-fit check: the arguments and result are `fit`'s.
    `measurement` (private: a bootstrap replicate's refit) fits a dict of cycles as if they
    came with that measurement. `runs` (a `joint.Runs`, with `data` None): one parameter
    set fitted to several runs, each through its own measurement and units."""
    wall0 = time.perf_counter()
    p = problem(model, data, free, fixed, seed=seed, n_sim=n_sim, dt=dt, t_max=t_max,
                scales=scales, trace=trace, sampling=sampling, measurement=measurement,
                runs=runs)  # fmt: skip
    keep = _keeps_samples(p.n_sim, sum(len(d) for d, _, _ in p.parts), len(p.names))
    loglik = Likelihood(p, progress=progress, keep=keep)
    # 1. a coarse grid over the box, Nelder-Mead from its best point
    u_best, optimizer, caught = search(loglik, p.lo, p.hi, p.free)
    _check_informative(loglik.points, p.names, p.data, p.centre, p.n_sim, p.dt, p.t_max,
                       p.seed, p.measured)  # fmt: skip
    # 2. a polynomial around it: the vertex and the Hessian
    step = DESIGN_STEP if p.measured is None else MEASURED_DESIGN_STEP
    if p.runs is not None:
        # SI boxes can be narrow in fit coordinates (a static friction of 93-99 mN is 0.06
        # in log): the design's +-2 steps kept within an eighth of the box each, where a
        # step of 0.3 put the design past both ends (a one-sided fit at the box)
        step = np.minimum(step, (p.hi - p.lo) / 8)
    loglik.design()
    surface = local_surface(loglik, u_best, p.lo, p.hi, p.data, p.names, step)
    caught += surface.warnings
    # 3. the simulation's own noise: the same design with a second, independent seed. The
    # simulator's draws move with the parameters (see `surface.search`), so the surface
    # carries Monte Carlo noise that common random numbers do not cancel: measured, the two
    # seeds' vertices differed by 1-1.5 standard errors at n_sim = 2e4 for two columns, far
    # above the sqrt(n / n_sim) widening alone assumes. The estimate's Monte Carlo
    # covariance is a jackknife over each seed's simulated cycles (the design's blocks),
    # checked by the two seeds' difference (`intervals.combine_seeds`). The two seeds'
    # per-cycle scores also give the sandwich's J without the simulation's noise
    # (`sandwich_covariance`).
    seed2 = (p.seed + 0x9E3779B97F4A7C15) % 2**64  # far from seed: an independent stream
    values2, scores2 = evaluate(surface.design, lambda u: loglik(u, seed2), p.data)
    samples, block_values = loglik.design_records(surface.design, (p.seed, seed2))
    # successive rows share a draw where the onset is random (`intervals.structural_lag`)
    # the curvature the intervals divide by (and the goodness of fit's one-step estimates,
    # whose scatter the covariance holds: the same bread), `diagnostics.hessian`
    lag = structural_lag(p.centre)
    bread = with_plain_bread(surface, values2)
    cov, said, dependence = sandwich_covariance(bread, p.names, scores2, lag)
    if bread is not surface:  # both curvatures, the larger covariance
        cubic, _, _ = sandwich_covariance(surface, p.names, scores2, lag)
        cov = larger_covariance(cov, cubic)
    caught += said
    shift2, _ = polynomial_vertex(surface.design - surface.centre, np.array(values2),
                                   surface.steps)  # fmt: skip
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    sandwich = cov
    u_hat, cov, noise = combine_seeds(surface, shift2, cov, block_values, p.lo, p.hi)
    mc_noise = mc_noise_report(p.names, noise, se, p.n_sim)
    mc_noise.update(
        seed=seed2, log_likelihood_difference=float(surface.values[0] - values2[0])
    )  # fmt: skip
    # A seed's surface (or most of the jackknife's) has no maximum near the estimate: the
    # simulation's noise, not the data, made the curvature, and there is no interval. On an
    # independent generator's random thresholds at n_sim 1000, 4 of the 5 fits where this
    # happened had missed the truth with at least one interval (7 of their 20), by up to
    # 7 standard errors. (Evaluating the design again at 4x n_sim was tried: on one of
    # those sets both seeds then had a maximum and the interval still missed by 8 standard
    # errors, on the mean-sd ridge; a rejected law fitted to three runs had none at 4000
    # either, at 3x the time.)
    lost = noise["mc"] is None
    if mc_noise["warning"]:
        caught.append(mc_noise["warning"])
    # 4. the estimate, its intervals
    ll_hat, _ = loglik(u_hat)
    estimate = p.params(u_hat)
    ci, said = wald(u_hat, cov, p.names, p.coords, p.lo, p.hi, p.free,
                    concave(surface.hessian) and not lost)  # fmt: skip
    caught += said
    ci, profiles, said = _chosen_intervals(intervals, ci, p, loglik, bread, sandwich, noise["mc"])
    caught += said
    for text in caught:
        warnings.warn(f"fit: {text}", stacklevel=STACKLEVEL)
    diagnostics = _diagnostics(
        p, loglik, bread, cov, optimizer=optimizer, caught=caught, values2=values2,
        seed2=seed2, samples=samples, mc_noise=mc_noise, dependence=dependence,
        seconds=time.perf_counter() - wall0,
    )  # fmt: skip
    diagnostics.profile = profiles
    fitted = p.build(estimate)
    if p.runs is not None:
        diagnostics.runs = p.runs.describe(fitted)
        diagnostics.joint = p.runs  # the map to each run's model (`compare_fits`)
    return FitResult(
        estimate=estimate, ci=ci, log_likelihood=ll_hat, method=_method(p, dependence, intervals),
        diagnostics=diagnostics, data=p.data, model=fitted[0],
    )  # fmt: skip


def _diagnostics(p: Problem, loglik: Likelihood, surface, cov, *, optimizer, caught, values2,
                 seed2, samples, mc_noise, dependence, seconds) -> FitDiagnostics:  # fmt: skip
    """A fit's diagnostics (`FitResult.diagnostics`): its settings and box, the surface's
    design, both seeds' values, the simulation's noise, the rows' dependence, the warnings."""
    return FitDiagnostics(
        n_sim=p.n_sim, dt=p.dt, t_max=p.t_max, seed=p.seed, measurement=p.measured,
        n_data={k: int(v.size) for k, v in p.data.items()},
        zero_fraction={k: float(np.mean(v == 0)) for k, v in p.data.items() if k in LOG_KINDS},
        bandwidth=p.bandwidth, scales=p.coords,
        box={k: (float(lo), float(hi)) for k, (lo, hi) in p.free.items()},
        covariance=cov.tolist(), hessian=surface.hessian.tolist(),
        evaluations=len(loglik.points), points=loglik.points, seconds=seconds,
        warnings=([p.sampled] if p.sampled else []) + caught,
        to_fit=ToFit(p.coords), optimizer=optimizer,
        # the surface's design (fit coordinates), its values at both seeds and, where kept,
        # the cycles simulated there: the model comparison's design (`compare_fits`)
        design=Design(
            clipped=surface.clipped, vertex=surface.shift is not None,
            centre=surface.centre.tolist(), steps=surface.steps.tolist(),
            points=surface.design.tolist(), values=[list(map(float, surface.values)),
                                                    list(map(float, values2))],
            seeds=[p.seed, seed2], samples=samples,
        ),
        mc_noise=mc_noise, dependence=dependence,
        units=p.units,  # the SI mapping given (`FitResult.predict`)
    )  # fmt: skip


def _chosen_intervals(intervals, ci, p: Problem, loglik, bread, sandwich, mc):
    """The intervals `fit` was asked for from the Wald ones `ci`: `(ci, profiles, said)`,
    `profiles` the profile's records (each with its Wald interval; `None` for Wald)."""
    if intervals != "profile":
        missing = [k for k in p.names if not np.all(np.isfinite(ci[k]))]
        said = [
            f"no Wald interval for {', '.join(missing)}: intervals='profile' follows the "
            "likelihood itself and gives one where the surface's quadratic does not (at "
            "about four times the fit's cost)"
        ] if missing else []  # fmt: skip
        return ci, None, said
    wald_ci = ci
    ci, profiles, said = profile_intervals(loglik, bread, sandwich, mc, p.names, p.coords,
                                           p.lo, p.hi)  # fmt: skip
    for k, record in profiles.items():
        record["wald"] = [float(v) for v in wald_ci[k]]
    return ci, profiles, said


def _method(p: Problem, dependence: dict, intervals: str = "wald") -> str:
    """What the fit did, in words."""
    measured = p.measured
    through = (
        f", through the data's measurement (a {measured.signal} trace sampled every "
        f"{measured.sampling_interval:.4g}, its noise, extract_cycles' settings)"
        if measured is not None
        else ""
    )
    return (
        f"simulated maximum likelihood ({p.n_sim} cycles per point{through}, common random "
        "numbers, "
        f"smoothed kernel likelihood of {', '.join(p.data)}, zero durations as a point mass); "
        + ("95 % profile-likelihood intervals, their threshold adjusted by the sandwich "
           "covariance of per-cycle scores" if intervals == "profile" else
           "95 % Wald intervals from the sandwich covariance of per-cycle scores")
        + (f" (rows dependent: their scores' cross products up to lag {dependence['lag']})"
           if dependence["lag"] else "")
    )  # fmt: skip


# The most memory a fit keeps of the cycles simulated at its design points (both seeds),
# for `compare_fits`: 8 B a simulated cycle and fitted column (of each run, for a fit of
# several). Through a measurement: ~2 MB at n_sim 1000 with three columns and four free
# parameters (41 points), ~8 MB at the default 4000 (16 MB for two such runs: kept).
# Per-cycle values at the default 10^5 cycles a point: kept for one free parameter (5
# points, 8 MB a column), not from two (13 points, 21 MB a column): the comparison
# simulates them again, the same cycles (a function of the point and the seed), ~0.1-0.3 s
# a point.
KEEP_SAMPLES_BYTES = 16 * 2**20


class _DesignSamples(list):
    """Per seed, the cycles simulated at each design point (`None` where the model refused
    it; for a fit of several runs, a list of each run's): a list, shown in one line (a
    `FitResult`'s repr shows its diagnostics)."""

    def __repr__(self) -> str:
        return f"<cycles simulated at {len(self[0])} design points, {len(self)} seeds>"


def _keeps_samples(n_sim: int, n_columns: int, n_free: int) -> bool:
    n_points = 1 + 4 * n_free + 2 * n_free * (n_free - 1)  # `surface.quadratic_design`
    return 2 * n_points * n_sim * n_columns * 8 <= KEEP_SAMPLES_BYTES


def _check_informative(points, names, data, centre, n_sim, dt, t_max, seed, measured):
    """A `DataError` where the log-likelihood is the same at every point of the search (a
    flat surface has no maximum and no curvature: the fit would return the box's first
    point with an interval of zero width), naming a column the model at the box's centre
    never makes a positive value of (a white-noise `langevin`, `tau=None`, ends its slips
    at once) where there is one."""
    values = np.array([v for _, v in points if np.isfinite(v)])
    if values.size < 3 or np.ptp(values) > 1e-9 * max(1.0, float(np.abs(values).max())):
        return
    sim = simulate_values(centre, n_sim, dt, t_max, seed, measured)
    none = [k for k in data if k in LOG_KINDS and np.any(data[k] > 0)
            and not np.any(np.asarray(sim[k]) > 0)]  # fmt: skip
    why = (
        f": at the box's centre the model makes no {' or '.join(none)} above zero in "
        f"{n_sim} cycles (a white-noise langevin, tau=None, does so: its slips end at "
        "once; hold tau at a small value instead; docs/simulator.md, 'The white-noise "
        "degeneracy')"
        if none else f": the model's simulated {', '.join(data)} do not change with them"
    )  # fmt: skip
    raise DataError(
        f"fit: the log-likelihood is {values[0]:.6g} at all {values.size} points evaluated "
        f"in the box, so the data do not constrain {', '.join(names)}{why}"
    )
