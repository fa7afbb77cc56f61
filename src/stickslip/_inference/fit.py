r"""`fit`: friction-noise parameters from measured per-cycle statistics, and whether the
model reproduces the data at all.

`fit` is the simulated maximum-likelihood estimator (`estimator.simulated_mle`: the data and
their measurement, the parameters and their box, the simulated likelihood, its maximum and
curvature, the intervals) followed, with `check=True`, by a simulation-calibrated
goodness-of-fit test (`goodness`).

What it assumes: independent cycles (the paper's sharp reset: every slip starts from the
model's onset state), the model family is right (`check` tests it), and the maximum lies
inside the `free` box. Cycles extracted from a trace (a `Cycles`) are fitted with the
measurement inside the forward model (`measurement`). Nothing fails silently: a one-line
warning each (also in `diagnostics.warnings`) when Nelder-Mead stops on its cap, the
estimate sits on an edge, the polynomial has no vertex near the best point, design points
are clipped at the box, the simulation noise is comparable with the curvature, a dict of
data looks like the cycles of a sampled trace, or the data reject the model.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from typing import TYPE_CHECKING

import numpy as np

from .._errors import ParameterError
from .._trace_kind import kind_of_signal
from .estimator import simulated_mle
from .goodness import ALPHA, MIN_VERDICT_REP, goodness_of_fit
from .result import FitResult

if TYPE_CHECKING:
    from .._extract import Cycles


def fit(
    model,
    data: dict | Cycles | list,
    free: dict,
    fixed: dict | None = None,
    *,
    seed: int = 0,
    n_sim: int | None = None,
    dt: float | None = None,
    t_max: float | None = None,
    scales=None,
    check: bool = True,
    progress: bool = False,
    trace: bool | None = None,
    sampling: float | None = None,
    intervals: str = "wald",
) -> FitResult:
    r"""Estimate the `free` parameters of `model` from per-cycle data.

    **Arguments:**

    - `model`: a model name (`"langevin"`) or class with a linear-Gaussian slip or not
      (any model `simulate` runs; exact stepping where it applies). A creeping slider
      (`"rate-and-state"`, in SI) is fitted to the `Cycles` of one force trace only,
      through its measurement, as its stationary motion: each simulated path leaves out
      the time its noise-free motion takes to settle from the onset (`measured_cycles`);
      its units follow from its fixed `stiffness` (`Scales.si`: leave `scales` out), its
      `n_sim` counts periods of its noise-free cycle, and its sticks are not checked
      against `v_b` (they creep: the loading slope is a little below the drive's).
    - `data`: the cycles, one row per cycle, any of the columns `slip_time`,
      `slip_distance`, `stick_time` (zeros included: a point mass), `period`, all of one
      length, fitted jointly. Either
      - a `Cycles` (from `extract_cycles`, or `read_cycles` of its CSV): the cycles of a
        measured trace, which carry their measurement (`Measurement.from_cycles`: the
        sampling interval, the noise, the extraction's settings). The model is then
        simulated as a continuous trace, sampled at the data's interval with the data's
        noise, and its cycles extracted with the data's settings (`measured_cycles`), so
        that data and model are compared like with like: what the sampling joins (short
        sticks, immediate re-sticks) or mistimes is joined and mistimed in the simulated
        cycles alike. Its `release_time` is not fitted; or
      - a dict of per-cycle arrays: *per-cycle values of the model* (as `simulate` gives
        them: no measurement). A dict that looks sampled (durations on one grid, a
        `sampling_interval` attribute, or release times with no stick of zero length, as
        an extracted table has) gets a warning: pass the `Cycles` instead.

      A force trace's `Cycles` (in s, m and N, with `scales`) is put in the model's units
      (as `Slider.to_model` does): its `force_drop` is its `slip_distance` times k, one
      column in the model's units (fit `slip_distance`); `peak_force`, the absolute force
      level, is not fitted. A fixed `v_b` more than 2 % off the sticks' loading speed in
      the data (`info["v_b_estimated"]`) gets a warning.

      Or **several runs**, a list: each a stick-slip `Run` of `analyse_run(...,
      mass=m)` (its `slip_time`, `stick_time` and `slip_distance` fitted, in the units of
      `Slider.from_cycles(run.cycles, mass=m)`) or a pair `(Cycles, Slider)` of a force
      trace's cycles (their columns fitted) and its reference slider. One set of
      physical parameters is fitted to all of them, each run through its own
      measurement, spring and speed: `free` and `fixed`
      then name the slider's SI values (`mass`, `damping`, `noise`, `noise_time`,
      `static_friction`, `kinetic_friction`, `threshold.mean`, `threshold.sd`, ...),
      mapped into each run's units by `Slider.model_parameters`; a value neither free nor
      fixed is each run's own (its reference slider's), and `NAME[i]` run i's own value
      of NAME over the shared one. The model is `langevin` or a
      threshold model (`random-threshold`, `random-threshold-held`); the estimate is in
      SI; `diagnostics.runs` has each run's spring, speed, cycles, fitted model and,
      with `check`, a KS p-value per observable against the fitted model's cycles through
      its measurement (not corrected for the fit: a low one rejects). The cycles see
      only the gap $F_s - F_k - cV$: fix `kinetic_friction` and fit `static_friction`.

      Data that cannot be fitted raise a `DataError` with the evidence: a `nan` or `inf`
      (the rows named: drop them yourself, knowing why they are there), columns of
      different lengths, fewer than 10 cycles or 10 distinct values in a column (a
      constant), a column that is not 1-D or not numbers.
    - `free`: `{name: (low, high)}`: the parameters to estimate and the box searched; a
      parameter with `low > 0` is searched on a log scale. An entry of a dict parameter is
      named with a dot, `"threshold_params.sd"`, its other entries in `fixed`.
    - `fixed`: the model's other parameters (a dotted free entry replaces its value in
      the dict fixed gives).
    - `seed`: the simulation's seed (common to every evaluated point; use one other than
      the data's when the data are simulated).
    - `n_sim`: simulated cycles per evaluation. Default 10^5 for per-cycle data (about
      0.3 s each on 2 cores); 4000 model cycles for a `Cycles` (a measured trace costs
      ~40 times more a cycle: recorded slips, sampling, extraction; 4000 take about a
      second, and about 60 % of them survive the measurement's joins as measured cycles).
    - `dt`: simulation step (per-cycle data: default a fifth of the model's slowest time
      scale, exact in law for linear-Gaussian slips at any step; a `Cycles`: default half
      the sampling interval, within an eighth and a half of the fastest time scale, since
      the recorded slips are interpolated onto the sampling grid).
    - `t_max`: longest simulated slip (per-cycle data only; default three times the
      longest slip or period in the data, at least 50 slow time scales).
    - `scales`: for a `Cycles` of a force trace in seconds and newtons, the model's units:
      a `stickslip.units.Scales` or a `Slider` (`Measurement.from_cycles`).
    - `check`: test the fitted model against the data (`goodness_of_fit` with its default
      replicates, 100 for a `Cycles`, seeded from `seed`): the result's `goodness` and
      `p_values`, and a one-line warning naming the observables whose p-value is below
      0.01 (the data reject the model). `False` skips it (`p_values` is then `None`).
    - `progress`: print each evaluated point's log-likelihood to stderr.
    - `intervals`: `"wald"` (default): 95 % intervals from the sandwich covariance over
      the surface's design about the estimate, with the simulation's noise; none where
      that surface has no maximum near the estimate (a warning says why). `"profile"`:
      from the profile likelihood, each parameter held at values either side and the
      others maximised (the threshold adjusted for the composite likelihood and the
      simulation's noise): it follows a ridge that the design's quadratic does not, and
      gives an interval where the Wald rule gives none; about one more fit's worth of
      evaluations per free parameter. `diagnostics.profile` has what it evaluated, and
      each parameter's Wald interval.
    - `trace`, `sampling`: deprecated (a `DeprecationWarning`), replaced by the measurement
      a `Cycles` carries: pass the `Cycles`. `trace=False` with a `Cycles` still fits its
      table as per-cycle values (pass `cycles.table` instead); `trace=True` with a dict is
      refused (a dict has no extraction settings to model).

    A parameter value whose simulated trace shows no cycles through the measurement (e.g.
    a sampling too coarse for its slips) has log-likelihood $-\infty$: the search moves
    away from it.

    A `ParameterError` names a bad argument (a box the model refuses at its ends: the
    `free` entry), a `ResourceError` an `n_sim` past half this machine's memory (an estimate
    of 160 B per cycle and state component), both before anything is simulated.

    **Returns:** a `FitResult`.
    """
    wall0 = time.perf_counter()
    if not isinstance(check, (bool, np.bool_)):
        raise ParameterError("fit", "check", "must be True or False", check)
    if intervals not in INTERVALS:
        raise ParameterError("fit", "intervals", f"must be one of {', '.join(INTERVALS)}",
                             intervals)  # fmt: skip
    if isinstance(data, (list, tuple)):
        return _joint(model, data, free, fixed, seed=seed, n_sim=n_sim, dt=dt, scales=scales,
                      check=check, progress=progress, wall0=wall0,
                      intervals=intervals)  # fmt: skip
    from .._model import CreepingSlider
    from .params import model_class

    # (a creeping slider loads its sticks slower than v_b, creeping: its own trace is read
    # by the same extraction)
    creeping = issubclass(model_class(model), CreepingSlider)
    loading = None if creeping else _loading_speed_mismatch(data, fixed, scales)
    if loading is not None:  # said now: the fit may take minutes
        warnings.warn(f"fit: {loading}", stacklevel=2)
    result = simulated_mle(
        model, data, free, fixed, seed=seed, n_sim=n_sim, dt=dt, t_max=t_max, scales=scales,
        trace=trace, sampling=sampling, progress=progress, intervals=intervals,
    )  # fmt: skip
    if loading is not None:
        result.diagnostics.warnings.insert(0, loading)
    return _checked(result, seed, wall0) if check else result


def _joint(
    model, data, free, fixed, *, seed, n_sim, dt, scales, check, progress, wall0, intervals="wald"
):
    """`fit` of one SI parameter set to several runs (`joint`)."""
    from .._model import CreepingSlider
    from .joint import CreepingRuns, Runs
    from .params import model_class

    Model = model_class(model)
    creeping = issubclass(Model, CreepingSlider)
    if scales is not None:
        raise ParameterError(
            "fit", "scales", "applies to one run: with several, each run's reference Slider "
            "sets its units (a Run's own, or the Slider of a (Cycles, Slider) pair)"
            if not creeping else f"must be left out for {Model.__name__}: a creeping slider "
            "is in SI, each run's units follow from its stiffness",
        )  # fmt: skip
    runs = (CreepingRuns if creeping else Runs)(Model, data)
    result = simulated_mle(model, None, free, fixed, seed=seed, n_sim=n_sim, dt=dt,
                           progress=progress, runs=runs, intervals=intervals)  # fmt: skip
    if check:
        d = result.diagnostics
        runs.p_values(result, d.n_sim, (seed + 1) % 2**64)
        low = [f"{row['name']} {k} p = {p:.3g}" for row in d.runs
               for k, p in row["p_values"].items() if p < ALPHA]  # fmt: skip
        if low:
            text = (f"the data reject the model: {', '.join(low)} < {ALPHA} (KS against the "
                    "fitted model's cycles through that run's measurement)")  # fmt: skip
            d.warnings.append(text)
            warnings.warn(f"fit: {text}", stacklevel=3)
    result.diagnostics.seconds = time.perf_counter() - wall0
    return result


# How `fit` reads its intervals (`intervals=`).
INTERVALS = ("wald", "profile")


# A model driven this far from the data's loading speed loads its sticks visibly faster or
# slower (stick times scale as 1/v_b): extract_cycles warns at the same 2 % (_force._VB_WARN).
LOADING_TOLERANCE = 0.02


def _loading_speed_mismatch(data, fixed, scales) -> str | None:
    """A warning when the cycles of a force trace were loaded at a speed (the sticks' slope,
    `info["v_b_estimated"]`, in SI) other than the fixed `v_b` of the model (in the model's
    units: times `scales.velocity`): a nominal driving speed where the rig's spring or
    speed is off by a few per cent puts every stick time off by as much."""
    info = getattr(data, "info", None)
    if not hasattr(info, "get") or not hasattr(fixed, "get") or scales is None:
        return None
    info = info.get("si", info) if hasattr(info.get("si"), "get") else info
    measured, v_b = info.get("v_b_estimated"), fixed.get("v_b")
    velocity = getattr(getattr(scales, "scales", scales), "velocity", None)
    kind = kind_of_signal(info.get("input"))
    if kind is None or not kind.in_si or velocity is None:
        return None
    try:
        ratio = float(v_b) * float(velocity) / float(measured)
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    if not np.isfinite(ratio) or abs(ratio - 1.0) <= LOADING_TOLERANCE:
        return None
    return (
        f"the model's v_b = {float(v_b):.4g} ({float(v_b) * float(velocity):.4g} m/s) is "
        f"{100 * (ratio - 1):+.0f} % off the speed the data's sticks were loaded at "
        f"({float(measured):.4g} m/s, cycles.info['v_b_estimated']): stick times scale as "
        "1/v_b; fix v_b at the measured loading speed (over scales.velocity)"
    )


# Replicates of the goodness-of-fit check for a fit through a measurement: the fewest that
# allow a verdict at ALPHA = 0.01 (the smallest p-value is 1/(n_rep + 1)); each replicate is
# a data set of measured cycles, ~40 times the cost of per-cycle ones (the default 200 would
# take over 3 minutes for 3000 cycles).
MEASURED_N_REP = MIN_VERDICT_REP


def _checked(result: FitResult, seed: int, wall0: float) -> FitResult:
    """`result` with its goodness of fit (`goodness_of_fit`, its own warnings kept in
    `goodness.warnings`), and one warning, also in the diagnostics, when the data reject
    the model."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # a seed of its own: the goodness check's streams are drawn from [seed, 0]
        measured = result.diagnostics.measurement is not None
        extra = dict(n_rep=MEASURED_N_REP) if measured else {}
        g = goodness_of_fit(result, seed=seed % 2**63, **extra)
    low = {k: p for k, p in g.p_values.items() if p < ALPHA}
    d = result.diagnostics
    if low:
        shown = ", ".join(f"{k} p = {p:.3g}" for k, p in low.items())
        text = (
            f"the data reject the model: {shown} < {ALPHA} (the data's distribution is unlike "
            f"the fitted {type(result.model).__name__}'s: see FitResult.plot)"
        )
        d.warnings.append(text)
        warnings.warn(f"fit: {text}", stacklevel=3)
    d.seconds = time.perf_counter() - wall0
    return dataclasses.replace(result, goodness=g)
