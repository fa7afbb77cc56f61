r"""`fit`: friction-noise parameters from measured per-cycle statistics.

The estimator is a *simulated likelihood with common random numbers*:

- at a parameter value $\theta$ the model is simulated (`simulate`, exact in law for
  linear-Gaussian slips at any step) for `n_sim` cycles with one fixed seed (the
  simulator's draws still move with $\theta$, so the surface carries Monte Carlo noise:
  see the last point);
- each observed quantity's density is a Gaussian kernel estimate of the simulated values
  (slip times, periods and positive stick times on a log scale, where the slip-time
  density's spike near zero and its long tail are both resolved by one bandwidth; slip
  distances on their own scale), with one bandwidth per quantity fixed from the data
  (Silverman's rule at `n_sim` points), the same at every $\theta$; a duration's atom at
  zero (a stick of zero length) is a point mass: a zero datum contributes $\log p_0$, a
  positive one $\log(1 - p_0)$ plus its density, $p_0$ the simulated fraction of zeros;
- the data are the cycles a trace shows: slips of positive length that ended, so the
  simulated law is conditioned on the same (zero-length slips and slips cut at `t_max`
  are left out of the simulated sample);
- the data are smoothed by the same kernel as the model: a datum contributes
  $\int K_h(y - y_i) \log (\hat f_\theta * K_h)(y)\,dy$, whose expectation is largest
  at the true $\theta$ whatever the bandwidth (the kernel estimate at the raw data is
  biased by the smoothing); the columns of one cycle add up (a composite likelihood;
  rows are cycles);
- the maximum is found by a coarse grid over the `free` box and Nelder-Mead from its
  best point, in log coordinates for positive parameters; then a quadratic plus a cubic
  term per axis is fitted by least squares on a design of steps 0.1 in those coordinates
  around it (the cubic terms keep the surface's skew out of the vertex): the vertex is
  the estimate, its Hessian the information;
- 95 % intervals are Wald intervals in those coordinates (so asymmetric in the
  parameter) with the sandwich covariance $H^{-1} J H^{-1}$ (per-cycle scores summed over
  the columns: the smoothed likelihood is not a likelihood, and the columns of one cycle
  are dependent), widened by $\sqrt{1 + n/n_{sim}}$ for the simulation's own noise;
- the design is evaluated again with a second seed: the estimate is the mean of the two
  vertices, and the square of their half difference, the Monte Carlo covariance of that
  mean, is added to the covariance (a warning, with the `n_sim` needed, when it passes a
  quarter of the data's variance).

What it assumes: independent cycles (the paper's sharp reset: every slip starts from the
model's onset state), the model family is right, and the maximum lies inside the `free`
box. Nothing fails silently: a one-line warning each (also in `diagnostics["warnings"]`)
when Nelder-Mead stops on its cap, the estimate sits on an edge, the polynomial has no
vertex near the best point, design points are clipped at the box, the simulation noise is
comparable with the curvature, or a dict of data looks like the cycles of a sampled trace.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import time
import warnings
from typing import Any

import numpy as np

from ._errors import (
    DataError,
    ParameterError,
    ResourceError,
    StickSlipError,
    check_int,
    check_positive,
)

KINDS = ("slip_time", "slip_distance", "stick_time", "period")
LOG_KINDS = ("slip_time", "stick_time", "period")  # positive: estimated on a log scale
Z95 = 1.959963984540054
DESIGN_STEP = 0.1  # the quadratic design's step (log coordinates for positive parameters)
KDE_BINS = 4096  # the binned kernel estimate's grid
GRID_POINTS = 5  # per free parameter, for the coarse start (p <= 2; 8 p points above)
# A trace (sampling interval h): `extract_cycles` needs 2 stuck interval velocities for a
# stick (a stick of 2-3 h), and times each transition to within h: durations below 5 h carry
# a relative error above 20 % and are left out.
TRACE_STICK = 2.5
TRACE_CUT = 5.0
# A column's density is a kernel estimate whose bandwidth comes from the data's spread, and
# the intervals from per-cycle scores: below 10 cycles, or 10 distinct values (a constant or
# a few repeated levels), there is no density to fit.
MIN_CYCLES = 10
DISTINCT_DIGITS = 1e-9  # values closer than this (relative, on the fitting scale) are one
MAX_LINEAR = 1e150  # a slip distance's spread is a sum of squares: it must stay finite
# Peak memory of one evaluation, per simulated cycle and state component: measured 475 B a
# cycle for langevin (3 components) at 2e6 cycles, plain and as a trace (peak RSS).
SIM_BYTES_PER_STATE = 160
MAX_SIM_PATHS = 2**32 - 1  # the simulator numbers its paths with 32 bits
MAX_STEPS = 2**30  # the simulator's limit on t_max / dt
# Nelder-Mead's cap a free parameter: converged on the simplex's size it took 22 evaluations
# for one parameter and 35 for two (measured, slip and stick times); the cap is 4-5 x that.
MAXFEV_PER_PARAMETER = 100
# The Monte Carlo noise check: a warning when the estimate's Monte Carlo sd (from two seeds)
# passes this fraction of its standard error (its variance then a quarter of the data's: the
# interval, which includes it, 12 % wider from the simulation alone); the n_sim advised
# brings it to MC_RATIO_GOAL (under 5 % wider).
MC_RATIO_WARN = 0.5
MC_RATIO_GOAL = 0.3


@dataclasses.dataclass(frozen=True)
class FitResult:
    """The result of `fit`.

    - `estimate`, `ci`: the maximum simulated-likelihood estimate and 95 % intervals of
      each free parameter;
    - `log_likelihood`: at the estimate (of the data's transformed values plus the
      Jacobian of the log scale: a density of the data themselves);
    - `method`: what was done, in words;
    - `diagnostics`: the settings (`n_sim`, `dt`, `t_max`, `seed`, bandwidths), the
      covariance and Hessian (fit coordinates), every evaluated point, the evaluations and
      seconds spent, `optimizer` (Nelder-Mead's evaluations and cap), `design` (the axes
      clipped at the box, whether the polynomial had a vertex), `mc_noise` (the second
      seed, the Monte Carlo sd of the estimate against its standard error, the `n_sim`
      advised), `zero_fraction` (of each duration column), and `warnings` (each also
      issued as a one-line `UserWarning`).
    """

    estimate: dict[str, float]
    ci: dict[str, tuple[float, float]]
    log_likelihood: float
    method: str
    diagnostics: dict[str, Any]
    data: dict[str, np.ndarray] = dataclasses.field(repr=False)
    model: Any = dataclasses.field(repr=False)

    def summary(self) -> str:
        lines = [f"{self.method}", f"log-likelihood {self.log_likelihood:.2f}"]
        for k, v in self.estimate.items():
            lo, hi = self.ci[k]
            lines.append(f"  {k} = {v:.4g}   95 % interval [{lo:.4g}, {hi:.4g}]")
        lines += [f"warning: {w}" for w in self.diagnostics.get("warnings", ())]
        return "\n".join(lines)

    def plot(self, path=None, n_sim: int | None = None):
        """Data against the fitted model (a histogram per quantity and the simulated
        density at the estimate), and the log-likelihood along each free parameter (the
        evaluated points and the fitted quadratic). Returns the figure; saves it to `path`."""
        import matplotlib

        if path is not None:
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        kinds = list(self.data)
        free = list(self.estimate)
        fig, axes = plt.subplots(
            1, len(kinds) + len(free), figsize=(3.6 * (len(kinds) + len(free)), 3.2)
        )
        axes = np.atleast_1d(axes)
        d = self.diagnostics
        sim = _simulate(
            self.model, n_sim or d["n_sim"], d["dt"], d["t_max"], d["seed"], d["observe"]
        )
        for ax, k in zip(axes, kinds, strict=False):
            x = self.data[k]
            edges = np.histogram_bin_edges(x, bins=min(60, max(10, x.size // 50)))
            ax.hist(x, edges, density=True, alpha=0.5, label=f"data ({x.size})")
            ax.hist(sim[k], edges, density=True, histtype="step", lw=1.5, label="fitted model")
            ax.set_xlabel(k)
            ax.legend(fontsize=7)
        pts = np.array([p[0] for p in d["points"]])
        ll = np.array([p[1] for p in d["points"]])
        for i, (ax, name) in enumerate(zip(axes[len(kinds) :], free, strict=True)):
            u = d["to_fit"](name, pts[:, i])
            ax.plot(u, ll, ".", ms=3, color="0.6", label="evaluated")
            u0 = d["to_fit"](name, self.estimate[name])
            grid = np.linspace(u0 - 3 * DESIGN_STEP, u0 + 3 * DESIGN_STEP, 50)
            H = np.asarray(d["hessian"])
            ax.plot(
                grid, self.log_likelihood + 0.5 * H[i, i] * (grid - u0) ** 2, "-", label="quadratic"
            )
            ax.set_ylim(self.log_likelihood - 20, self.log_likelihood + 2)
            ax.set_xlabel(f"{d['scales'][name]} {name}")
            ax.set_ylabel("log-likelihood")
            ax.legend(fontsize=7)
        fig.tight_layout()
        if path is not None:
            fig.savefig(path, dpi=110)
            plt.close(fig)
        return fig


def fit(
    model,
    data: dict,
    free: dict,
    fixed: dict | None = None,
    *,
    seed: int = 0,
    n_sim: int = 100_000,
    dt: float | None = None,
    t_max: float | None = None,
    trace: bool | None = None,
    sampling: float | None = None,
    progress: bool = False,
) -> FitResult:
    """Estimate the `free` parameters of `model` from per-cycle data.

    **Arguments:**

    - `model`: a model name (`"langevin"`) or class with a linear-Gaussian slip or not
      (any model `simulate` runs; exact stepping where it applies).
    - `data`: the cycles, one row per cycle: a dict of per-cycle arrays, any of
      `slip_time`, `slip_distance`, `stick_time` (zeros included: a point mass),
      `period`, all of one length, fitted jointly; a dict holds *per-cycle values of the
      model* (as `simulate` gives them: no measurement). A `Cycles` from `extract_cycles`
      carries its measurement (`info["sampling_interval"]`: fitted as a trace's cycles,
      below); a dict that looks sampled (durations on one grid, a `sampling_interval`
      attribute, or release times with no stick of zero length, as an extracted table has)
      gets a warning. Data that cannot be fitted raise a `DataError` with the evidence: a
      `nan` or `inf` (the rows named: drop them yourself, knowing why they are there),
      columns of different lengths, fewer than 10 cycles or 10 distinct values in a column
      (a constant), a column that is not 1-D or not numbers.
    - `free`: `{name: (low, high)}`: the parameters to estimate and the box searched; a
      parameter with `low > 0` is searched on a log scale. An entry of a dict parameter is
      named with a dot, `"threshold_params.sd"`, its other entries in `fixed`.
    - `fixed`: the model's other parameters (a dotted free entry replaces its value in
      the dict fixed gives).
    - `seed`: the simulation's seed (common to every evaluated point; use one other than
      the data's when the data are simulated).
    - `n_sim`: simulated cycles per evaluation (10^5: about 0.3 s each on 2 cores).
    - `dt`: simulation step (default: a fifth of the model's slowest time scale; exact in
      law for linear-Gaussian slips at any step).
    - `t_max`: longest simulated slip (default: three times the longest slip or period in
      the data, at least 50 slow time scales).
    - `trace`: the data are the cycles of a sampled trace (`extract_cycles`; the default
      when `data` is its `Cycles`). A trace joins what it cannot see: a stick shorter than
      about 2.5 sampling intervals (zero-length ones among them) joins the slips on either
      side into one, a slip shorter than one interval (immediate re-sticks among them)
      joins the sticks; the simulated cycles are joined by the same rule
      (`visible_cycles`), and slip times, stick times and periods shorter than 5 sampling
      intervals, which the sampling times to within one interval, are left out of the data
      and of the simulated law alike. Slip distances cannot be fitted from a trace (the
      model restarts a slip from the threshold across a joined stick, a jump no trace
      shows). Without `trace` the data are per-cycle values of the model, as `simulate`
      gives them (slips of positive length).
    - `sampling`: the trace's sampling interval (with `trace` only; default: the `Cycles`'
      own).

    A `ParameterError` names a bad argument (a box the model refuses at its ends: the
    `free` entry), a `ResourceError` an `n_sim` past half this machine's memory (an estimate
    of 160 B per cycle and state component), both before anything is simulated.

    **Returns:** a `FitResult`.
    """
    wall0 = time.perf_counter()
    owner = "fit"
    Model = _model_class(model)
    if trace is not None and not isinstance(trace, (bool, np.bool_)):
        raise ParameterError(owner, "trace", "must be True or False", trace)
    from .extract import Cycles

    if isinstance(data, Cycles):
        if trace is None:
            trace = True
        if sampling is None:
            sampling = data.info.get("sampling_interval")
        # a trace's slip distances cannot be fitted (below): the Cycles' table has them
        data = {k: v for k, v in data.table.items() if not (trace and k == "slip_distance")}
    elif sampling is not None and not trace:
        raise ParameterError(
            owner,
            "sampling",
            "is only used with trace=True (the data are the cycles of a sampled trace); drop "
            "it or set trace",
            sampling,
        )
    trace = bool(trace)
    observe = None
    if trace:
        if sampling is None:
            raise ParameterError(owner, "sampling", "is required with trace=True (the trace's "
                                 "sampling interval)")  # fmt: skip
        sampling = check_positive(owner, "sampling", sampling)
        observe = dict(
            min_slip=sampling, min_stick=TRACE_STICK * sampling, cut=TRACE_CUT * sampling
        )
    if trace and hasattr(data, "keys") and "slip_distance" in data.keys():
        raise ParameterError(
            owner, "data['slip_distance']", "cannot be fitted from a trace (trace=True): the "
            "model restarts a slip from the threshold across a stick of zero length, a jump "
            "no trace shows; fit slip_time, stick_time or period",
        )  # fmt: skip
    fixed = _check_fixed(fixed, Model)
    free = _check_free(free, fixed, Model)
    seed = check_int(owner, "seed", seed, minimum=0)
    if seed >= 2**64:
        raise ParameterError(owner, "seed", "must be < 2**64", seed)
    n_sim = check_int(owner, "n_sim", n_sim, minimum=1000)
    dt = check_positive(owner, "dt", dt, allow_none=True)
    t_max = check_positive(owner, "t_max", t_max, allow_none=True)
    names = list(free)
    scales = {k: "log" if free[k][0] > 0 else "linear" for k in names}
    lo = np.array([_to_fit(scales[k], free[k][0]) for k in names])
    hi = np.array([_to_fit(scales[k], free[k][1]) for k in names])

    def params(u):
        return {k: _from_fit(scales[k], float(x)) for k, x in zip(names, u, strict=True)}

    # The model at the box's centre and at each end of each axis: a value the model refuses
    # is the box's fault, said here in one line rather than as points that quietly fail.
    centre = _check_box(Model, fixed, free, params(0.5 * (lo + hi)))
    _check_memory(n_sim, centre)
    given = data
    data = _check_data(data, observe, sampling)
    sampled = None if trace else _looks_sampled(given, data)
    if sampled is not None:  # said now: the fit may take minutes
        warnings.warn(f"fit: {sampled}", stacklevel=2)
    if observe is not None:
        observe["cut_kinds"] = [k for k in ("slip_time", "stick_time", "period") if k in data]
    given_dt, given_t_max = dt is not None, t_max is not None
    if dt is None:
        dt = 0.2 * _slow_scale(centre)
    if t_max is None:
        timed = [k for k in ("slip_time", "period") if k in data]
        longest = max(float(np.max(data[k])) for k in timed) if timed else 0.0
        t_max = max(3.0 * longest, 50.0 * _slow_scale(centre))
        origin = (
            f"3 x the data's longest {' or '.join(timed)}"
            if 3.0 * longest >= 50.0 * _slow_scale(centre)
            else "50 of the model's slowest time scales"
        )
    if t_max < dt:
        if given_t_max:
            raise ParameterError(owner, "t_max", f"must be >= dt = {dt:.4g}", t_max)
        raise ParameterError(owner, "dt", f"must be <= t_max = {t_max:.4g} ({origin})", dt)
    steps = t_max / dt
    if steps >= MAX_STEPS:
        if given_t_max:
            raise ParameterError(
                owner, "t_max", f"/ dt = {steps:.3g} steps: must be below 2**30 (dt = {dt:.4g})",
                t_max,
            )  # fmt: skip
        raise ParameterError(
            owner, "t_max", f"(by default {origin}, {t_max:.3g}) is {steps:.3g} steps of dt = "
            f"{dt:.3g}, past 2**30: "
            + ("check dt, or give t_max" if given_dt else "check the data's time unit"),
        )  # fmt: skip
    n_data = max(x.size for x in data.values())
    bandwidth = {k: _bandwidth(_transform(k, data[k]), n_sim) for k in data}
    points: list = []
    caught: list[str] = []

    def per_cycle(u, at_seed):
        try:
            m = Model(**_kwargs(fixed, params(u)))
        except (ValueError, ArithmeticError):  # inside the box, a joint constraint
            return None
        try:
            sim = _simulate(m, n_sim, dt, t_max, at_seed, observe)
        except ParameterError as err:  # simulate's names are fit's arguments
            name = {"n_paths": "n_sim"}.get(err.parameter, err.parameter)
            raise ParameterError(owner, name, err.reason, err.value) from None
        return {k: _log_density(k, data[k], sim[k], bandwidth[k]) for k in data}

    def loglik(u, at_seed=seed):
        u = np.clip(u, lo, hi)
        terms = per_cycle(u, at_seed)
        value = -np.inf if terms is None else float(sum(np.sum(v) for v in terms.values()))
        if at_seed == seed:  # the surface's points (the second seed's are in mc_noise)
            points.append((np.array([params(u)[k] for k in names]), value))
        if progress:
            import sys

            shown = ", ".join(f"{k}={v:.4g}" for k, v in params(u).items())
            print(f"fit: {shown}: log-likelihood {value:.2f}", file=sys.stderr, flush=True)
        return value, terms

    # 1. a coarse grid over the box, 2. Nelder-Mead from its best point
    start = _design(lo, hi)
    values = [loglik(u)[0] for u in start]
    if not np.any(np.isfinite(values)):
        raise ParameterError(
            owner,
            "free",
            f"the model could not be built at any of the {len(start)} starting points of the box",
            free,
        )
    best = start[int(np.argmax(values))]
    from scipy.optimize import minimize

    simplex = np.vstack([best, best + 0.15 * np.diag(hi - lo)])
    res = minimize(
        lambda u: -loglik(u)[0], best, method="Nelder-Mead",
        options=dict(xatol=0.02, fatol=np.inf, maxfev=_max_evaluations(len(names)),
                     initial_simplex=simplex),
    )  # fmt: skip
    # Converged on the simplex's size alone (fatol infinite): the simulator's draws move
    # with the parameters (a change of 1e-12 in D moved every simulated slip time, by 1e-3
    # typically), so points 1e-4 apart differ by several log-likelihood units and a value
    # tolerance (0.2 before) was never met: Nelder-Mead ran into its cap. The polynomial
    # below, on steps of 0.1, finds the maximum more precisely than 0.02 anyway.
    if res.status == 1:  # scipy: the cap on evaluations (2 is the cap on iterations)
        caught.append(
            f"Nelder-Mead stopped on its cap of {_max_evaluations(len(names))} evaluations "
            "before converging: the estimate is the polynomial vertex around its last best "
            "point; check it with a narrower box"
        )
    u_hat = np.clip(res.x, lo, hi)
    # 3. the maximum and the observed information from a polynomial fitted to the surface
    # around it: quadratic, plus a cubic term along each axis, on steps of DESIGN_STEP (wide
    # against the surface's Monte Carlo roughness; on steps of one standard error it drowned
    # the curvature, and what it leaves is measured in 4. below). The cubic terms take the
    # surface's skew out of the vertex: a quadratic alone put it 3-4 % low. Points past the
    # box are evaluated at the box (loglik clips) and so regressed where they were evaluated.
    design_steps = np.full(len(names), DESIGN_STEP)
    for attempt in range(2):
        nominal = _quadratic_design(u_hat, design_steps)
        design = np.clip(nominal, lo, hi)
        values, scores = _evaluate(design, lambda u: loglik(u), data)
        u_design = u_hat
        shift, H = _polynomial_vertex(design - u_design, np.array(values), design_steps)
        best_point = int(np.argmax(values))
        if shift is not None or attempt == 1 or best_point == 0:
            break
        # no vertex near Nelder-Mead's point (a rough surface can leave it off the
        # maximum): once more around the design's best point
        u_hat = design[best_point]
    clipped = [k for i, k in enumerate(names) if np.any(design[:, i] != nominal[:, i])]
    if clipped:
        caught.append(
            f"the surface design around the estimate reaches past the box in "
            f"{', '.join(clipped)}: those points were evaluated and regressed at the box's edge "
            "(a one-sided fit there): widen the box"
        )
    if shift is not None:
        u_hat = np.clip(u_hat + shift, lo, hi)
    else:
        caught.append(
            "the polynomial fitted to the surface has no maximum within 2 design steps of the "
            "best point found (the surface is rough or flat there): the estimate is that "
            "point, and the curvature the quadratic's"
        )
    info = -H
    if not np.all(np.linalg.eigvalsh(info) > 0):
        caught.append(
            "the log-likelihood is not concave around the estimate (the data do not pin the "
            "free parameters down, or the box holds no maximum): intervals unreliable"
        )
        info = info + np.eye(len(names)) * max(1e-9, -np.min(np.linalg.eigvalsh(info)) + 1e-9)
    cov = np.linalg.inv(info)
    if all(s is not None for s in scores):
        J = _score_outer(nominal, design, u_design, scores)
        cov = cov @ J @ cov
    else:
        caught.append("a design point failed: intervals from the Hessian alone")
    # 4. the simulation's own noise: the same design with a second, independent seed. The
    # simulator's draws move with the parameters (see Nelder-Mead above), so the surface
    # carries Monte Carlo noise that common random numbers do not cancel: measured, the two
    # seeds' vertices differed by 1-1.5 standard errors at n_sim = 2e4 for two columns,
    # far above the sqrt(n / n_sim) the widening below assumes. The estimate is the mean of
    # the two vertices, and their half difference, squared, its Monte Carlo covariance
    # (unbiased; one draw, so added on top of the widening rather than instead of it).
    seed2 = (seed + 0x9E3779B97F4A7C15) % 2**64  # far from seed: an independent stream
    values2, _ = _evaluate(design, lambda u: loglik(u, seed2), data)
    shift2, _ = _polynomial_vertex(design - u_design, np.array(values2), design_steps)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    mc_noise = _mc_noise(names, shift, shift2, se, n_sim)
    mc_noise.update(seed=seed2, log_likelihood_difference=float(values[0] - values2[0]))
    if mc_noise["warning"]:
        caught.append(mc_noise["warning"])
    cov = cov * (1.0 + n_data / n_sim)
    if shift is not None and shift2 is not None:
        half = 0.5 * (shift - shift2)
        u_hat = np.clip(u_design + 0.5 * (shift + shift2), lo, hi)
        cov = cov + np.outer(half, half)
    ll_hat, _ = loglik(u_hat)
    estimate = params(u_hat)
    ci = {}
    for i, k in enumerate(names):
        half = Z95 * math.sqrt(max(cov[i, i], 0.0))
        ci[k] = (_from_fit(scales[k], u_hat[i] - half), _from_fit(scales[k], u_hat[i] + half))
        edge = min(u_hat[i] - lo[i], hi[i] - u_hat[i]) < 0.01 * (hi[i] - lo[i])
        if edge:
            caught.append(f"{k} = {estimate[k]:.4g} is on the edge of its box {free[k]}: widen it")
    for text in caught:
        warnings.warn(f"fit: {text}", stacklevel=2)
    method = (
        f"simulated maximum likelihood ({n_sim} cycles per point, common random numbers, "
        f"smoothed kernel likelihood of {', '.join(data)}, zero durations as a point mass); "
        "95 % Wald intervals from the sandwich covariance of per-cycle scores"
    )
    diagnostics = dict(
        n_sim=n_sim, dt=dt, t_max=t_max, seed=seed, trace=trace, sampling=sampling,
        observe=observe,
        n_data={k: int(v.size) for k, v in data.items()},
        zero_fraction={k: float(np.mean(v == 0)) for k, v in data.items() if k in LOG_KINDS},
        bandwidth=bandwidth, scales=scales, covariance=cov.tolist(), hessian=H.tolist(),
        evaluations=len(points), points=points, seconds=time.perf_counter() - wall0,
        warnings=([sampled] if sampled else []) + caught,
        to_fit=lambda name, x: _to_fit(scales[name], np.asarray(x)),
        optimizer=dict(success=bool(res.success), message=str(res.message),
                       evaluations=int(res.nfev), cap=_max_evaluations(len(names))),
        design=dict(clipped=clipped, vertex=shift is not None),
        mc_noise=mc_noise,
    )  # fmt: skip
    return FitResult(
        estimate=estimate, ci=ci, log_likelihood=ll_hat, method=method,
        diagnostics=diagnostics, data=data, model=Model(**_kwargs(fixed, estimate)),
    )  # fmt: skip


# -- pieces -----------------------------------------------------------------------------
def _model_class(model):
    from ._model import ChainModel, FrictionModel
    from ._registry import get_model

    if isinstance(model, str):
        Model = get_model(model)
    elif isinstance(model, type) and issubclass(model, FrictionModel):
        Model = model
    else:
        raise ParameterError("fit", "model", "must be a model name or a FrictionModel class", model)
    if issubclass(Model, ChainModel):
        raise ParameterError(
            "fit", "model", f"{Model.__name__} is a chain of blocks: fit needs a single-block model"
        )
    return Model


def _refuse(cls, parameter: str, reason: str, value: Any = None) -> StickSlipError:
    """A `DataError` or `ResourceError` about one of fit's arguments, worded as a
    `ParameterError` is; its `parameter`, `reason` and `value` are kept on it, as a
    `ParameterError` keeps them, for callers that re-phrase it (a study's fit)."""
    got = "" if value is None else f" (got {value!r})"
    err = cls(f"fit: parameter '{parameter}' {reason}{got}")
    err.owner, err.parameter, err.reason, err.value = "fit", parameter, reason, value
    return err


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _rows(index: np.ndarray) -> str:
    """The first few of some row numbers (0-based), for a message."""
    shown = ", ".join(str(int(i)) for i in index[:5])
    more = f" and {index.size - 5} more" if index.size > 5 else ""
    return f"row{'s' if index.size > 1 else ''} {shown}{more}"


def _column(name: str, value) -> np.ndarray:
    """One column of per-cycle values as a 1-D float array, or a `DataError` that says what
    it is instead (strings, objects, a table of several columns)."""
    where = f"data['{name}']"
    try:
        x = np.asarray(value)
    except (ValueError, TypeError):  # ragged nested lists
        raise _refuse(
            DataError,
            where,
            f"must be a 1-D array of numbers, one per cycle (got a ragged {type(value).__name__})",
        ) from None
    if x.dtype.kind == "O" and all(
        isinstance(v, numbers.Real) and not isinstance(v, bool) for v in x.ravel()
    ):
        x = x.astype(float)
    if x.dtype.kind not in "iuf":
        what = {"U": "strings", "S": "bytes", "b": "booleans", "c": "complex numbers"}
        got = what.get(x.dtype.kind, type(value).__name__ if x.ndim == 0 else "other objects")
        raise _refuse(
            DataError, where, f"must hold real numbers, one per cycle (got {got}, shape {x.shape})"
        )
    if x.ndim != 1:
        raise _refuse(
            DataError,
            where,
            f"must be 1-D, one value per cycle (got shape {x.shape}"
            f"{', ' + str(x.size) + ' values' if x.ndim > 1 else ''})",
        )
    return x.astype(float)


def _check_data(data, observe=None, sampling=None) -> dict[str, np.ndarray]:
    """The known columns of a per-cycle table, as float arrays of one length (for a trace,
    without the rows whose durations fall below the cut). Unusable data are refused with the
    evidence (counts, shapes, rows), never silently dropped."""
    if not hasattr(data, "keys") or not len(data):
        raise ParameterError(
            "fit", "data", f"must be a dict of per-cycle arrays ({', '.join(KINDS)})"
        )
    cols = {k: _column(k, data[k]) for k in data.keys() if k in KINDS}
    if not cols:
        raise ParameterError(
            "fit", "data", f"has none of the columns {', '.join(KINDS)}", sorted(map(str, data))
        )
    sizes = {k: x.size for k, x in cols.items()}
    if len(set(sizes.values())) > 1:
        raise _refuse(
            DataError,
            "data",
            "columns must have one length, a row per cycle (the likelihood sums each cycle's "
            "columns; columns of different lengths are not rows of one table)",
            sizes,
        )
    for k, x in cols.items():
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise _refuse(
                DataError,
                f"data['{k}']",
                f"has {_count(bad.size, 'non-finite value')} (nan or inf) among "
                f"{_count(x.size, 'cycle')}, at {_rows(bad)}: remove or fix those cycles",
            )
        if k in ("slip_time", "period") and np.any(x <= 0):
            raise ParameterError("fit", f"data['{k}']", "must be > 0 (slips of positive length)")
        if k == "stick_time" and np.any(x < 0):
            raise ParameterError("fit", f"data['{k}']", "must be >= 0")
        if k not in LOG_KINDS and np.max(np.abs(x), initial=0.0) > MAX_LINEAR:
            raise _refuse(
                DataError,
                f"data['{k}']",
                f"reaches {np.max(np.abs(x)):.3g}, past {MAX_LINEAR:.0e}: its spread would "
                "overflow",
            )
        _check_spread(k, x)
    if observe is None:
        return cols
    keep = np.ones(next(iter(sizes.values())), bool)
    for k in ("slip_time", "stick_time", "period"):
        if k in cols:
            keep &= cols[k] > observe["cut"]
    out = {k: x[keep] for k, x in cols.items()}
    for k, x in out.items():
        _check_spread(k, x, sampling)
    return out


def _check_spread(kind: str, x: np.ndarray, sampling=None) -> None:
    """At least `MIN_CYCLES` values whose density is fitted (the positive ones, on a log
    scale, for durations) and as many distinct ones (to `DISTINCT_DIGITS`, on that scale).
    With `sampling`, `x` is what a trace's cut left: then the cut is at fault."""
    y = _transform(kind, x)
    scale = max(float(np.max(np.abs(y), initial=0.0)), 1.0 if kind in LOG_KINDS else 0.0)
    distinct = np.unique(np.round(y / (DISTINCT_DIGITS * scale))).size if scale > 0 else 1
    distinct = min(distinct, y.size)
    if y.size >= MIN_CYCLES and distinct >= MIN_CYCLES:
        return
    evidence = _count(x.size, "cycle")
    if y.size < x.size:
        evidence += f", {y.size} of them positive (a log scale is fitted)"
    evidence += f", {_count(distinct, 'distinct value')}"
    if sampling is not None:
        raise ParameterError(
            "fit",
            "sampling",
            f"leaves {evidence} of {kind} above the trace's cut, {TRACE_CUT:g} x sampling = "
            f"{TRACE_CUT * sampling:.4g}; {MIN_CYCLES} are needed: check the sampling interval",
            sampling,
        )
    if x.size < MIN_CYCLES:
        what = "has too few cycles"
    elif y.size < MIN_CYCLES:
        what = "has too few positive values"
    else:
        what = "is constant" if distinct == 1 else "has too few distinct values"
    raise _refuse(
        DataError,
        f"data['{kind}']",
        f"{what}: {evidence}; a density needs at least {MIN_CYCLES} of each (its kernel's "
        "bandwidth comes from the data's spread)",
    )


def _check_fixed(fixed, Model) -> dict[str, Any]:
    if fixed is None:
        return {}
    if not hasattr(fixed, "items"):
        raise ParameterError("fit", "fixed", "must be a dict {name: value}", fixed)
    known = Model.parameters()
    for k in fixed:
        if k not in known:
            raise ParameterError(
                "fit",
                f"fixed['{k}']",
                f"is not a parameter of {Model.__name__} (parameters: {', '.join(known)})",
            )
    return dict(fixed)


def _check_free(free, fixed, Model) -> dict[str, tuple[float, float]]:
    """The boxes, checked; a dotted name (`"threshold_params.sd"`) is an entry of a dict
    parameter, whose other entries `fixed` holds (a value `fixed` gives it too is replaced:
    a study's `model.params` names a complete model)."""
    if not hasattr(free, "items") or not free:
        raise ParameterError("fit", "free", "must be a non-empty dict {name: (low, high)}", free)
    known = Model.parameters()
    out = {}
    for k, box in free.items():
        head, _, entry = str(k).partition(".")
        if head not in known:
            raise ParameterError(
                "fit",
                f"free['{k}']",
                f"is not a parameter of {Model.__name__} (parameters: {', '.join(known)})",
            )
        if entry and not hasattr(fixed.get(head), "items"):
            raise ParameterError(
                "fit",
                f"free['{k}']",
                f"names an entry of {head}, which fixed must give as a dict of its other entries",
            )
        try:
            low, high = (float(b) for b in box)
        except (TypeError, ValueError):
            raise ParameterError("fit", f"free['{k}']", "must be a pair (low, high)", box) from None
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise ParameterError("fit", f"free['{k}']", "must be finite with low < high", box)
        if k in fixed:
            raise ParameterError("fit", f"free['{k}']", "is also fixed")
        if not entry and any(str(j).startswith(f"{k}.") for j in free):
            raise ParameterError("fit", f"free['{k}']", "is free with one of its own entries")
        out[str(k)] = (low, high)
    return out


def _kwargs(fixed: dict, values: dict) -> dict[str, Any]:
    """The model's keyword arguments: `fixed` with the free `values` set, a dotted name
    into its dict parameter (copied, so `fixed` is left as given)."""
    out = dict(fixed)
    for k, v in values.items():
        head, _, entry = k.partition(".")
        if entry:
            out[head] = {**out[head], entry: v}
        else:
            out[k] = v
    return out


def _check_box(Model, fixed, free, centre: dict):
    """The model at the box's centre, after building it there and at both ends of each
    axis: a value it refuses is a `ParameterError` naming the free parameter's box."""
    trials = [(None, centre)] + [(k, {**centre, k: b}) for k in free for b in free[k]]
    for name, values in trials:
        try:
            model = Model(**_kwargs(fixed, values))
        except TypeError as err:  # a required parameter neither fixed nor free
            raise ParameterError(
                "fit",
                "fixed",
                f"with free does not make a {Model.__name__}: {str(err).splitlines()[0]}",
            ) from None
        except (ValueError, ArithmeticError) as err:
            culprit = name or (err.parameter if isinstance(err, ParameterError) else None)
            if isinstance(err, ParameterError):
                reason = f"{err.owner} says {err.parameter} {err.reason}"
            else:
                reason = f"{type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}"
            if culprit in free:
                raise ParameterError(
                    "fit",
                    f"free['{culprit}']",
                    f"reaches {culprit} = {values[culprit]:.4g}, where {reason}: narrow the box",
                    free[culprit],
                ) from None
            where = f"fixed['{culprit}']" if culprit in fixed else "fixed"
            raise ParameterError(
                "fit",
                where,
                f"with free at the box's centre does not make a {Model.__name__} ({reason})",
            ) from None
        if name is None:
            built = model
    return built


def _memory_limit() -> int:
    """The simulator's memory limit (`driver.memory_limit`: half this machine's memory, or
    `STICKSLIP_MEMORY_LIMIT`), so that a fit and a plain simulation refuse alike."""
    from ._simulate.driver import memory_limit

    return int(memory_limit())


def _check_memory(n_sim: int, model) -> None:
    need = n_sim * SIM_BYTES_PER_STATE * model.state_dim
    limit = _memory_limit()
    if need > limit:
        raise _refuse(
            ResourceError,
            "n_sim",
            f"needs about {need / 2**30:.3g} GiB per evaluated point "
            f"({SIM_BYTES_PER_STATE * model.state_dim} B a simulated cycle), past the limit of "
            f"{limit / 2**30:.3g} GiB (half this machine's memory, or STICKSLIP_MEMORY_LIMIT): "
            f"take at most "
            f"{limit // (need // n_sim):.3g}",
            n_sim,
        )
    if n_sim > MAX_SIM_PATHS:
        raise ParameterError(
            "fit", "n_sim", "must be < 2**32 (the simulator numbers its paths with 32 bits)", n_sim
        )


def _to_fit(scale, x):
    return np.log(x) if scale == "log" else x


def _from_fit(scale, u):
    return float(np.exp(u)) if scale == "log" else float(u)


def _slow_scale(model) -> float:
    from ._model import time_scales

    scales = time_scales(model)
    return 1.0 if scales is None else scales[1]


def _simulate(model, n, dt, t_max, seed, observe=None) -> dict[str, np.ndarray]:
    """Simulated cycles as the data see them: slips of positive length that ended (per
    cycle), or, with `observe` (a trace's), the cycles of one long sampled trace
    (`visible_cycles`), without those whose durations fall below the cut."""
    from ._simulate import simulate

    e = simulate(model, n, dt, t_max, seed, progress=False)
    if observe is not None:
        vis = visible_cycles(e.slip_time, e.stick_time, observe["min_slip"], observe["min_stick"])
        keep = np.all([vis[k] > observe["cut"] for k in observe["cut_kinds"]], axis=0)
        return {k: v[keep] for k, v in vis.items()}
    keep = e.stuck & ~e.immediate  # what a trace shows: slips of positive length that ended
    return {k: np.asarray(getattr(e, k))[keep] for k in KINDS}


def visible_cycles(slip_time, stick_time, min_slip=0.0, min_stick=0.0) -> dict[str, np.ndarray]:
    """The cycles a trace shows when independent cycles (`slip_time`, `stick_time` in
    order; `nan` for a slip cut at `t_max`) follow one another: a stick no longer than
    `min_stick` (zero-length ones at least) joins the slips on either side into one, a slip
    no longer than `min_slip` (immediate re-sticks at least) joins the sticks on either
    side. Returns `slip_time`, `stick_time` and `period` of each
    complete visible cycle (a cut slip ends the cycles around it; the first and last are
    dropped as a trace's would be); `slip_distance` is `nan` (across a joined stick the
    model restarts its slip from the threshold, a jump no trace shows)."""
    slip = np.asarray(slip_time, float)
    stick = np.asarray(stick_time, float)
    durations = np.stack([slip, stick], axis=1).ravel()  # slip 1, stick 1, slip 2, ...
    kinds = np.tile([0, 1], slip.size)
    shortest = np.tile([min_slip, min_stick], slip.size)
    show = ~(durations <= shortest)  # nan (a cut slip) stays, and poisons its run
    durations, kinds = durations[show], kinds[show]
    starts = np.r_[True, kinds[1:] != kinds[:-1]]
    run_kind = kinds[starts]
    run_length = np.add.reduceat(durations, np.nonzero(starts)[0]) if durations.size else durations
    first = 1 if run_kind.size and run_kind[0] == 1 else 0  # a visible cycle starts with a slip
    run_kind, run_length = run_kind[first:], run_length[first:]
    m = run_kind.size // 2
    vis_slip, vis_stick = run_length[0 : 2 * m : 2], run_length[1 : 2 * m : 2]
    vis_slip, vis_stick = vis_slip[1:-1], vis_stick[1:-1]  # the trace's ends are cut
    ok = np.isfinite(vis_slip) & np.isfinite(vis_stick)
    vis_slip, vis_stick = vis_slip[ok], vis_stick[ok]
    return dict(
        slip_time=vis_slip, stick_time=vis_stick, period=vis_slip + vis_stick,
        slip_distance=np.full(vis_slip.size, np.nan),
    )  # fmt: skip


def _transform(kind, x):
    if kind in LOG_KINDS:
        x = x[x > 0]
        return np.log(x)
    return x


def _bandwidth(y, n_sim) -> float:
    iqr = np.subtract(*np.percentile(y, [75, 25])) / 1.349
    spread = min(np.std(y), iqr) if iqr > 0 else np.std(y)
    return float(0.9 * max(spread, 1e-12) * n_sim ** (-0.2))


def _zero_fraction(sim: np.ndarray) -> float:
    r"""The simulated fraction of zeros, $p_0 = (k + 1/2)/(n + 1)$ for $k$ zeros among $n$
    finite values: the Jeffreys-type half count keeps $\log p_0$ and $\log(1 - p_0)$ finite
    when no simulated value (or every one) is zero, and differs from $k/n$ by less than
    $1/n$."""
    finite = sim[np.isfinite(sim)]
    return (np.count_nonzero(finite == 0) + 0.5) / (finite.size + 1)


def _log_density(kind, x, sim, h):
    r"""Per-cycle contributions to the smoothed log-likelihood, one per datum. For a positive
    datum $y_i$ (on the kind's scale), $\int K_h(y - y_i) \log \hat f(y)\,dy$, where
    $\hat f = f_	heta * K_h$ is the kernel estimate of the simulated positive values.
    Smoothing the data with the same kernel as the model keeps the estimator consistent at
    a fixed bandwidth: the expected value, $\int (f_0 * K_h) \log (f_	heta * K_h)$, is
    largest at the true $	heta$ (Gibbs' inequality), where the kernel estimate evaluated
    at the raw data is biased by the smoothing (measured: D 14 % low on the public set). A
    mixture weight 1/n_sim of a broad normal keeps a datum far from every simulated value
    finite.

    A duration's law has an atom at 0 (a stick of zero length: 38 % of the public set's):
    a zero datum contributes $\log p_0$, a positive one $\log(1 - p_0)$ plus the density
    of the positive values, with $p_0$ the simulated fraction of zeros (`_zero_fraction`).
    Dropping the zeros instead biased D to 0.227 for a truth of 0.4 from stick times."""
    x = np.asarray(x, float)
    out = np.empty(x.size)
    positive = x > 0 if kind in LOG_KINDS else np.ones(x.size, bool)
    y = _transform(kind, x)
    s = _transform(kind, sim[np.isfinite(sim)])
    n = max(s.size, 1)
    # The grid spans the data (fixed for every theta): simulated values past it count in n
    # but add no density there (they lie over 8 bandwidths from every datum). A grid that
    # spanned the simulated values moved with the smallest of them (a stick of 1e-6 is -14
    # on the log scale) and the binning with it: the surface jumped ~10 units between
    # parameters 1e-4 apart, and Nelder-Mead ran into its cap.
    lo, hi = y.min() - 8 * h, y.max() + 8 * h
    edges = np.linspace(lo, hi, KDE_BINS + 1)
    dx = edges[1] - edges[0]
    half = max(1, int(math.ceil(6 * h / dx)))
    k = np.arange(-half, half + 1) * dx
    kernel = np.exp(-0.5 * (k / h) ** 2)
    kernel /= kernel.sum()
    counts = np.histogram(s, edges)[0].astype(float)
    f = np.convolve(counts, kernel, mode="same") / (n * dx)
    centres = 0.5 * (edges[1:] + edges[:-1])
    mu, sd = np.mean(y), 3.0 * max(np.std(y), h)
    broad = np.exp(-0.5 * ((centres - mu) / sd) ** 2) / (sd * math.sqrt(2 * math.pi))
    eps = 1.0 / n
    smoothed_log = np.convolve(np.log((1 - eps) * f + eps * broad), kernel, mode="same")
    logf = np.interp(y, centres, smoothed_log)
    if kind in LOG_KINDS:
        p0 = _zero_fraction(sim)
        logf = logf - y + math.log1p(-p0)  # the density of x = exp(y), given x > 0
        out[~positive] = math.log(p0)
    out[positive] = logf
    return out


def _design(lo, hi):
    p = lo.size
    if p <= 2:
        axes = [np.linspace(a, b, GRID_POINTS + 2)[1:-1] for a, b in zip(lo, hi, strict=True)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, p)
    from scipy.stats import qmc

    return qmc.scale(qmc.Sobol(p, seed=0).random(8 * p), lo, hi)


def _quadratic_design(u, steps):
    """The centre, 4 points along each axis (+-1, +-2 steps) and 4 diagonal points per pair."""
    p = u.size
    pts = [u]
    for i in range(p):
        for m in (-2, -1, 1, 2):
            e = np.zeros(p)
            e[i] = m * steps[i]
            pts.append(u + e)
        for j in range(i + 1, p):
            for a, b in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                e = np.zeros(p)
                e[i], e[j] = a * steps[i], b * steps[j]
                pts.append(u + e)
    return np.array(pts)


def _polynomial_vertex(du, values, steps):
    """Fit c + g.du + du.Q.du / 2 + sum_i k_i du_i^3 by least squares; return the vertex
    nearest the centre (Newton from 0, `None` if it leaves two steps) and the Hessian there
    (the quadratic's alone if there is no vertex)."""
    p = du.shape[1]
    ok = np.isfinite(values)
    cols = [np.ones(len(du))] + [du[:, i] for i in range(p)]
    pairs = [(i, j) for i in range(p) for j in range(i, p)]
    cols += [du[:, i] * du[:, j] * (0.5 if i == j else 1.0) for i, j in pairs]
    cols += [du[:, i] ** 3 for i in range(p)]
    coef = np.linalg.lstsq(np.stack(cols, axis=1)[ok], values[ok], rcond=None)[0]
    g = coef[1 : 1 + p]
    Q = np.zeros((p, p))
    for (i, j), v in zip(pairs, coef[1 + p : 1 + p + len(pairs)], strict=True):
        Q[i, j] = Q[j, i] = v
    k = coef[1 + p + len(pairs) :]
    x = np.zeros(p)
    for _ in range(20):
        grad = g + Q @ x + 3 * k * x**2
        hess = Q + np.diag(6 * k * x)
        try:
            step = np.linalg.solve(hess, -grad)
        except np.linalg.LinAlgError:
            return None, Q
        x = x + step
        if np.any(np.abs(x) > 2 * steps):
            return None, Q
        if np.all(np.abs(step) < 1e-6 * steps):
            break
    return x, Q + np.diag(6 * k * x)


def _evaluate(design, loglik, data):
    """The log-likelihood at each design point and its per-cycle terms summed over the
    columns (a cycle's score: the columns of one cycle are dependent)."""
    values, scores = [], []
    for u in design:
        v, terms = loglik(u)
        values.append(v)
        scores.append(None if terms is None else np.sum([terms[k] for k in data], axis=0))
    return values, scores


def _score_outer(nominal, design, u_hat, scores):
    """J = sum over cycles of the outer product of per-cycle scores (differences between
    the design's +-1 step points along each axis, over their distance where they were
    evaluated: clipped at the box, a point is nearer), centred."""
    p = u_hat.size
    grads = []
    for i in range(p):
        d = nominal - u_hat
        axis = np.all(np.isclose(np.delete(d, i, axis=1), 0), axis=1)
        ends = np.flatnonzero(axis & (np.abs(d[:, i]) > 0))
        ends = ends[np.argsort(np.abs(d[ends, i]))][:2]  # the +-1 step points
        plus, minus = sorted(ends, key=lambda j: -d[j, i])
        width = design[plus, i] - design[minus, i]
        if width <= 0:  # a box narrower than the design: no difference to take
            grads.append(np.zeros_like(scores[0]))
            continue
        grads.append((scores[plus] - scores[minus]) / width)
    G = np.stack(grads, axis=1)
    G = G - G.mean(axis=0)
    return G.T @ G


def _max_evaluations(p: int) -> int:
    """Nelder-Mead's cap: MAXFEV_PER_PARAMETER a free parameter (30 a parameter, with a
    value tolerance the rough surface never met, was hit in most two-parameter fits)."""
    return MAXFEV_PER_PARAMETER * p


def _mc_noise(names, shift, shift2, se, n_sim) -> dict[str, Any]:
    """The Monte Carlo sd of the estimate (the mean of two seeds' vertices: |difference|
    / 2) against the standard error; a warning when it passes MC_RATIO_WARN of it, with the
    n_sim that would bring it to MC_RATIO_GOAL (its variance falls as 1/n_sim)."""
    out: dict[str, Any] = dict(warning=None)
    if shift is None:
        return out
    if shift2 is None:
        out["warning"] = (
            "with a second seed the surface has no maximum near the estimate: the simulation "
            f"noise is comparable with the likelihood's curvature; take n_sim >= {4 * n_sim}"
        )
        return out
    sd = 0.5 * np.abs(shift - shift2)
    ratio = sd / np.maximum(se, 1e-300)
    worst = int(np.argmax(ratio))
    need = n_sim * (ratio[worst] / MC_RATIO_GOAL) ** 2
    out.update(
        sd={k: float(v) for k, v in zip(names, sd, strict=True)},
        ratio={k: float(v) for k, v in zip(names, ratio, strict=True)},
        n_sim_needed=int(float(f"{max(need, n_sim):.2g}")),
    )
    if ratio[worst] > MC_RATIO_WARN:
        out["warning"] = (
            f"the simulation noise is comparable with the likelihood's curvature: its sd in "
            f"{names[worst]}'s estimate (two seeds) is {ratio[worst]:.2g} standard errors; "
            f"the interval includes it; take n_sim >= {out['n_sim_needed']:.2g} (now {n_sim})"
        )
    return out


def _looks_sampled(given, cols: dict[str, np.ndarray]) -> str | None:
    """A warning when data given as per-cycle truths (a dict) look like the cycles of a
    sampled trace, which a trace's measurement would have to model (pass the `Cycles`)."""
    meta = getattr(given, "attrs", None)
    interval = getattr(given, "sampling_interval", None)
    if interval is None and hasattr(meta, "get"):
        interval = meta.get("sampling_interval")
    advice = (
        "a dict is fitted as per-cycle values of the model; pass the Cycles from "
        "extract_cycles (or trace=True, sampling=...) so the measurement is modelled"
    )
    if interval is not None:
        return f"the data carry a sampling interval ({interval!r}) but {advice}"
    durations = [cols[k] for k in ("slip_time", "stick_time", "period") if k in cols]
    pooled = np.unique(np.concatenate(durations)) if durations else np.array([])
    pooled = pooled[pooled > 0]
    if pooled.size >= MIN_CYCLES:
        step = float(np.min(np.diff(np.r_[0.0, pooled])))
        ratio = pooled / step
        if step > 1e-9 * pooled[-1] and np.all(np.abs(ratio - np.round(ratio)) < 1e-3):
            return f"every duration is a multiple of {step:.4g} (a sampled trace's grid): {advice}"
    if "release_time" in getattr(given, "keys", lambda: ())() and "stick_time" in cols:
        if cols["stick_time"].size >= MIN_CYCLES and np.all(cols["stick_time"] > 0):
            return (
                f"the data have release times and no stick of zero length in "
                f"{cols['stick_time'].size} cycles, as cycles extracted from a trace do: {advice}"
            )
    return None
