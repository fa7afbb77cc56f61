r"""What a kind of measured trace is, as one class: `TraceKind`.

A kind of trace (a spring force, a position and/or velocity, or a user's own sensor) says
two things, both here: how the cycles are read from such a trace (`extract`, behind
`extract_cycles`), and what its measurement does to a simulated cycle (`measurement`,
`synthesise`, `record`, `extracted`, behind a fit through the measurement). The kinds are
plugins of the entry-point group `stickslip.trace_kinds`, the built-in ones registered
there exactly as a third-party package registers its own (`stickslip.trace_kinds`
holds them).
"""

from __future__ import annotations

import abc
import dataclasses
import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from ._errors import ParameterError, PluginError
from ._keyed import keyed_grid, noise_pool
from ._registry import TRACE_KIND_GROUP, Registry


@dataclasses.dataclass(frozen=True, eq=False)
class SimulatedPath:
    """One path of the model's successive cycles, as `TraceKind.synthesise` receives it
    (model units).

    - `t`, `x`, `v`: the recorded states' times (non-decreasing) and the position and
      velocity there (linear between them: exact along a stick);
    - `release`, `slip`, `stick`: each cycle's release time, slip time and stick time;
    - `seed`, `path`: the simulation's seed and this path's index (key the noise by them);
    - `v_b`: the driving speed; `rng`: a generator of this path's own (e.g. for phases);
    - `cut`: whether the caller asked for only the stretches about the slips (a kind that
      cannot cut synthesises the whole trace).
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    release: np.ndarray
    slip: np.ndarray
    stick: np.ndarray
    seed: int
    path: int
    v_b: float
    rng: np.random.Generator
    cut: bool = False


class TraceKind(abc.ABC):
    r"""A kind of measured trace: its reader and what its measurement does to a simulated
    cycle. Subclass it, set the class attributes and write the abstract methods, and
    register the class under the entry-point group `stickslip.trace_kinds` (or, in a
    script, with `register_trace_kind`).

    **Class attributes:**

    - `name`: what messages call it ("force", "x/v");
    - `signals`: the values of `Measurement.signal` (and of `Cycles.info["input"]`, which
      `extract` records) that are this kind;
    - `inputs`: the keyword arguments of `extract_cycles` that make a trace of this kind
      (`force`, `stiffness`); a user's kind may name its own (`extract_cycles(t,
      pressure=...)`);
    - `options`: the settings of `extract_cycles` it takes (`window`, `tol`, ...);
    - `fields`: the fields of `Measurement` that are its own (another kind's refuses them);
      a user's kind keeps its settings in `Measurement.options`;
    - `info_keys`: what `Measurement.from_cycles` needs in `Cycles.info` besides `input`,
      `sampling_interval` and `noise_sd`;
    - `quantities`: the tag of `stickslip.quantities` whose per-cycle columns its tables
      have (`"trace"`: release, slip, stick times, slip distance, period);
    - `in_si`: whether its cycles are in SI units (a fit then needs the model's scales and
      `to_model_units`);
    - `default`: the kind `extract_cycles` reads when no kind's inputs are given (one kind).

    **Methods** (model units throughout, except `extract` and `measurement`, which see the
    trace as measured):

    - `extract(t, given, v_b, options)`: the `Cycles` of a trace; `given` holds this
      kind's inputs, `options` every setting given to `extract_cycles` (refuse the others'
      with `refuse_options`);
    - `measurement(info, columns, scales)`: the keyword arguments of `Measurement` that
      describe how a trace with this `Cycles.info` was measured, in the model's units;
    - `settings(measurement, v_b)`: the keyword arguments (besides the trace) that
      `extract_cycles` takes for a simulated trace of this measurement;
    - `record(measurement, t, x, v, noise, rng)`: the signals this measurement records at
      times `t` from the model's position and velocity there, `noise` one standard normal
      a sample (keyed: common random numbers);
    - `synthesise(measurement, path)`: one `SimulatedPath` as a recorded trace (by default
      sampled at the measurement's interval on a grid re-anchored at each cycle and
      passed through `record`); `extracted(signals, measurement, v_b)`: its cycle table.
    """

    name: ClassVar[str] = ""
    signals: ClassVar[tuple[str, ...]] = ()
    inputs: ClassVar[tuple[str, ...]] = ()
    options: ClassVar[tuple[str, ...]] = ()
    fields: ClassVar[tuple[str, ...]] = ()
    info_keys: ClassVar[tuple[str, ...]] = ()
    quantities: ClassVar[str] = "trace"
    in_si: ClassVar[bool] = False
    default: ClassVar[bool] = False

    @abc.abstractmethod
    def extract(self, t, given: dict[str, Any], v_b, options: dict[str, Any]):
        """The `Cycles` of the trace `given` at times `t`."""

    @abc.abstractmethod
    def measurement(self, info: Mapping, columns: tuple[str, ...], scales) -> dict[str, Any]:
        """`Measurement`'s keyword arguments read from a `Cycles.info`."""

    @abc.abstractmethod
    def record(self, measurement, t, x, v, noise, rng) -> dict[str, np.ndarray]:
        """The recorded signals (`t` and this kind's inputs) at times `t`."""

    def settings(self, measurement, v_b: float) -> dict[str, Any]:
        """`extract_cycles`' settings for a simulated trace: `v_b` and the measurement's
        `options`."""
        return dict(v_b=v_b, **dict(measurement.options))

    def prepare(self, measurement, seed: int) -> None:
        """Called once before the paths are synthesised (on two threads): the default
        makes the noise pool of `seed` that the default `synthesise` reads."""
        noise_pool(seed)

    def synthesise(self, measurement, path: SimulatedPath) -> dict[str, np.ndarray]:
        """The recorded trace of one path: sampled every `measurement.sampling_interval` on
        a grid re-anchored in the middle of each stick at the next cycle's keyed phase,
        its noise keyed by cycle too (a parameter change that moves earlier cycles leaves a
        cycle's samples as they were), then `record`."""
        h = measurement.sampling_interval
        grid, noise = keyed_grid(path.release, path.slip, path.stick, path.t[-1], h,
                                 path.seed, path.path)  # fmt: skip
        x = np.interp(grid, path.t, path.x)
        v = np.interp(grid, path.t, path.v)
        return self.record(measurement, grid, x, v, noise, path.rng)

    def extracted(self, signals: dict, measurement, v_b: float) -> dict[str, np.ndarray]:
        """The cycle table of a synthesised trace: `extract` with `settings` (as
        `extract_cycles(**signals, **settings)` reads it)."""
        settings = dict(self.settings(measurement, v_b))
        v_b = settings.pop("v_b")
        given = {k: settings.pop(k, None) for k in self.inputs}  # (a force's stiffness)
        given.update({k: signals[k] for k in self.inputs if k in signals})
        options = {k: v for k, v in settings.items() if v is not None}
        return self.extract(signals["t"], given, v_b, options).table

    def to_model_units(self, table: dict, scales, info: Mapping) -> dict[str, np.ndarray]:
        """The cycles' columns in the model's units (a kind `in_si` converts them)."""
        return table

    def refuse_options(self, options: Mapping[str, Any]) -> None:
        """A `ParameterError` for the first setting in `options` that is not this kind's:
        "applies to <its kind> traces only"."""
        for key in options:
            if key not in self.options:
                owner = next((k for k in trace_kinds() if key in k.options), None)
                what = f"applies to {owner.name} traces only" if owner else "is not a setting"
                raise ParameterError(OWNER, key, what)


OWNER = "extract_cycles"

TRACE_KINDS = Registry(TRACE_KIND_GROUP, lambda: TraceKind, "trace kind", "stickslip.TraceKind")


def trace_kinds() -> tuple[TraceKind, ...]:
    """One instance of each registered trace kind, by registry name; a `PluginError` where
    none is (the built-in ones come through the package's own entry points)."""
    kinds = tuple(cls() for cls in TRACE_KINDS.all().values())
    if not kinds:
        raise PluginError(
            f"no kind of trace is registered under the entry points '{TRACE_KIND_GROUP}': "
            "the installed package's metadata predates them; reinstall stickslip "
            "(pip install -e . in a source checkout)"
        )
    return kinds


def list_trace_kinds() -> dict[str, type[TraceKind]]:
    """All available trace kinds, `{name: class}`, sorted by name (entry-point plugins,
    then those added with `register_trace_kind`)."""
    return TRACE_KINDS.all()


def register_trace_kind(name: str, cls: type[TraceKind]) -> None:
    """Register a trace kind under `name` for this process (no packaging needed).
    Packages should prefer the `stickslip.trace_kinds` entry point."""
    TRACE_KINDS.register("register_trace_kind", name, cls)


def get_trace_kind(name: str | type[TraceKind]) -> type[TraceKind]:
    """The trace kind registered as `name` (a class is returned unchanged); a
    `PluginError` lists the known ones."""
    return TRACE_KINDS.get(name)


def kind_of_signal(signal) -> TraceKind | None:
    """The kind whose `signals` hold `signal` (`Measurement.signal`, `Cycles.info["input"]`),
    or None."""
    return next((k for k in trace_kinds() if signal in k.signals), None)


def all_signals() -> tuple[str, ...]:
    return tuple(s for k in trace_kinds() for s in k.signals)


def default_kind() -> TraceKind:
    """The kind `extract_cycles` reads when none of any kind's inputs is given."""
    kind = next((k for k in trace_kinds() if k.default), None)
    if kind is None:
        raise PluginError("no registered kind of trace is the default (MotionTrace is)")
    return kind


def info_number(info: Mapping, key: str) -> float:
    """`info[key]` as a finite number >= 0, or a `ParameterError` naming it."""
    try:
        value = float(info[key])
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value) or value < 0:
        raise ParameterError("Measurement", f"cycles.info['{key}']",
                             "must be a finite number >= 0", info[key])  # fmt: skip
    return value
