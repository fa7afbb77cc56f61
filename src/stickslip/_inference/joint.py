"""One parameter set fitted to several runs (`fit(model, [run, run, ...])`).

A campaign sweeps the spring and the driving speed; what a friction law claims is that one
set of physical parameters (an effective mass, a damping, a friction noise, a static and
a kinetic friction) makes every run. Each run keeps its own spring $k$, speed $V$,
measurement and units (its reference `Slider`); the free and fixed parameters are the
slider's SI values (`units.MODEL_SI_NAMES`), mapped into each run's model units by
`Slider.model_parameters`. A value neither free nor fixed stays each run's own (its
reference slider's: the kinetic friction from its median drop, say): a parameter per run
where the physics says it may differ. `NAME[i]` (free or fixed) is run i's own value of
NAME, over the shared one: `"static_friction[2]"` frees the third run's static friction
alone.

The log-likelihood is the sum of the runs' (independent runs); its per-cycle terms are the
runs' rows one after the other, so that the sandwich, the second seed's noise check and
the intervals are `fit`'s own.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._errors import ParameterError

OWNER = "fit"
# What a `Run`'s cycles are fitted in
RUN_COLUMNS = ("slip_time", "stick_time", "slip_distance")


def _reference(run, i: int):
    """`(cycles, slider, label)` of one entry of the runs: a stick-slip `Run` made with
    its mass, or a `(Cycles, Slider)` pair."""
    from .._extract import Cycles
    from .._extract._regime import Run
    from ..units import Slider

    where = f"data[{i}]"
    if isinstance(run, Run):
        cycles, label = _stick_slip(run, i)
        mass = run.settings.get("mass")
        if not mass:
            raise ParameterError(
                OWNER, where, f"({label}) was read without its mass: analyse_run(..., mass=m) "
                "sets the units its cycles are fitted in",
            )  # fmt: skip
        return cycles, Slider.from_cycles(run.cycles, mass=mass), label
    if isinstance(run, tuple) and len(run) == 2:
        cycles, slider = run
        if isinstance(cycles, Cycles) and isinstance(slider, Slider):
            return cycles, slider, cycles.info.get("name") or f"run {i}"
    raise ParameterError(
        OWNER, where, "must be a stick-slip Run (analyse_run(..., mass=m)) or a pair "
        "(Cycles, Slider) of a force trace's cycles and its reference slider", type(run).__name__,
    )  # fmt: skip


def _stick_slip(run, i: int):
    """`(cycles, label)` of a stick-slip `Run`: its independent columns (a period is slip
    plus stick, a force drop the slip distance times k, a peak force the absolute level
    the cycles do not fix); any other regime is refused by name."""
    from .._extract import Cycles

    label = run.settings.get("name") or f"run {i}"
    if run.regime != "stick-slip":
        raise ParameterError(
            OWNER, f"data[{i}]", f"({label}) is {run.regime}, not stick-slip: it has no "
            f"cycles to fit ({run.evidence})",
        )  # fmt: skip
    return Cycles({k: run.cycles[k] for k in RUN_COLUMNS}, run.cycles.info), label


def _split(name: str) -> tuple[str, int | None]:
    """`"static_friction[2]"` -> `("static_friction", 2)`; a shared name -> `(name, None)`."""
    head, bracket, rest = str(name).partition("[")
    if not bracket or not rest.endswith("]") or not rest[:-1].isdigit():
        return str(name), None
    return head, int(rest[:-1])


class Runs:
    """The runs of a joint fit: their data in their own units, their measurements, and
    the map from a point of SI values to each run's model."""

    what = "a slider parameter (SI values)"

    def __init__(self, Model, runs):
        from ..units import MODEL_SI_NAMES
        from .data import check_data, measurement_of

        self.Model = Model
        known = Model.parameters()
        self.law = "threshold" in known
        if not {"omega0", "zeta", "D", "v_b"} <= set(known) or not (self.law or "x0" in known):
            raise ParameterError(
                OWNER, "model", f"{Model.__name__} does not take a slider's parameters "
                "(omega0, zeta, D, v_b and x0 or a threshold law): a fit of several runs maps "
                "one set of SI values into each run's units through its Slider",
            )  # fmt: skip
        if not isinstance(runs, (list, tuple)) or len(runs) < 1:
            raise ParameterError(OWNER, "data", "must be a non-empty list of runs", runs)
        self.names = MODEL_SI_NAMES
        self.labels, self.sliders = [], []
        self.columns, self.measurements = [], []
        for i, run in enumerate(runs):
            cycles, slider, label = _reference(run, i)
            d, measured = measurement_of(cycles, None, None, slider, OWNER)
            if measured is None:
                raise ParameterError(OWNER, f"data[{i}]", "must be the cycles of a force trace")
            self.labels.append(label)
            self.sliders.append(slider)
            self.columns.append(check_data(d, measured=True))
            self.measurements.append(measured)
        self._pooled()

    def _pooled(self) -> None:
        """`data`: every run's rows, one run after the other, once every run has the first
        run's columns (else a `ParameterError` naming the run)."""
        first = list(self.columns[0])
        for i, d in enumerate(self.columns):
            if list(d) != first:
                raise ParameterError(
                    OWNER, f"data[{i}]", f"has the columns {', '.join(d)}, the first run "
                    f"{', '.join(first)}: fit the same observables of every run",
                )  # fmt: skip
        self.data = {k: np.concatenate([d[k] for d in self.columns]) for k in first}
        self.fixed: dict[str, Any] = {}

    def __repr__(self) -> str:
        return f"<{len(self.labels)} runs: {', '.join(self.labels)}>"

    def checked(self, fixed, free) -> tuple[dict, dict]:
        """`(fixed, free)`: SI names of a slider, finite boxes with low < high, none both."""
        fixed = {} if fixed is None else fixed
        if not hasattr(fixed, "items"):
            raise ParameterError(OWNER, "fixed", "must be a dict {name: value}", fixed)
        if not hasattr(free, "items") or not free:
            raise ParameterError(OWNER, "free", "must be a non-empty dict {name: (low, high)}")
        for where, names in (("fixed", fixed), ("free", free)):
            for k in names:
                name, run = _split(k)
                if name not in self.names:
                    raise ParameterError(
                        OWNER, f"{where}['{k}']", f"is not {self.what} of a fit of several "
                        f"runs ({', '.join(self.names)}; NAME[i] for run i's own)",
                    )  # fmt: skip
                if run is not None and not 0 <= run < len(self.sliders):
                    raise ParameterError(
                        OWNER, f"{where}['{k}']", f"names run {run}: there are "
                        f"{len(self.sliders)} runs, 0 to {len(self.sliders) - 1}",
                    )  # fmt: skip
        out = {}
        for k, box in free.items():
            try:
                low, high = (float(b) for b in box)
            except (TypeError, ValueError):
                raise ParameterError(OWNER, f"free['{k}']", "must be a pair (low, high)") from None
            if not (math.isfinite(low) and math.isfinite(high) and low < high):
                raise ParameterError(OWNER, f"free['{k}']", "must be finite with low < high", box)
            if k in fixed:
                raise ParameterError(OWNER, f"free['{k}']", "is also fixed")
            out[k] = (low, high)
        self.fixed = dict(fixed)
        return self.fixed, out

    def build(self, values: dict) -> list:
        """Each run's model at the SI `values` (with the fixed ones): a name `NAME[i]`
        is run i's own value of NAME, over the shared one."""
        given = {**self.fixed, **values}
        shared = {k: v for k, v in given.items() if _split(k)[1] is None}
        models = []
        for i, slider in enumerate(self.sliders):
            own = {_split(k)[0]: v for k, v in given.items() if _split(k)[1] == i}
            p = slider.model_parameters({**shared, **own})
            if "threshold" in p and not self.law:
                raise ParameterError(
                    OWNER, "model", f"{self.Model.__name__} has a fixed threshold; the runs' "
                    "sliders (or threshold.* values) give a random one",
                )  # fmt: skip
            if self.law and "x0" in p:  # a fixed static friction: a law of no spread
                p["threshold"] = "normal"
                p["threshold_params"] = {"mean": p.pop("x0"), "sd": 0.0}
            models.append(self.Model(**p))
        return models

    def check_box(self, free: dict, centre: dict):
        """The first run's model at the box's centre, after building every run's there and
        at both ends of each axis: a value a run's model refuses is a `ParameterError`
        naming the box and the run."""
        trials = [(None, centre)] + [(k, {**centre, k: b}) for k in free for b in free[k]]
        built = None
        for name, values in trials:
            try:
                models = self.build(values)
            except (ValueError, ArithmeticError) as err:
                reason = str(err).splitlines()[0] if str(err) else type(err).__name__
                where = f"free['{name}']" if name else "fixed"
                raise ParameterError(
                    OWNER, where, f"gives a model a run refuses ({reason}): narrow the box",
                ) from None  # fmt: skip
            if name is None:
                built = models[0]
        return built

    def springs(self) -> list[tuple[float, float]]:
        """Per run: its spring's stiffness (N/m) and driving speed (m/s)."""
        return [(s.stiffness, s.v_b) for s in self.sliders]

    def describe(self, models) -> list[dict[str, Any]]:
        """Per run: its label, spring, speed, cycles and the fitted model's parameters."""
        out = []
        for label, (k, v_b), d, m in zip(self.labels, self.springs(), self.columns, models,
                                         strict=True):  # fmt: skip
            out.append(dict(
                name=label, stiffness=k, v_b=v_b,
                cycles=int(max(np.size(v) for v in d.values())),
                model={k: v for k, v in m.params().items()
                       if isinstance(v, (int, float, str, dict)) or v is None},
            ))  # fmt: skip
        return out

    def p_values(self, result, n_sim: int, seed: int) -> None:
        """Per run and observable, the KS p-value of its cycles against the fitted models'
        simulated ones through its measurement (another seed than the fit's), into
        `result.diagnostics.runs`, each sample counted at its effective size for its
        rows' dependence (`statistics.dependent_ks`: successive cycles of a slider with
        memory are dependent). Not corrected for the fit (the estimate was tuned on these
        data): high p-values are optimistic, a low one is a rejection. A run on which the
        fitted slider's trace shows no cycles through its measurement gets p-values of 0
        and the reason (`"unresolved"`)."""
        from .._errors import DataError
        from .forward import simulate_values
        from .statistics import dependent_ks

        models = self.build(result.estimate)
        for row, m, d, measured in zip(result.diagnostics.runs, models, self.columns,
                                       self.measurements, strict=True):  # fmt: skip
            try:
                sim = simulate_values(m, n_sim, None, None, seed, measured)
            except DataError as err:  # the fitted slider shows no cycles on this run
                row["p_values"] = dict.fromkeys(d, 0.0)
                row["unresolved"] = str(err).splitlines()[0]
                continue
            row["p_values"] = {k: dependent_ks(d[k], sim[k]) for k in d}


def _creeping_reference(run, i: int, name: str):
    """`(cycles, stiffness, v_b, label)` of one entry of a creeping slider's runs: a
    stick-slip `Run` or the `Cycles` of a force trace, with the stiffness and the given
    driving speed it was read with (the model's; not the sticks' slope, which creep)."""
    from .._extract import Cycles
    from .._extract._regime import Run

    where = f"data[{i}]"
    if isinstance(run, Run):
        cycles, label = _stick_slip(run, i)
        k, v_b = run.settings.get("stiffness"), run.settings.get("v_b")
    elif isinstance(run, Cycles):
        label = run.info.get("name") or f"run {i}"
        cycles, k, v_b = run, run.info.get("stiffness"), run.info.get("v_b")
    else:
        raise ParameterError(
            OWNER, where, f"must be a stick-slip Run (analyse_run) or the Cycles of a force "
            f"trace (extract_cycles) for {name}", type(run).__name__,
        )  # fmt: skip
    try:
        k, v_b = float(k), float(v_b)
    except (TypeError, ValueError):
        k = v_b = math.nan
    if not (math.isfinite(k) and k > 0 and math.isfinite(v_b) and v_b > 0):
        raise ParameterError(
            OWNER, where, f"({label}) must carry its spring and driving speed (a force "
            "trace read with stiffness= and v_b=): they are its model's",
        )  # fmt: skip
    return cycles, k, v_b, label


class CreepingRuns(Runs):
    """The runs of a joint fit of a creeping slider (`CreepingSlider`, in SI): each run's
    cycles in SI (`Scales.si` of its spring: times in s, the drop over k in m), its
    measurement, and its own spring and driving speed as its model's `stiffness` and
    `v_b`; the free and fixed values are the model's own parameters (`NAME[i]`: run i's
    own value of NAME, over the shared one)."""

    @property
    def what(self) -> str:
        return f"a parameter of {self.Model.__name__}"

    def __init__(self, Model, runs):
        from ..units import Scales
        from .data import check_data, measurement_of

        self.Model, self.law = Model, False
        if not isinstance(runs, (list, tuple)) or len(runs) < 1:
            raise ParameterError(OWNER, "data", "must be a non-empty list of runs", runs)
        own = ("stiffness", "v_b")
        self.names = tuple(k for k in Model.parameters() if k not in own)
        self.labels, self.settings, self.columns, self.measurements = [], [], [], []
        for i, run in enumerate(runs):
            cycles, k, v_b, label = _creeping_reference(run, i, Model.__name__)
            d, measured = measurement_of(cycles, None, None, Scales.si(k), OWNER)
            self.labels.append(label)
            self.settings.append((k, v_b))
            self.columns.append(check_data(d, measured=True))
            self.measurements.append(measured)
        self.sliders = [Scales.si(k) for k, _ in self.settings]
        self._pooled()

    def checked(self, fixed, free) -> tuple[dict, dict]:
        for where, names in (("fixed", fixed or {}), ("free", free or {})):
            for k in names if hasattr(names, "keys") else ():
                if _split(k)[0] in ("stiffness", "v_b"):
                    raise ParameterError(
                        OWNER, f"{where}['{k}']", "is each run's own in a fit of several runs "
                        "(the stiffness and v_b its force trace was read with)",
                    )  # fmt: skip
        return super().checked(fixed, free)

    def build(self, values: dict) -> list:
        given = {**self.fixed, **values}
        shared = {k: v for k, v in given.items() if _split(k)[1] is None}
        models = []
        for i, (k, v_b) in enumerate(self.settings):
            own = {_split(n)[0]: v for n, v in given.items() if _split(n)[1] == i}
            models.append(self.Model(**{**shared, **own}, stiffness=k, v_b=v_b))
        return models

    def springs(self) -> list[tuple[float, float]]:
        return list(self.settings)
