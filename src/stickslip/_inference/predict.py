r"""A fitted slider at another spring and speed: `FitResult.predict`.

A fit to a force trace in SI (`fit(..., cycles, scales=slider)`) estimates the model in
the units of its reference `Slider`; `Slider.si_parameters` reads the estimate as physical
quantities: the effective mass $m/\omega_0^2$ (a fitted natural frequency at the rig's
stiffness), the damping $c$, the noise intensity $S$ and its correlation time, the static
threshold in newtons. A prediction keeps those and changes what the experimenter sets, the
spring's stiffness $k$ and the driving speed $V$: the slider at $(k, V)$ is simulated in
its own units and its cycles given in SI, through a measured run's own measurement when a
run is given (its sampling, noise, spikes, lines and extraction settings, at its stiffness
and loading speed), with a predictive p-value per observable against the run's cycles.

The p-values are two-sample Kolmogorov-Smirnov tests of the run's cycles against the
predicted ones at the estimate (a plug-in check: the estimate's own uncertainty is not
propagated, so they are somewhat small when the fit's intervals are wide).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from .._errors import ParameterError, StickSlipError, check_int, check_positive
from .._trace_kind import kind_of_signal
from .measurement import Measurement

OWNER = "FitResult.predict"
# The parameters `Slider.si_parameters` maps; the others of a model (`eta0`) are settings.
_PHYSICAL = ("omega0", "zeta", "D", "tau", "v_b", "x0", "threshold", "threshold_params")
# What a run's cycles are compared in: the force trace's columns, in SI.
_OBSERVABLES = ("stick_time", "slip_time", "force_drop")
# A prediction without a run: at least this many independent cycles (`Slider.simulate`).
_N_CYCLES = 4000
_STUCK = 0.5  # a slider whose cycles stick again in at least this share: stick-slip


@dataclasses.dataclass(frozen=True, eq=False)
class Prediction:
    """What a fitted model predicts at a stiffness and driving speed (`FitResult.predict`).

    - `slider`: the predicted slider in SI (the fit's physical parameters at `stiffness`
      and `v_b`; for a creeping slider, the fitted model at them);
    - `regime`: `"stick-slip"`; `"no stick"` where the slider does not stick again within
      the simulated time; `"steady sliding"` where a creeping slider's noise-free motion
      settles into it; `"unresolved"` where the run's measurement shows no cycles of
      the predicted slider (its p-values are then 0); and `evidence`, the numbers or the
      extraction's reason that decided it;
    - `cycles`: the predicted per-cycle values in SI (`stick_time`, `slip_time` in s,
      `force_drop` in N), through the run's measurement when a run was given;
    - `data`: the run's cycles in the same columns (None without a run), and `p_values`,
      `{observable: p}` of each against the prediction (None without a run);
    - `method`: what was done, in words.
    """

    slider: Any
    regime: str
    evidence: str
    cycles: dict[str, np.ndarray]
    data: dict[str, np.ndarray] | None
    p_values: dict[str, float] | None
    method: str

    def medians(self) -> dict[str, tuple[float, float | None]]:
        """`{observable: (predicted median, the run's median or None)}`."""
        return {
            k: (float(np.median(v)) if v.size else math.nan,
                None if self.data is None else float(np.median(self.data[k])))
            for k, v in self.cycles.items()
        }  # fmt: skip

    def summary(self) -> str:
        s = self.slider
        lines = [f"prediction at k = {s.stiffness:.6g} N/m, V = {s.v_b:.4g} m/s: {self.regime} "
                 f"({self.evidence})", self.method]  # fmt: skip
        for k, (model, data) in self.medians().items():
            shown = "" if data is None else f", the run's {data:.4g}"
            p = "" if self.p_values is None else f", p = {self.p_values[k]:.3g}"
            lines.append(f"  {k}: median {model:.4g}{shown}{p}")
        return "\n".join(lines)


def predict(result, run=None, *, stiffness=None, v_b=None, n_sim=None, seed=None) -> Prediction:
    """`FitResult.predict`: see its docstring."""
    from .._model import CreepingSlider
    from ..units import Slider
    from .params import model_kwargs

    slider = result.diagnostics.units
    creeping = isinstance(result.model, CreepingSlider)
    if not creeping and not isinstance(slider, Slider):
        raise ParameterError(
            OWNER, "result", "must be a fit in physical units: fit(..., cycles, scales="
            "Slider(...)) (its Slider maps the estimate to a mass, a noise and a threshold)",
        )  # fmt: skip
    info = None
    if run is not None:
        info = getattr(run, "info", None)
        kind = kind_of_signal(info.get("input")) if isinstance(info, dict) else None
        if kind is None or not kind.in_si:
            raise ParameterError(OWNER, "run", "must be a Cycles of a force trace (from "
                                 "extract_cycles or analyse_run), in s, m and N")  # fmt: skip
        stiffness = info["stiffness"] if stiffness is None else stiffness
        # (a creeping slider loads its sticks slower than it is driven: the given speed)
        speed = info.get("v_b") if creeping else info.get("v_b_estimated")
        v_b = speed if v_b is None else v_b
    if stiffness is None or v_b is None:
        raise ParameterError(OWNER, "stiffness" if stiffness is None else "v_b",
                             "is required without a run")  # fmt: skip
    stiffness = check_positive(OWNER, "stiffness", stiffness)
    v_b = check_positive(OWNER, "v_b", v_b)
    d = result.diagnostics
    n_sim = d.n_sim if n_sim is None else check_int(OWNER, "n_sim", n_sim, minimum=100)
    # a seed other than the fit's: the check does not reuse the draws it was tuned on
    seed = int(d.seed) + 1 if seed is None else check_int(OWNER, "seed", seed, minimum=0)
    if creeping:
        return _creeping(result.model, run, stiffness, v_b, n_sim, seed)
    params = model_kwargs(result.model)
    si = slider.si_parameters({k: v for k, v in params.items() if k in _PHYSICAL})
    si.pop("v_b", None)
    # the fitted model's threshold, fixed or drawn, replaces the reference slider's
    if "threshold" in si:
        si["static_friction"] = None
    elif "static_friction" in si:
        si["threshold"] = None
    try:
        predicted = dataclasses.replace(slider, **si, stiffness=stiffness, v_b=v_b)
    except ParameterError as err:
        raise ParameterError(OWNER, "stiffness, v_b", f"give a slider the model refuses: "
                             f"{err.parameter} {err.reason}") from None  # fmt: skip
    how = (f"the fit's slider (effective mass {predicted.mass:.4g} kg, damping "
           f"{predicted.damping:.3g} kg/s, noise {predicted.noise:.3g} N^2 s) at the given "
           "stiffness and speed, seed {seed}")  # fmt: skip
    if run is None:
        return _per_cycle(predicted, n_sim, seed, how.format(seed=seed))
    Model = type(result.model)
    measurement = Measurement.from_cycles(run, scales=predicted)
    return _through(Model(**predicted.dimensionless()), predicted.scales, predicted,
                    measurement, run, n_sim, seed, how.format(seed=seed))  # fmt: skip


def _creeping(model, run, stiffness, v_b, n_sim, seed) -> Prediction:
    """A fitted creeping slider (in SI) at `stiffness` and `v_b`: its stationary cycles
    through `run`'s measurement, or without a run through a noise-free force trace sampled
    at a fortieth of its noise-free slip; `"steady sliding"` where its noise-free motion
    settles into it (`creeping.limit_cycle`)."""
    from .._errors import DataError
    from ..units import Scales
    from .creeping import limit_cycle
    from .params import model_kwargs

    try:
        predicted = type(model)(**dict(model_kwargs(model), stiffness=stiffness, v_b=v_b))
    except ParameterError as err:
        raise ParameterError(OWNER, "stiffness, v_b", f"give a slider the model refuses: "
                             f"{err.parameter} {err.reason}") from None  # fmt: skip
    how = (f"the fitted {type(model).__name__} at the given stiffness and speed (its "
           f"stationary motion, each path after a burn-in), seed {seed}")  # fmt: skip
    try:
        cycle = limit_cycle(predicted, OWNER)
    except DataError as err:
        empty = {k: np.zeros(0) for k in _OBSERVABLES}
        p = None if run is None else {k: 0.0 for k in _OBSERVABLES}
        data = None if run is None else {k: np.asarray(run[k], float) for k in _OBSERVABLES}
        return Prediction(predicted, "steady sliding", str(err), empty, data, p, how)
    if run is None:
        measurement = Measurement(signal="force", sampling_interval=cycle.slip_time / 40)
        how += f", as a noise-free force trace sampled every {cycle.slip_time / 40:.3g} s"
    else:
        measurement = Measurement.from_cycles(run, scales=Scales.si(stiffness))
    return _through(predicted, Scales.si(stiffness), predicted, measurement, run, n_sim, seed,
                    how)  # fmt: skip


def _per_cycle(slider, n_sim, seed, how) -> Prediction:
    """Independent cycles of `slider` (`Slider.simulate`), those that stuck again."""
    n = max(int(n_sim), _N_CYCLES)
    sim = slider.simulate(n, seed=seed, progress=False)
    stuck = np.asarray(sim.ensemble.stuck) & ~np.asarray(sim.ensemble.immediate)
    share = float(np.mean(np.asarray(sim.ensemble.stuck)))
    regime = "stick-slip" if share >= _STUCK else "no stick"
    cycles = {k: np.asarray(sim[k], float)[stuck] for k in _OBSERVABLES}
    evidence = f"{100 * share:.1f} % of {n} simulated slips stick again"
    return Prediction(slider, regime, evidence, cycles, None, None,
                      f"{n} independent cycles of {how}")  # fmt: skip


def _through(model, s, slider, measurement, run, n_sim, seed, how) -> Prediction:
    """The `model`'s cycles (in the units `s`, a `Scales`) through `measurement` (`run`'s,
    or a noise-free one without a run), in SI, against the run's: the fitted model's class
    (`random-threshold-held` releases as it does) with the predicted slider's parameters."""
    from .measurement import measured_cycles
    from .statistics import dependent_ks

    data = None if run is None else {k: np.asarray(run[k], float) for k in _OBSERVABLES}
    whose = "the run's" if run is not None else "a"
    try:
        sim = measured_cycles(model, measurement, n_sim, seed)
    except StickSlipError as err:  # (a DataError: no cycles through the measurement)
        # no cycles through the run's measurement: the run's stick-slip is not predicted
        empty = {k: np.zeros(0) for k in _OBSERVABLES}
        method = f"{n_sim} model cycles of {how}, through {whose} measurement"
        p = None if run is None else {k: 0.0 for k in _OBSERVABLES}
        return Prediction(slider, "unresolved", str(err), empty, data, p, method)
    cycles = {"stick_time": np.asarray(sim["stick_time"]) * s.time,
              "slip_time": np.asarray(sim["slip_time"]) * s.time,
              "force_drop": np.asarray(sim["slip_distance"]) * s.force}  # fmt: skip
    evidence = f"{cycles['slip_time'].size} cycles through {whose} measurement"
    if run is None:
        return Prediction(slider, "stick-slip", evidence, cycles, None, None,
                          f"{n_sim} model cycles of {how}")  # fmt: skip
    p = {k: dependent_ks(data[k], cycles[k]) for k in _OBSERVABLES}
    method = (f"{n_sim} model cycles of {how}, through the run's measurement (its sampling, "
              "noise, spikes, lines and extraction settings); p-values: two-sample "
              "Kolmogorov-Smirnov against the run's cycles, at the estimate, each sample "
              "at its effective size for its rows' dependence")  # fmt: skip
    return Prediction(slider, "stick-slip", evidence, cycles, data, p, method)
