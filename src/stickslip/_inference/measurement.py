r"""The measurement inside the forward model.

Cycles extracted from a sampled trace are not the model's per-cycle values: the sampling
joins what it cannot resolve (a stick shorter than a few samples, zero-length ones among
them, runs the slips on either side into one; an immediate re-stick is invisible), times
each transition to within a sampling interval, and the noise moves the thresholds. Rather
than emulate that by a rule on per-cycle values, the model's cycles are passed through the
same measurement as the data, so that data and model are compared like with like:

1. the model runs as one continuous trace of successive cycles (`simulate_cycles`, every
   cycle from the onset state, eq. 9 in the sticks);
2. the trace is sampled at the data's interval $h$ (the recorded slip states, one per
   simulator step $\Delta t = h/2$ by default, interpolated linearly; the sticks are linear
   in closed form); for position and velocity traces each cycle at its own keyed phase
   from its release, the grid re-anchored in the middle of the stick before it
   (`keyed_grid`), so that a parameter change that moves earlier cycles leaves a cycle's
   sampling as it was (common random numbers);
3. the data's noise model is added (white Gaussian of the measured sd, keyed by cycle and
   sample from its release: `keyed_grid` for position and velocity traces,
   `keyed_samples` for a force trace, whose one uniform grid cannot be re-anchored; for a
   force trace also spikes, keyed alike, and mains lines as `extract_cycles` reported
   them);
4. `extract_cycles` runs with the data's settings, and its per-cycle columns are returned.

`Measurement.from_cycles` reads the measurement from a `Cycles` (its `info`, also kept in
the CSV header). Per-cycle data given as a dict of arrays carry no measurement.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np

from .._cpu import on_two_threads
from .._errors import (
    DataError,
    ParameterError,
    StickSlipError,
    check_int,
    check_nonnegative,
    check_positive,
)
from .._keyed import NOISE_STREAM, segments
from .._trace_kind import (
    SimulatedPath,
    TraceKind,
    all_signals,
    default_kind,
    kind_of_signal,
    trace_kinds,
)
from ..quantities import names

OWNER = "Measurement"
CYCLE_COLUMNS = names("measurement")
# Longest slip followed, in slow time scales (fit's default is 50; the slider's slips last
# 3-7 of them, its sticks some 100): a slip still going there ends its path's trace (and
# the trace is refused where fewer than half the cycles stick), as it ended the pilot's.
_PILOT_HORIZON = 200.0
# Successive cycles run as several paths (vectorised over paths): 500 cycles a path lose
# 0.4 % of them to the cut ends of each path's trace, 64 paths bound the padding. Two
# paths or more are synthesised and extracted on two threads (`_cpu.on_two_threads`): the default
# fit's 1000 cycles a point as two paths took 0.105 s a point against 0.119 s as one
# (`benchmarks/fit_forward.py`).
_CYCLES_PER_PATH = 500
_MAX_PATHS = 64
# ... but a slip-and-stick model with memory (`carries_state`) runs its cycles one round at
# a time, every path's next cycle in one round (`simulate_cycles`): 1000 cycles of one path
# were 1000 rounds, 6x the memoryless model's time on the measured slider's random
# threshold. In paths of this many cycles, 1000 are some 32 rounds (about 3x a memoryless
# model's single round, 1.3x its doubling rounds before); each path's cut
# ends lose ~2 of them, and each path starts at the onset state: a memory of a cycle or two
# (a stick that carries its force into the next slip) has relaxed by the second cycle. A
# creeping slider (rate and state), whose state relaxes over many cycles, keeps long paths.
_CYCLES_PER_PATH_MEMORY = 32
# The recorded slip states are interpolated linearly onto the sampling grid: with a step
# of half the sampling interval (and of the fastest time scale) the position errs by
# dt^2 |a| / 8 (3e-4 at dt = 0.05 on the public set), the velocity by the friction noise's
# change over a step (~1e-2 there), both far below the timing resolution h.
_STEPS_PER_SAMPLE = 2.0
# ... but no finer than an eighth of the fastest time scale (a sampling far finer than the
# model's own scales would cost steps without changing what the samples show: the slip is
# smooth between steps, its position to (dt / scale)^2 / 8 = 2e-3 of its scale's change).
_FINEST = 0.25
# Peak bytes per sample of the sampled trace: the grid, x, v, the noise, the signal and the
# extraction's work arrays of one path (about ten float arrays at a time), counted on all.
_TRACE_BYTES = 8 * 10
# How the forward measurement treats a force trace's sticks (`measured_cycles`): "cut",
# only the stretches about the slips synthesised and extracted (`cut_grid`), or "whole".
STICKS = ("cut", "whole")
# The samples kept about a slip (`cut_grid`): its own length and this many force-rate
# windows either side. The extraction's shape fit takes the slip's stretch (its length and
# half a window each side) and as much again either side (at least a window), its drop the
# median of a window beyond that: 2 windows and the slip's length from it; one more for
# the force rate's filter and the despiking's running median.
_CUT_MARGIN = 3


@dataclasses.dataclass(frozen=True)
class Measurement:
    r"""How a trace was measured and its cycles extracted, in the model's units.

    - `sampling_interval` $h$ (> 0): the trace's (median) sampling interval;
    - `signal`: what was recorded and given to `extract_cycles`: `"x"` (position), `"v"`
      (velocity), `"x and v"` or `"force"` (the spring force, in units of $k x_0$: the
      model's position), or a signal of a plugin's trace kind;
    - `noise_sd` ($\ge 0$): sd of white Gaussian noise on that signal (for `"x and v"`
      on the velocity: `extract_cycles` does not measure the position's noise, taken as 0);
    - `tol`, `min_stick` (`x`/`v`): the stuck band, when it was given (None: from the
      trace's own noise, as on the data), and the fewest stuck values a stick holds;
    - `window`, `thresholds` (`force`): the force-rate filter's samples and the detection
      thresholds (as `extract_cycles` takes them);
    - `spike_fraction`, `spike_height` (`force`): the fraction of samples replaced as
      spikes and a spike's height (twice the detection threshold: the height beyond it is
      not reported and does not change what the despiking does);
    - `lines`, `line_amplitude` (`force`): the frequencies of the spectral lines notched
      out (cycles per model time unit), and their amplitude in the simulated trace (not
      reported by `extract_cycles`: one noise sd, which its detector finds and notches out);
    - `columns`: the per-cycle columns the data have;
    - `options`: the settings of a trace kind from a plugin (a mapping; the built-in
      kinds keep theirs in the fields above).

    Each `signal` belongs to a kind of trace (`kind`, a `stickslip.trace_kinds.TraceKind`),
    which reads its settings from `Cycles.info` and knows what its measurement does to a
    simulated cycle; another kind's fields are refused.
    `Measurement.from_cycles(cycles)` reads all of it from a `Cycles`.
    """

    sampling_interval: float
    signal: str
    noise_sd: float = 0.0
    tol: float | None = None
    min_stick: int | None = None
    window: int | None = None
    thresholds: tuple[tuple[str, float], ...] | None = None
    spike_fraction: float = 0.0
    spike_height: float = 0.0
    lines: tuple[float, ...] = ()
    line_amplitude: float = 0.0
    columns: tuple[str, ...] = ("slip_time", "slip_distance", "stick_time", "period")
    options: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self):
        def put(name, value):  # (frozen: store the checked values)
            object.__setattr__(self, name, value)

        put("sampling_interval", check_positive(OWNER, "sampling_interval",
                                                self.sampling_interval))  # fmt: skip
        kind = kind_of_signal(self.signal)
        if kind is None:
            raise ParameterError(
                OWNER, "signal", f"must be one of {', '.join(map(repr, all_signals()))}",
                self.signal,
            )  # fmt: skip
        put("noise_sd", check_nonnegative(OWNER, "noise_sd", self.noise_sd))
        defaults = {f.name: f.default for f in dataclasses.fields(self)}
        for other in trace_kinds():  # another kind's settings, left unset
            for name in other.fields:
                if name in defaults and name not in kind.fields and _is_set(getattr(self, name)):
                    raise ParameterError(OWNER, name, f"applies to {other.name} traces only")
        put("tol", check_positive(OWNER, "tol", self.tol, allow_none=True))
        if self.min_stick is not None:
            put("min_stick", check_int(OWNER, "min_stick", self.min_stick, minimum=1))
        if self.window is not None:
            put("window", check_int(OWNER, "window", self.window, minimum=5))
        if self.thresholds is not None:
            items = self.thresholds.items() if isinstance(self.thresholds, Mapping) else None
            if items is None:
                raise ParameterError(OWNER, "thresholds", "must be a mapping of names to numbers")
            put("thresholds", tuple(sorted(
                (str(k), check_positive(OWNER, f"thresholds[{k!r}]", v)) for k, v in items
            )))  # fmt: skip
        put("spike_fraction", check_nonnegative(OWNER, "spike_fraction", self.spike_fraction))
        if self.spike_fraction >= 1.0:
            raise ParameterError(OWNER, "spike_fraction", "must be < 1", self.spike_fraction)
        put("spike_height", check_nonnegative(OWNER, "spike_height", self.spike_height))
        put("lines", tuple(check_positive(OWNER, "lines", f) for f in self.lines))
        put("line_amplitude", check_nonnegative(OWNER, "line_amplitude", self.line_amplitude))
        columns = tuple(self.columns)
        unknown = [c for c in columns if c not in CYCLE_COLUMNS]
        if unknown or not columns:
            raise ParameterError(
                OWNER, "columns", f"must be some of {', '.join(CYCLE_COLUMNS)}",
                ", ".join(map(str, unknown)) or None,
            )  # fmt: skip
        foreign = [c for c in columns if c not in names(kind.quantities)]
        if foreign:
            giver = next((k for k in trace_kinds() if set(foreign) <= set(names(k.quantities))),
                         None)  # fmt: skip
            verb = "needs" if len(foreign) == 1 else "need"
            need = f"{verb} a {giver.name} trace" if giver else f"{verb} another kind of trace"
            raise ParameterError(OWNER, "columns", f"{' and '.join(foreign)} {need}")
        options = self.options
        items = options.items() if isinstance(options, Mapping) else options
        try:  # a mapping, or its (name, value) pairs (as a saved fit keeps them)
            put("options", tuple(sorted((str(k), v) for k, v in items)))
        except (TypeError, ValueError):
            raise ParameterError(OWNER, "options", "must be a mapping of a trace kind's "
                                 "settings by name", options) from None  # fmt: skip
        put("columns", columns)

    @classmethod
    def from_cycles(cls, cycles, scales=None) -> Measurement:
        """The measurement of the trace `cycles` were extracted from (`Cycles.info`).

        **Arguments:**

        - `cycles`: a `Cycles` from `extract_cycles`, or read back from its CSV (the
          settings are in its `#` header);
        - `scales`: for a force trace in SI (or a `Slider.to_model` one), the model's units:
          a `stickslip.units.Scales` or a `Slider`; times are divided by its `time`, forces
          by its `force` ($k x_0$). Position and velocity traces are taken in the model's
          units, as `fit` takes their cycles.

        **Returns:** a `Measurement`. A `ParameterError` names what `info` lacks (a table
        from an older file without its settings, or a dict: per-cycle values carry no
        measurement).
        """
        info = getattr(cycles, "info", None)
        table = getattr(cycles, "table", None)
        if not isinstance(info, Mapping) or not isinstance(table, Mapping):
            raise ParameterError(
                OWNER, "cycles", "must be a Cycles from extract_cycles (a dict of per-cycle "
                "values carries no measurement)",
            )  # fmt: skip
        if "si" in info and isinstance(info["si"], Mapping):
            info = info["si"]  # `Slider.to_model`: the extraction's own settings, in SI
        columns = tuple(c for c in CYCLE_COLUMNS if c in table)
        signal = info.get("input")
        kind = kind_of_signal(signal) or default_kind()
        need = ["input", "sampling_interval", "noise_sd", *kind.info_keys]
        missing = [k for k in need if k not in info]
        if missing:
            raise ParameterError(
                OWNER, "cycles.info", f"lacks {', '.join(missing)}: the settings of the "
                "extraction are needed to model the measurement (a table from an older file "
                "without them? extract the cycles again)",
            )  # fmt: skip
        if kind_of_signal(signal) is None:
            raise ParameterError(OWNER, "cycles.info['input']", "is not a known signal", signal)
        return cls(**kind.measurement(info, columns, scales))

    @property
    def kind(self) -> TraceKind:
        """The kind of trace this measurement records (`stickslip.trace_kinds`)."""
        return kind_of_signal(self.signal)

    def extract_settings(self, v_b: float) -> dict[str, Any]:
        """The keyword arguments of `extract_cycles` (besides the trace) for a trace of
        this measurement driven at `v_b` (model units; a force in units of $k x_0$:
        stiffness 1)."""
        return self.kind.settings(self, v_b)


def _is_set(value) -> bool:
    """Whether a kind's setting is given: not None, not an empty sequence, not 0."""
    if value is None:
        return False
    if isinstance(value, (tuple, list, np.ndarray, Mapping)):
        return len(value) > 0
    return not (isinstance(value, (int, float)) and value == 0)


@dataclasses.dataclass(frozen=True, eq=False)
class MeasuredTrace:
    """A simulated trace as the measurement records it (`measured_trace`).

    - `traces`: one dict per path, `t` and the recorded signal(s) (`x`, `v` or `force`),
      noise included;
    - `truth`: the model's own successive cycles behind them (`simulate_cycles`' table,
      ordered by path then cycle);
    - `measurement`, `dt` (the simulator's step).
    """

    traces: tuple[dict[str, np.ndarray], ...]
    truth: dict[str, np.ndarray]
    measurement: Measurement
    dt: float


def measured_trace(model, measurement: Measurement, n_cycles: int, seed: int, *,
                   dt: float | None = None, sticks: str = "whole") -> MeasuredTrace:  # fmt: skip
    """The model as a continuous trace of about `n_cycles` successive cycles, sampled and
    made noisy as `measurement` says; see `measured_cycles`. `sticks="cut"` (a force trace
    with a given `window`): the middles of the long sticks left out (`cut_grid`), each
    trace's `cut` saying which samples of the whole trace were kept."""
    from .._model import CreepingSlider, time_scales

    owner = "measured_cycles"
    names, n_cycles, seed = _checked(owner, model, measurement, n_cycles, seed, sticks)
    if isinstance(model, CreepingSlider):  # its stationary motion, after a burn-in
        from .creeping import creeping_trace

        return creeping_trace(owner, model, measurement, n_cycles, seed, dt, sticks)
    h = measurement.sampling_interval
    scales = time_scales(model)
    fast, slow = (1.0, 1.0) if scales is None else scales
    if dt is None:
        dt = min(max(h, _FINEST * fast), fast) / _STEPS_PER_SAMPLE
    dt = check_positive(owner, "dt", dt)
    short = model.carries_state
    per_path = _CYCLES_PER_PATH_MEMORY if short else _CYCLES_PER_PATH
    n_paths = int(min(_MAX_PATHS, max(1, round(n_cycles / per_path))))
    horizon = max(_PILOT_HORIZON * slow, 2 * dt)
    series = _series(owner, model, n_cycles, n_paths, dt, horizon, seed, h)
    ix, iv = names.index("x"), names.index("v")
    table = series.cycles
    kind = measurement.kind
    kind.prepare(measurement, seed)  # (here, not by two paths' threads at once)

    def path_signals(p):
        t, states, _ = series.trajectory(p)
        # the slip samples lie at release + k dt, which may pass the stick by rounding
        t = np.maximum.accumulate(np.asarray(t, float))
        rows = table["path"] == p
        return kind.synthesise(measurement, SimulatedPath(
            t=t, x=states[:, ix], v=states[:, iv], release=table["release_time"][rows],
            slip=table["slip_time"][rows], stick=table["stick_time"][rows], seed=seed, path=p,
            v_b=float(model.v_b), rng=np.random.default_rng([seed, NOISE_STREAM, p]),
            cut=sticks == "cut",
        ))  # fmt: skip

    traces = on_two_threads(path_signals, n_paths)
    return MeasuredTrace(tuple(traces), dict(series.cycles), measurement, dt)


def _checked(owner, model, measurement, n_cycles, seed, sticks):
    """`measured_trace`'s arguments checked: the model's state names, `n_cycles`, `seed`."""
    from .._model import CreepingSlider, FrictionModel

    if not isinstance(model, FrictionModel):
        raise ParameterError(owner, "model", "must be a FrictionModel instance")
    names = tuple(model.state_names)
    if not isinstance(model, CreepingSlider) and ("x" not in names or "v" not in names):
        raise ParameterError(
            owner, "model", "must have states x and v (a single-block model): the trace "
            f"records them (states: {', '.join(names)})",
        )  # fmt: skip
    if not isinstance(measurement, Measurement):
        raise ParameterError(owner, "measurement", "must be a Measurement")
    n_cycles = check_int(owner, "n_cycles", n_cycles, minimum=10)
    seed = check_int(owner, "seed", seed, minimum=0)
    if sticks not in STICKS:
        raise ParameterError(owner, "sticks", f"must be one of {', '.join(map(repr, STICKS))}",
                             sticks)  # fmt: skip
    return names, n_cycles, seed


def _series(owner, model, n_cycles, n_paths, dt, horizon, seed, h):
    """The model's successive cycles on `n_paths` paths, their slips recorded, each path's
    trace checked against the memory limit first."""
    from .._simulate.cycles import counted_cycles

    # each path's share of the cycles, counted (`counted_cycles`), their trace's size
    # checked before their slips are recorded
    count = math.ceil(n_cycles / n_paths)

    def check(cycles):
        stuck = int(np.sum(np.isfinite(cycles["period"])))
        if stuck < n_paths * count // 2:
            raise DataError(
                f"{owner}: the model sticks again within {_PILOT_HORIZON:g} slow time "
                f"scales in {stuck} of {n_paths * count} successive cycles: no stick-slip "
                "trace to measure"
            )  # fmt: skip
        period = cycles["period"]
        _check_trace(owner, float(np.sum(period[np.isfinite(period)])), n_cycles, h)

    return counted_cycles(model, n_paths, dt, horizon, seed, count, check=check)


def _check_trace(owner: str, duration: float, n_cycles: int, h: float) -> None:
    """The memory check of a trace of this total `duration`, sampled every `h`."""
    from .._memory import check_memory

    check_memory(
        owner, f"a trace of {duration / h:.3g} samples ({n_cycles} cycles at an interval of "
        f"{h:.3g})", _TRACE_BYTES * duration / h, "take fewer cycles",
    )  # fmt: skip


def notched(x, index, rise, lines, h):
    """The noise-free force `x` at the samples `index` of a uniform grid (spacing `h`),
    through the notches `extract_cycles` puts at `lines` (scipy's iirnotch, Q 30, run
    forwards and backwards), as if the whole grid were filtered: between the kept
    stretches the force is the sticks' line, rising `rise` a sample, which the notch passes
    unchanged, so the trace less that line is filtered with its cut stretches constant
    (`_gapped_filtfilt`). A notch 1.7 Hz wide at 50 Hz rings for some 0.2 s about each slip
    (a few noise sd on the measured slider): further than the samples kept, so it cannot be
    left to the extraction of the cut trace. The noise is not notched: the notch takes
    0.2 % of white noise's variance."""
    from scipy.signal import iirnotch

    from .._extract._force import NOTCH_Q

    breaks = np.flatnonzero(np.diff(index) > 1) + 1
    starts = np.r_[0, breaks]
    gaps = np.r_[index[0], index[breaks] - index[breaks - 1] - 1]
    line = rise * index
    # the notches in turn are one filter, their product (zero-phase: their order does not
    # matter); one notch's ringing would not be constant across the next one's gaps
    b, a = np.ones(1), np.ones(1)
    for f in lines:
        bf, af = iirnotch(f, NOTCH_Q, fs=1.0 / h)
        b, a = np.convolve(b, bf), np.convolve(a, af)
    return _gapped_filtfilt(b, a, x - line, starts, gaps) + line


def _gapped_filtfilt(b, a, values, starts, gaps):
    """`scipy.signal.filtfilt(b, a, ..., padlen=0)` of a trace of which only the stretches
    `values[starts[p]:starts[p + 1]]` are given, stretch p after a gap of `gaps[p]` samples
    over which the input stays at the value next to it (the last of the stretch before;
    for a leading gap the first of stretch 0); the filter starts and ends in its steady
    state. The stretches are filtered sample by sample (`lfilter` with the state carried
    in, compiled: `_gapped`), the gaps in closed form in the eigenbasis of the filter's
    state-space matrix M:
    forwards the state's distance from the steady state decays as M^G; backwards the input
    is the forward pass's free ringing, e0 M^n d, whose effect on the state is
    sum_n M^n B e0 M^n d, a geometric sum per pair of eigenvalues. The same numbers as
    filtfilt of the whole trace to rounding (tests/test_cut_measurement.py)."""
    from scipy.signal import lfilter_zi

    from ._gapped import passes

    b, a = np.asarray(b, float) / a[0], np.asarray(a, float) / a[0]
    order = a.size - 1
    M = np.zeros((order, order))
    M[:, 0] = -a[1:]
    M[:-1, 1:] = np.eye(order - 1)
    B = b[1:] - a[1:] * b[0]
    unit = lfilter_zi(b, a)  # the steady state for a unit input
    lam, V = np.linalg.eig(M)
    Vi = np.linalg.inv(V)
    K = Vi @ np.outer(B, np.eye(order)[0]) @ V
    return passes(b, a, values, starts, gaps, unit, lam, V, Vi, K)


def keyed_samples(release, slip, stick, n, h, seed, path, normals, spikes, at=None):
    """Standard normal noise of the samples `k h` (`k` in `at`, by default all `n` of the
    uniform grid: a force trace), if `normals`, and, if `spikes`, uniforms that place its
    spikes (`ForceTrace.record`), both keyed by cycle: a sample in cycle c's stretch (`segments`)
    `j` samples from the first at or after c's release (j < 0 before it) takes the value
    of `(seed, path, c, j)` (`_hashed`). A parameter change that moves the cycles before c
    therefore leaves the noise about c's slip as it was, up to the release's phase within
    one interval (the grid cannot be re-anchored: `extract_cycles` refuses an uneven force
    trace), and a sample's value does not depend on which others are drawn (a cut trace,
    `cut_grid`, has the whole trace's noise on the samples it keeps)."""
    anchors, starts = segments(release, slip, stick, n * h, h)
    first = np.minimum(np.ceil(starts / h - 1e-9), n).astype(np.int64)
    zero = np.ceil(release[anchors] / h - 1e-9).astype(np.int64)
    k = np.arange(n, dtype=np.int64) if at is None else np.asarray(at, np.int64)
    stretch = np.searchsorted(first, k, side="right") - 1  # first[0] is 0
    offset = k - zero[stretch]
    cycle = anchors[stretch]
    noise = _hashed(seed, path, cycle, offset, 0, "normal") if normals else None
    uniforms = _hashed(seed, path, cycle, offset, 2, "uniform") if spikes else None
    return noise, uniforms


_GOLDEN = 0x9E3779B97F4A7C15  # splitmix64's increment


def _mix(z: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser of uint64 values (products wrap around: modulo 2**64)."""
    z = z ^ (z >> np.uint64(30))
    z = z * np.uint64(0xBF58476D1CE4E5B9)
    z = z ^ (z >> np.uint64(27))
    z = z * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def _hashed(seed, path, cycle, offset, stream, kind):
    """A standard normal (`kind="normal"`) or uniform on (0, 1) for each `(cycle, offset)`
    of `(seed, path, stream)`: splitmix64's output at `offset` of the stream whose state the
    key hashes to (the uniform from its top 53 bits, the normal its inverse cdf), computed
    for all samples at once and the same whichever others are drawn. The noise's own
    stream (`NOISE_STREAM`), far from the simulator's keys."""
    from scipy.special import ndtri

    from ._samples import uniforms

    golden = np.uint64(_GOLDEN)
    with np.errstate(over="ignore"):
        head = np.zeros(1, np.uint64)
        for value in (seed, NOISE_STREAM, path, stream):
            head = _mix(head + (np.uint64(value) + np.uint64(1)) * golden)
    u = uniforms(int(head[0]), np.broadcast_to(cycle, np.shape(offset)), offset)
    return ndtri(u) if kind == "normal" else u


def cut_grid(release, slip, stick, n, h, window):
    """Which samples of a force trace's uniform grid (`n` samples at `h`) the forward
    measurement keeps (`sticks="cut"`): about each slip, from `_CUT_MARGIN` windows plus
    its own length before its release to as many after its stick, the long sticks'
    middles cut out (a cut of fewer than `window` samples is not made). What a slip moves
    in the extraction lies within a few windows and its own length of it (the force rate,
    the medians either side, the shape fit's samples); the rest of a stick is a line and
    the noise, of which the kept far samples (`Cut.far`) stand for the cut ones in the
    trace-wide statistics. Returns a `Cut`."""
    from .._extract._force import Cut
    from ._samples import far_samples

    r = release / h
    e = np.where(np.isfinite(slip), (release + slip) / h, n - 1.0)
    length = np.where(np.isfinite(slip), slip / h, 0.0)
    margin = length + _CUT_MARGIN * window
    lo = np.clip(np.floor(r - margin), 0, n - 1).astype(np.int64)
    hi = np.clip(np.ceil(e + margin), 0, n - 1).astype(np.int64)
    # merge the intervals that overlap or leave less than a window between them
    hi = np.maximum.accumulate(hi)
    new = np.r_[True, lo[1:] > hi[:-1] + window]
    lo = lo[new]
    hi = np.maximum.reduceat(hi, np.flatnonzero(new))
    counts = hi - lo + 1
    index = np.repeat(lo - (np.cumsum(counts) - counts), counts) + np.arange(counts.sum())
    # further than FAR windows from the nearest slip [release, stick]
    far = far_samples(index, r, e, Cut.FAR * window)
    n_far = int(far.sum())
    weight = (n_far + (n - index.size)) / n_far if n_far else 1.0
    return Cut(index=index, far=far, weight=float(weight))


def measured_cycles(model, measurement: Measurement, n_cycles: int, seed: int, *,
                    dt: float | None = None,
                    sticks: str = "cut") -> dict[str, np.ndarray]:  # fmt: skip
    r"""The model's cycles as `measurement` sees them: simulated as a continuous trace,
    sampled, made noisy and extracted with the data's settings.

    **Arguments:**

    - `model`: a single-block model instance (states `x` and `v`), or a creeping slider
      in SI (rate-and-state) measured as a force trace: its stationary motion, each path
      after a burn-in as long as its noise-free motion takes to settle from the onset, in
      SI units with forces over the stiffness (`stickslip.units.Scales.si`: the
      data's `Measurement.from_cycles(cycles, scales=Scales.si(k))`);
    - `measurement`: a `Measurement` (`Measurement.from_cycles(data)`);
    - `n_cycles`: how many model cycles to simulate ($\ge 10$), shared among a few paths
      (a creeping slider's paths last their share times its noise-free period). The
      measured cycles are fewer where the measurement joins cycles (a zero-length stick,
      a stick shorter than `min_stick` samples) or drops a path's cut ends;
    - `seed`: the simulation's seed, and the noise's (its own stream): the same seed gives
      the same cycles, and the same noise draws at every parameter value;
    - `dt`: the simulator's step (default: half the sampling interval, within an eighth
      and a half of the model's fastest time scale);
    - `sticks`: `"cut"` (default) synthesises and extracts a force trace only about its
      slips, the long sticks' middles left out (`cut_grid`; the same cycles as the whole
      trace gives, to within the extraction's timing error: docs/fit.md); `"whole"`
      every sample. Position and velocity traces, and a force measurement without a
      `window`, are synthesised whole.

    **Returns:** a dict with the measurement's `columns` (model units; force columns in
    units of $k x_0$), the cycles of all paths concatenated.

    **Raises:** `ParameterError` for bad arguments, `ResourceError` for a trace past the
    memory limit (said once its cycles are known, before their slips are recorded and the
    trace is sampled), `DataError` where the simulated trace
    shows no cycles through this measurement (e.g. sampling too coarse for this model, or
    no stick-slip), with `extract_cycles`' reason.
    """
    trace = measured_trace(model, measurement, n_cycles, seed, dt=dt, sticks=sticks)

    def table(p):
        try:
            return _extracted(trace.traces[p], measurement, float(model.v_b))
        except StickSlipError as err:
            raise DataError(
                f"measured_cycles: the simulated trace (path {p}) shows no cycles through "
                f"this measurement: {err}"
            ) from None

    with warnings.catch_warnings():  # (here: the filters are the process's, not a thread's)
        warnings.simplefilter("ignore")
        tables = on_two_threads(table, len(trace.traces))
    return {k: np.concatenate([tb[k] for tb in tables]) for k in measurement.columns}


def extracted(signals: dict, measurement: Measurement, v_b: float) -> dict[str, np.ndarray]:
    """The whole cycle table of one path of a `MeasuredTrace`: `extract_cycles` with the
    measurement's settings, or for a cut force trace (`"cut"` in `signals`) the same
    extraction on the kept samples, without the notch its making applied already. The
    simulated sticks move at exactly v_b and the noise is the data's: a warning here is
    about the simulation, which the fit reports in its own terms, and is not shown."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return _extracted(signals, measurement, v_b)


def _extracted(signals: dict, measurement: Measurement, v_b: float) -> dict[str, np.ndarray]:
    """`extracted` with the warnings left to the caller (who may run it in a thread: the
    warning filters are the process's)."""
    return measurement.kind.extracted(signals, measurement, v_b)
