"""The study schema: what a YAML study may say, checked by pydantic.

Every model is strict: unknown keys are errors, types are not converted (an int is accepted
where a float is expected, nothing else), and every setting carries a description so that
the JSON schema (`stickslip schema`) documents itself. Checks that involve more than one
field (the model's own parameters, outputs the model cannot give, a sweep over a parameter
that does not exist) raise errors located at the field they are about.
"""

from __future__ import annotations

import difflib
import itertools
import math
import warnings
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    model_validator,
)
from pydantic_core import PydanticCustomError

DENSITIES = ("slip_time", "period", "slip_distance", "stick_time")
BLOCK_OUTPUTS = (*DENSITIES, "n1", "n2", "time_series", "phase_portrait")
AUTO_OUTPUTS = ("slip_time", "period")  # the densities the accuracy-cost data measures
SINGLE_RUN_OUTPUTS = ("n1", "n2", "time_series", "phase_portrait")  # not over a sweep
CHAIN_OUTPUTS = ("event_size", "event_duration", "event_interval", "time_series")
OutputName = Literal[
    "slip_time", "period", "slip_distance", "stick_time", "n1", "n2", "time_series",
    "phase_portrait", "event_size", "event_duration", "event_interval",
]  # fmt: skip


def fail(loc: str, reason: str):
    """An error located at `loc` (dotted, relative to the model being validated)."""
    return PydanticCustomError("stickslip", "{reason}", {"loc": loc, "reason": reason})


def suggest(word: str, options) -> str:
    close = difflib.get_close_matches(str(word), [str(o) for o in options], n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


class Base(BaseModel):
    model_config = ConfigDict(
        extra="forbid", strict=True, validate_assignment=True, validate_default=True
    )


# Limits stated up front, checked at validation (before anything is built or allocated):
MAX_SWEEP_POINTS = 10_000  # points of a sweep; each is a full run
MAX_STEPS = 2**30  # time steps per path, t_max / dt: the simulator's own bound


def short(value: Any, limit: int = 60) -> str:
    """`repr(value)` for a message, cut to `limit` characters (a value may be huge)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _check_steps(loc: str, t_max: float, dt: float):
    steps = t_max / dt
    if steps >= MAX_STEPS:
        count = f"{steps:.3g}" if math.isfinite(steps) else "more than 1e308"
        raise fail(
            loc,
            f"t_max / dt = {count} time steps is past the limit of 2**30 "
            f"(t_max = {t_max:g}, dt = {dt:g}): raise dt or lower t_max",
        )


PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
PositiveInt = Annotated[int, Field(ge=1)]


class ModelSpec(Base):
    """The friction model: a plugin's name and its parameters."""

    name: str = Field(description="Model name, as listed by `stickslip models`.")
    params: dict[str, Any] = Field(
        default_factory=dict,
        description="The model's parameters, checked by the plugin's own parameter model "
        "(`stickslip models` lists them; `stickslip schema --model NAME` prints their schema).",
    )
    _instance: Any = PrivateAttr(default=None)

    @model_validator(mode="after")
    def _build(self):
        from .._errors import ParameterError
        from .._registry import list_models

        models = list_models()
        if self.name not in models:
            raise fail(
                "name",
                f"unknown model '{self.name}' (installed: {', '.join(models)})"
                + suggest(self.name, models),
            )
        cls = models[self.name]
        try:
            values = cls.params_model().model_validate(self.params)
        except ValidationError as err:
            e = first_error(err)
            loc = ".".join(str(p) for p in e["loc"])
            names = list(cls.parameters())
            if e["type"] == "extra_forbidden":
                reason = f"unknown parameter of {self.name} (parameters: {', '.join(names)})"
                reason += suggest(e["loc"][-1], names)
            elif e["type"] == "missing":
                reason = f"required parameter of {self.name} is missing"
            else:
                reason = describe_error(e)
            raise fail(f"params.{loc}", reason) from None
        kwargs = {k: getattr(values, k) for k in values.model_fields_set}
        try:
            self._instance = cls(**kwargs)
            from .._model import ChainModel

            if not isinstance(self._instance, ChainModel):
                self._instance.linear_gaussian()  # its formulas, evaluated once here
        except ParameterError as err:
            got = "" if err.value is None else f" (got {short(err.value)})"
            raise fail(f"params.{err.parameter}", f"{err.reason}{got}") from None
        except ArithmeticError as err:  # OverflowError, ZeroDivisionError in the formulas
            raise fail("params", _overflow_reason(self.name, kwargs, err)) from None
        except (TypeError, ValueError) as err:
            raise fail("params", str(err).splitlines()[0] if str(err) else repr(err)) from None
        return self

    @property
    def instance(self):
        """The model object these settings make."""
        return self._instance


def _overflow_reason(name: str, params: dict, err: ArithmeticError) -> str:
    """Why a model's formulas failed (`OverflowError` ...), naming its largest value."""
    numbers = {k: v for k, v in params.items() if isinstance(v, int | float) and v == v}
    why = f"the values overflow {name}'s formulas ({type(err).__name__})"
    if numbers:
        k = max(numbers, key=lambda k: abs(numbers[k]))
        why += f"; the largest is {k} = {numbers[k]:g}"
    return why


class Cycles(Base):
    """A few paths run through successive cycles, for the time series and phase portraits."""

    n_paths: int = Field(2, ge=1, le=64, description="Paths to run through many cycles.")
    t_max: PositiveFloat = Field(60.0, description="Length of each path's run (time units).")
    dt: PositiveFloat | None = Field(
        None,
        description="Time step of these runs (default: the simulation's dt). A time series "
        "needs a fine step to look smooth; the slip statistics of the exact detector do not.",
    )


class Simulation(Base):
    """The Monte Carlo run (`stickslip.simulate`, or `simulate_chain` for chains)."""

    n_paths: PositiveInt = Field(
        100_000, le=2**32 - 1, description="Paths (one slip-stick cycle each); chains: chains."
    )
    dt: PositiveFloat = Field(0.005, description="Time step.")
    t_max: PositiveFloat = Field(
        60.0, description="Longest slip followed (chains: the length of the run)."
    )
    seed: int = Field(0, ge=0, lt=2**64, description="Random seed; results depend on it alone.")
    solver: Literal["auto", "exact", "euler"] = Field(
        "auto", description="'exact' Gaussian transitions, 'euler' (Euler-Maruyama), or 'auto'."
    )
    monitor: Literal["continuous", "grid"] = Field(
        "continuous",
        description="Look for the stick inside each step ('continuous') or only on the time "
        "grid ('grid', the paper's convention).",
    )
    chunk_size: PositiveInt = Field(2**20, description="Paths per chunk (bounds the memory).")
    upcrossings: PositiveInt = Field(
        12,
        le=256,
        description="Upcrossings recorded per path when n1, n2 or an empirical estimate is "
        "requested.",
    )
    cycles: Cycles = Field(default_factory=Cycles, description="Runs for time series.")

    @model_validator(mode="after")
    def _steps(self):
        if self.t_max < self.dt:
            raise fail("t_max", f"must be >= dt = {self.dt:g} (got {self.t_max:g})")
        _check_steps("t_max", self.t_max, self.dt)
        _check_steps("cycles.t_max", self.cycles.t_max, self.cycles.dt or self.dt)
        return self


class Analytic(Base):
    """One level-crossing approximation of the first-passage density."""

    method: Literal["truncation", "decoupling"] = Field(
        description="'truncation' (F_n, eq. 6) or 'decoupling' (F_g, eq. 7)."
    )
    order: Literal[1, 2] = Field(1, description="Order of the approximation.")
    normalized: bool = Field(
        False, description="Normalised truncation (cut where the integral reaches 1)."
    )
    source: Literal["auto", "exact", "empirical"] = Field(
        "auto",
        description="Crossing densities from the exact Gaussian formulas ('exact'), from "
        "simulated upcrossings ('empirical'), or exact where the model allows ('auto').",
    )
    label: str | None = Field(None, description="Legend label (default from the method).")

    @model_validator(mode="after")
    def _normalised(self):
        if self.normalized and self.method != "truncation":
            raise fail("normalized", "applies only to method 'truncation'")
        return self

    @property
    def key(self) -> str:
        """A short identifier: e.g. `Fg1`, `Fn2_norm`, `Fg1_empirical`."""
        k = f"F{'n' if self.method == 'truncation' else 'g'}{self.order}"
        if self.normalized:
            k += "_norm"
        if self.source == "empirical":
            k += "_empirical"
        return k

    @property
    def title(self) -> str:
        if self.label:
            return self.label
        sym = ("\\hat{\\mathcal{F}}" if self.normalized else "\\mathcal{F}") + (
            "_n" if self.method == "truncation" else "_g"
        )
        name = f"${sym}^{{({self.order})}}$ {self.method}"
        return name + (" (empirical)" if self.source == "empirical" else "")


class Estimator(Base):
    """Settings of the crossing-statistics estimator."""

    dt: PositiveFloat | None = Field(
        None, description="Time step of the series (default 0.01; 0.05 empirical)."
    )
    horizon: PositiveFloat | None = Field(
        None, description="End of the time grid of the position-resolved densities."
    )
    mixing: Literal["components", "process"] | None = Field(
        None, description="How a random onset is mixed (see CrossingEstimator)."
    )


class Range(Base):
    """Bins of a histogram: `bins` cells between `start` and `stop`; a missing end is taken
    from the simulated data (0.5% and 99.5% quantiles) or from the theory."""

    start: float | None = Field(None, description="Left edge (default: automatic).")
    stop: float | None = Field(None, description="Right edge (default: automatic).")
    bins: int = Field(100, ge=2, le=100_000, description="Number of cells.")

    @model_validator(mode="after")
    def _order(self):
        if self.start is not None and self.stop is not None and not self.stop > self.start:
            raise fail("stop", f"must be > start = {self.start:g} (got {self.stop:g})")
        return self


class Grid(Base):
    """Where densities are evaluated: shared by Monte Carlo histograms and the theory."""

    slip_time: Range = Field(default_factory=Range, description="Slip times T_sl.")
    period: Range = Field(default_factory=Range, description="Periods T = T_sl + T_st.")
    slip_distance: Range = Field(default_factory=Range, description="Slip distances d.")
    stick_time: Range = Field(default_factory=Range, description="Stick times T_st.")
    n1: Range = Field(default_factory=Range, description="Times of the upcrossing density.")
    n2: Range = Field(
        default_factory=lambda: Range(bins=40), description="Times (both axes) of n2(t1, t2)."
    )
    event_size: Range = Field(
        default_factory=lambda: Range(bins=30), description="Event sizes (log-spaced bins)."
    )
    event_duration: Range = Field(
        default_factory=lambda: Range(bins=30), description="Event durations (log-spaced)."
    )
    event_interval: Range = Field(
        default_factory=lambda: Range(bins=30), description="Times between events (log-spaced)."
    )


class Sweep(Base):
    """Run the study at several values of one or more settings."""

    parameters: dict[str, list[Any]] = Field(
        description="Dotted path of a setting (e.g. `model.params.v_b`, `simulation.dt`) -> "
        "the values it takes.",
        min_length=1,
    )
    mode: Literal["product", "zip"] = Field(
        "product", description="Every combination ('product') or values side by side ('zip')."
    )

    @model_validator(mode="after")
    def _lengths(self):
        for path, values in self.parameters.items():
            if not values:
                raise fail(f"parameters.{path}", "needs at least one value")
        lengths = {len(v) for v in self.parameters.values()}
        if self.mode == "zip" and len(lengths) > 1:
            raise fail("parameters", f"mode 'zip' needs lists of one length (got {lengths})")
        n = self.size()
        if n > MAX_SWEEP_POINTS:
            counts = " x ".join(str(len(v)) for v in self.parameters.values())
            how = f"{counts} values" if self.mode == "product" else "values side by side"
            raise fail(
                "parameters",
                f"{n} points ({how}) is past the limit of {MAX_SWEEP_POINTS} points of a "
                "sweep: split it into several studies",
            )
        return self

    def size(self) -> int:
        """The number of points, counted without making them."""
        lengths = [len(v) for v in self.parameters.values()]
        return math.prod(lengths) if self.mode == "product" else min(lengths, default=0)

    def points(self) -> list[dict[str, Any]]:
        """The settings of each point: `[{path: value, ...}, ...]`."""
        paths = list(self.parameters)
        values = [self.parameters[p] for p in paths]
        combos = itertools.product(*values) if self.mode == "product" else zip(*values, strict=True)
        return [dict(zip(paths, c, strict=True)) for c in combos]


FreeBoxes = dict[str, Annotated[list[float], Field(min_length=2, max_length=2)]]
CANDIDATE_NAME = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,39}$"  # also a file name: fit_<name>.png


def _check_boxes(loc: str, free: dict) -> None:
    for name, (low, high) in free.items():
        if not low < high:
            raise fail(f"{loc}.{name}", f"must be [low, high] with low < high (got {[low, high]})")


class Scales(Base):
    """The model's units in SI, for the cycles of a force trace (`stickslip cycles` on a
    trace in seconds and newtons): the model's time unit in seconds and its force unit in
    newtons, as `stickslip.units.Slider(...).scales` gives them (`time` = 1/omega0, `force`
    = k x0). The trace's sampling interval, noise and removed mains lines are divided by
    them (`Measurement.from_cycles`), and the summary states the estimates in SI."""

    time: PositiveFloat = Field(
        description="Seconds per model time unit: 1/omega0 = sqrt(m/k) (`Slider.scales.time`)."
    )
    force: PositiveFloat = Field(
        description="Newtons per model force unit: k x0, the spring force from the sliding "
        "level to the static threshold (`Slider.scales.force`)."
    )


class Candidate(Base):
    """One candidate model of a fit with several (`fit.candidates`): fitted to the fit's
    data with the fit's settings, then `compare_fits` chooses the simplest one the data do
    not reject."""

    name: str = Field(
        pattern=CANDIDATE_NAME,
        description="A short name (letters, digits, '_', '.', '-'; up to 40): the table's row "
        "and the figure fit_<name>.png.",
    )
    model: ModelSpec | None = Field(
        None,
        description="Its own model block (name and params), e.g. a random-threshold model "
        "against the study's langevin (default: the study's model with `params` changed).",
    )
    params: dict[str, Any] | None = Field(
        None,
        description="Changes to the study's model parameters for this candidate, e.g. "
        "`{tau: 0.03}` (null keeps a parameter's default); not with `model`.",
    )
    free: FreeBoxes = Field(
        min_length=1,
        description="Parameter -> [low, high]: this candidate's parameters to estimate and "
        "their boxes (log scale where low > 0); its other parameters are held.",
    )

    @model_validator(mode="after")
    def _boxes(self):
        if self.model is not None and self.params is not None:
            raise fail(
                "params", "give either model (a whole model block) or params (changes to the "
                "study's model), not both",
            )  # fmt: skip
        _check_boxes("free", self.free)
        return self


class Fit(Base):
    """Estimate model parameters from measured per-cycle data (`stickslip fit STUDY.yaml`):
    the parameters in `free` are estimated, the model's other parameters are held at their
    values in `model.params` (those of the free ones there are not used). With
    `candidates` instead of `free`, each candidate model is fitted to the same data and
    `compare_fits` chooses the simplest one the data do not reject."""

    data: str = Field(
        description="CSV file of cycles: as `stickslip cycles` writes them (its '# stickslip "
        "cycles' header keeps the extraction's settings: the model is fitted through the same "
        "measurement, sampled, noisy and extracted alike), or any table of per-cycle values "
        "of the model (a header naming slip_time, slip_distance, stick_time and/or period; no "
        "measurement); a relative path is taken from the study file's folder."
    )
    columns: list[Literal["slip_time", "slip_distance", "stick_time", "period"]] | None = Field(
        None, description="The columns to fit (default: every known column in the file)."
    )
    free: FreeBoxes | None = Field(
        None,
        min_length=1,
        description="Parameter -> [low, high]: the parameters to estimate and the box searched "
        "(log scale where low > 0). Required unless `candidates` are listed.",
    )
    candidates: list[Candidate] | None = Field(
        None,
        description="Two or more candidate models, each fitted to the data (instead of `free`); "
        "`compare_fits` chooses the simplest the data do not reject (docs/compare.md).",
    )
    alpha: Annotated[float, Field(gt=0, lt=1)] = Field(
        0.01,
        description="Level of the model choice: a simpler candidate is kept unless rejected at "
        "it (with `candidates`).",
    )
    n_boot: int | None = Field(
        None,
        ge=1,
        le=100_000,
        description="Parametric-bootstrap replicates per test of the model choice (default: "
        "enough that the smallest p-value is alpha / 2; with `candidates`).",
    )
    scales: Scales | None = Field(
        None,
        description="The model's units in SI (time in s, force in N), required for the cycles "
        "of a force trace, refused for any other data.",
    )
    trace: bool | None = Field(
        None,
        description="Deprecated and ignored: a cycles file written by `stickslip cycles` "
        "carries its measurement (true with any other file is refused).",
    )
    sampling: PositiveFloat | None = Field(
        None, description="Deprecated and ignored: the cycles file carries its sampling interval."
    )
    n_sim: int | None = Field(
        None,
        ge=1000,
        le=2**32 - 1,
        description="Simulated cycles per evaluated point (default: 100000 for per-cycle values, "
        "4000 model cycles for a cycles file of a measured trace, each ~40 times dearer).",
    )
    seed: int = Field(0, ge=0, description="Seed of the simulations (common to every point).")
    intervals: Literal["wald", "profile"] = Field(
        "wald",
        description="How the 95 % intervals are read: 'wald' (the curvature about the "
        "estimate) or 'profile' (each parameter held, the others maximised; follows a ridge, "
        "about one more fit's cost a free parameter).",
    )
    dt: PositiveFloat | None = Field(
        None, description="Simulation step (default: a fifth of the model's slowest time scale)."
    )
    t_max: PositiveFloat | None = Field(
        None, description="Longest simulated slip (default: 3 x the longest in the data)."
    )

    @model_validator(mode="after")
    def _boxes(self):
        if self.t_max is not None and self.dt is not None:
            _check_steps("t_max", self.t_max, self.dt)
        if self.candidates is None:
            if self.free is None:
                raise fail("free", "is required: the parameters to estimate (or candidates)")
            for name in ("alpha", "n_boot"):
                if name in self.model_fields_set:
                    raise fail(name, "applies to a choice between candidates only")
            _check_boxes("free", self.free)
            return self
        if self.free is not None:
            raise fail(
                "free", "goes inside each candidate when candidates are listed (remove it here)"
            )
        if len(self.candidates) < 2:
            raise fail(
                "candidates", "must list at least two models to choose from"
                + (" (got an empty list)" if not self.candidates else " (for one, use free)"),
            )  # fmt: skip
        names = [c.name for c in self.candidates]
        for i, name in enumerate(names):
            if name in names[:i]:
                raise fail(
                    f"candidates.{i}.name",
                    f"'{name}' is already the name of candidates.{names.index(name)}",
                )
        return self

    def models(self, study_model: ModelSpec) -> list[tuple[str, ModelSpec, dict, str]]:
        """The models to fit: `[(name, model, free, loc), ...]`, `loc` where the model's
        settings lie in the study (`model` for the study's own block)."""
        if self.candidates is None:
            return [("fit", study_model, self.free, "model")]
        out = []
        for i, c in enumerate(self.candidates):
            if c.model is not None:
                out.append((c.name, c.model, c.free, f"fit.candidates.{i}.model"))
                continue
            params = {**study_model.params, **(c.params or {})}
            spec = ModelSpec.model_validate({"name": study_model.name, "params": params})
            out.append((c.name, spec, c.free, f"fit.candidates.{i}"))
        return out


class Study(Base):
    """A stick-slip study: a model, how to simulate it, which theory to compare, what to
    write. Run it with `stickslip run STUDY.yaml --out DIR` or `stickslip.run_study`."""

    title: str | None = Field(None, description="Title of the figures and the summary.")
    description: str | None = Field(None, description="Free text, copied to the summary.")
    model: ModelSpec = Field(description="The friction model.")
    method: Literal["compare", "auto"] = Field(
        "compare",
        description="'compare': run the simulation and every analytic method listed. 'auto': "
        "run only the cheapest method whose L1 error meets `tolerance` on each requested "
        "density (slip_time, period), chosen from the measured accuracy-cost data and the "
        "stability rules; the summary says which and why.",
    )
    tolerance: PositiveFloat | None = Field(
        None, description="L1 tolerance of the densities, for method: auto (e.g. 0.05)."
    )
    simulation: Simulation | None = Field(
        default_factory=Simulation, description="The Monte Carlo run; null for theory only."
    )
    analytic: list[Analytic] = Field(
        default_factory=list, description="Level-crossing approximations to compare."
    )
    estimator: Estimator = Field(default_factory=Estimator, description="Estimator settings.")
    outputs: list[OutputName] | None = Field(
        None,
        description="What to compute and plot (default: slip_time, period, slip_distance for "
        "a block; event_size, event_duration, time_series for a chain).",
    )
    grid: Grid = Field(default_factory=Grid, description="Grids of the densities.")
    sweep: Sweep | None = Field(None, description="Parameters to sweep (optional).")
    fit: Fit | None = Field(
        None,
        description="Estimate parameters from measured cycles (run with `stickslip fit`; "
        "`stickslip run` does not use it).",
    )

    # -- cross-field checks ------------------------------------------------------------
    @model_validator(mode="after")
    def _consistent(self):
        from .._model import ChainModel

        model = self.model.instance
        chain = isinstance(model, ChainModel)
        allowed = CHAIN_OUTPUTS if chain else BLOCK_OUTPUTS
        kind = "a chain" if chain else "a single block"
        for i, name in enumerate(self.outputs or ()):
            if name not in allowed:
                raise fail(
                    f"outputs.{i}",
                    f"'{name}' is not an output of {self.model.name} ({kind}); "
                    f"choose from {', '.join(allowed)}",
                )
            if name in (self.outputs or ())[:i]:
                raise fail(f"outputs.{i}", f"'{name}' is listed twice")
        if chain:
            if self.analytic:
                raise fail(
                    "analytic",
                    f"the crossing estimator needs a single-block model; {self.model.name} is "
                    "a chain (remove 'analytic')",
                )
            if self.simulation is None:
                raise fail("simulation", f"is required for {self.model.name} (a chain)")
        self._check_auto(chain)
        if self.fit is not None:
            if chain:
                raise fail("fit", f"needs a single-block model; {self.model.name} is a chain")
            self._check_fit()
        lg = None if chain else model.linear_gaussian()
        if lg is not None and self.simulation is not None and self.simulation.solver != "euler":
            self._check_step(lg, bool(model.crossing_is_smooth))
        keys = [a.key for a in self.analytic]
        for i, key in enumerate(keys):
            if key in keys[:i]:
                raise fail(f"analytic.{i}", f"repeats an earlier entry ({key})")
        for i, a in enumerate(self.analytic):
            if a.source == "exact" and lg is None:
                raise fail(
                    f"analytic.{i}.source",
                    f"'exact' needs a linear-Gaussian model; {self.model.name} is not "
                    "(use 'empirical')",
                )
            if self.simulation is None and (a.source == "empirical" or lg is None):
                raise fail(
                    f"analytic.{i}.source",
                    "an empirical estimate needs a simulation (simulation is null)",
                )
        if self.simulation is None:
            for i, name in enumerate(self.resolved_outputs()):
                if name in ("time_series", "phase_portrait"):
                    raise fail(f"outputs.{i}", f"'{name}' needs a simulation")
                if name in DENSITIES and not self.analytic:
                    raise fail(f"outputs.{i}", f"'{name}' needs a simulation or an analytic method")
        if self.sweep is not None:
            drawn = ", ".join(n for n in allowed if n not in SINGLE_RUN_OUTPUTS)
            for i, name in enumerate(self.resolved_outputs()):
                if name in SINGLE_RUN_OUTPUTS:
                    raise fail(
                        f"outputs.{i}",
                        f"'{name}' is not drawn over a sweep (run the study at one value; a "
                        f"sweep draws {drawn})",
                    )
            self._check_sweep()
        return self

    def _check_fit(self):
        """Each model of the fit (the study's, or each candidate's) can be built, is a
        single block, and has the parameters its `free` names."""
        from .._model import ChainModel

        fixed = self.fit.candidates is None
        for i, c in enumerate(self.fit.candidates or ()):
            if c.params is not None:  # the study's model with changes: built here
                params = {**self.model.params, **c.params}
                try:
                    ModelSpec.model_validate({"name": self.model.name, "params": params})
                except ValidationError as err:
                    loc, reason = locate(first_error(err))
                    raise fail(f"fit.candidates.{i}.{loc}", reason) from None
        for _, spec, free, loc in self.fit.models(self.model):
            where = "fit.free" if fixed else f"{loc.removesuffix('.model')}.free"
            if isinstance(spec.instance, ChainModel):
                raise fail(loc, f"needs a single-block model; {spec.name} is a chain")
            names = list(type(spec.instance).parameters())
            params = f"{loc}.params" if loc != "model" else "model.params"
            for key in free:
                head, _, tail = key.partition(".")  # "threshold_params.sd": a nested entry
                nested = spec.params.get(head)
                if tail and head in names and not (isinstance(nested, dict) and tail in nested):
                    have = ", ".join(nested) if isinstance(nested, dict) else "none"
                    raise fail(
                        f"{where}.{key}",
                        f"is not an entry of {params}.{head} (its entries: {have})"
                        + (suggest(tail, list(nested)) if isinstance(nested, dict) else ""),
                    )
                if head not in names:
                    raise fail(
                        f"{where}.{key}",
                        f"is not a parameter of {spec.name} (parameters: "
                        f"{', '.join(names)})" + suggest(key, names),
                    )

    def _check_step(self, lg, smooth: bool):
        """A step the exact solver cannot follow (dt far past the slip's time scale, e.g.
        omega0 = 1e8 at dt = 0.2, or too fine for float64) is refused here, not after the run
        has started."""
        from .._errors import ParameterError
        from .._simulate import config

        sim = self.simulation
        for loc, dt in (("simulation.dt", sim.dt), ("simulation.cycles.dt", sim.cycles.dt)):
            if dt is None:
                continue
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # (refusals only: the run warns)
                    # (the step's tables, kept for the run: ~4 ms)
                    config.check_exact_step("simulate", lg, dt, monitor=sim.monitor,
                                            smooth=smooth)  # fmt: skip
            except ParameterError as err:
                where = "model.params" if err.parameter == "model" else loc
                raise fail(where, err.reason) from None

    def _check_auto(self, chain: bool):
        if self.method == "compare":
            if self.tolerance is not None:
                raise fail("tolerance", "applies only to method: auto")
            return
        if self.tolerance is None:
            raise fail("tolerance", "is required with method: auto (an L1 error, e.g. 0.05)")
        if chain:
            raise fail("method", f"'auto' needs a single-block model; {self.model.name} is a chain")
        if self.analytic:
            raise fail("analytic", "method: auto chooses the method itself (remove 'analytic')")
        if self.sweep is not None:
            raise fail("method", "'auto' chooses per parameter set: run each point on its own")
        if self.simulation is not None:
            for name in ("n_paths", "dt", "solver"):
                if name in self.simulation.model_fields_set:
                    raise fail(f"simulation.{name}", "is chosen by method: auto (remove it)")
        for i, name in enumerate(self.outputs or ()):
            if name not in AUTO_OUTPUTS:
                raise fail(
                    f"outputs.{i}",
                    f"method: auto computes {' and '.join(AUTO_OUTPUTS)} only, not '{name}'",
                )

    def resolved_outputs(self) -> tuple[str, ...]:
        """The outputs, with the default filled in."""
        if self.outputs is not None:
            return tuple(self.outputs)
        if self.method == "auto":
            return AUTO_OUTPUTS
        from .._model import ChainModel

        if isinstance(self.model.instance, ChainModel):
            return ("event_size", "event_duration", "time_series")
        return ("slip_time", "period", "slip_distance")

    def _check_sweep(self):
        base = self.model_dump(exclude={"sweep"}, exclude_unset=True)
        for path, values in self.sweep.parameters.items():
            where = f"sweep.parameters.{path}"
            parts = path.split(".")
            if (
                parts[0] in ("sweep", "outputs", "analytic")
                or parts[0] not in type(self).model_fields
            ):
                raise fail(where, f"cannot sweep '{path}': not a setting of a study")
            if parts[:2] == ["model", "params"]:
                names = list(type(self.model.instance).parameters())
                if len(parts) < 3 or parts[2] not in names:
                    raise fail(
                        where,
                        f"unknown parameter of {self.model.name} (parameters: {', '.join(names)})"
                        + suggest(parts[-1], names),
                    )
            elif not _settable(type(self), parts):
                raise fail(where, f"cannot sweep '{path}': no such setting")
            for j, value in enumerate(values):
                data = set_path(base, path, value)
                try:
                    Study.model_validate(data)
                except ValidationError as err:
                    loc, reason = locate(first_error(err))
                    raise fail(f"{where}.{j}", f"value {short(value)}: {loc}: {reason}") from None

    def points(self) -> list[tuple[dict[str, Any], Study]]:
        """The studies to run: `[(swept values, study without sweep), ...]`."""
        if self.sweep is None:
            return [({}, self)]
        base = self.model_dump(exclude={"sweep"}, exclude_unset=True)
        out = []
        for point in self.sweep.points():
            data = base
            for path, value in point.items():
                data = set_path(data, path, value)
            out.append((point, Study.model_validate(data)))
        return out


def _settable(model_cls, parts) -> bool:
    """True if a dotted path names a (nested) field of a pydantic model class."""
    import types
    import typing

    cls = model_cls
    for part in parts:
        if not (isinstance(cls, type) and issubclass(cls, BaseModel)):
            return False
        field = cls.model_fields.get(part)
        if field is None:
            return False
        ann = field.annotation
        # unwrap Optional[X]
        if typing.get_origin(ann) in (typing.Union, types.UnionType):
            args = [a for a in typing.get_args(ann) if a is not type(None)]
            ann = args[0] if len(args) == 1 else ann
        cls = ann
    return True


def set_path(data: dict, path: str, value: Any) -> dict:
    """A copy of nested `data` with the dotted `path` set to `value` (missing levels are
    created; a numeric part indexes a list)."""
    import copy

    out = copy.deepcopy(data)
    parts = path.split(".")
    node = out
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            where = ".".join(parts[:i])
            try:
                idx = int(part)
            except ValueError:
                raise KeyError(f"'{where}' is a list: index it by number") from None
            if not -len(node) <= idx < len(node):
                raise KeyError(f"'{where}' has {len(node)} item(s): no index {idx}")
            if last:
                node[idx] = value
            else:
                node = node[idx]
            continue
        if not isinstance(node, dict):
            raise KeyError(f"'{'.'.join(parts[:i])}' is not a mapping or list")
        if last:
            node[part] = value
        else:
            if node.get(part) is None:
                node[part] = {}
            node = node[part]
    return out


def first_error(err: ValidationError) -> dict:
    """The error to report: an unknown key first (a misspelt required key is also reported
    missing, and the typo is the useful news), else the first."""
    errors = err.errors()
    for e in errors:
        if e["type"] == "extra_forbidden":
            return e
    return errors[0]


def describe_error(e: dict) -> str:
    """One pydantic error as a reason: 'must be ...' with the offending value."""
    msg = e["msg"]
    if e["type"] == "stickslip":
        return e["ctx"]["reason"]
    if e["type"] == "missing":
        return "is required"
    if e["type"] == "extra_forbidden":
        return "unknown key"
    msg = msg.replace("Input should be", "must be").replace("Value error, ", "")
    msg = msg.replace("must be a valid number", "must be a number")
    for words, sym in (
        ("greater than or equal to", ">="), ("less than or equal to", "<="),
        ("greater than", ">"), ("less than", "<"),
    ):  # fmt: skip
        msg = msg.replace(f"must be {words}", f"must be {sym}")
    if e["type"] in ("model_type", "dict_type"):
        msg = f"must be a mapping of keys to values (got {yaml_type(e.get('input'))})"
    elif e["type"] == "list_type":
        msg = f"must be a list (got {yaml_type(e.get('input'))})"
    elif e["type"] == "too_short":
        msg = "must not be empty"
    elif e["type"] == "string_pattern_mismatch" and e["ctx"]["pattern"] == CANDIDATE_NAME:
        msg = (
            "must be up to 40 letters, digits, '_', '.' or '-', the first a letter or digit "
            f"(it names a file; got {short(e.get('input'))})"
        )
    elif "input" in e:
        value = e["input"]
        if not isinstance(value, dict | list):
            msg += f" (got {'null' if value is None else short(value)})"
    return msg


def yaml_type(value) -> str:
    names = {dict: "a mapping", list: "a list", str: "a string", bool: "a boolean",
             int: "an integer", float: "a number", type(None): "null"}  # fmt: skip
    return names.get(type(value), type(value).__name__)


def locate(e: dict) -> tuple[str, str]:
    """The dotted location and the reason of one pydantic error (custom errors carry a
    location relative to where they were raised)."""
    loc = [str(p) for p in e["loc"]]
    if e["type"] == "stickslip":
        loc += [p for p in e["ctx"]["loc"].split(".") if p]
    reason = describe_error(e)
    if e["type"] == "extra_forbidden":
        fields = _fields_at(loc[:-1])
        if fields:
            reason += f" (known: {', '.join(fields)})" + suggest(loc[-1], fields)
    return ".".join(loc) or "study", reason


def _fields_at(loc) -> list[str]:
    """Field names of the (sub-)model at a location of the study."""
    import types
    import typing

    cls: Any = Study
    for part in loc:
        if part.isdigit():
            continue
        if not (isinstance(cls, type) and issubclass(cls, BaseModel)):
            return []
        field = cls.model_fields.get(part)
        if field is None:
            return []
        ann = field.annotation
        while typing.get_origin(ann) in (typing.Union, types.UnionType, list):
            args = [a for a in typing.get_args(ann) if a is not type(None)]
            ann = args[0]
        cls = ann
    if isinstance(cls, type) and issubclass(cls, BaseModel):
        return list(cls.model_fields)
    return []
