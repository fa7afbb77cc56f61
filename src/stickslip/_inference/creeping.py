r"""A creeping slider (friction with memory, e.g. rate-and-state) as a measured force trace.

A creeping slider's cycles carry the state of the ones before, and a run starts in a
velocity step's transient (`CreepingSlider.onset_state`). What a measured run shows is the
stationary motion, so its forward measurement (`creeping_trace`) is built from that:

1. the noise-free motion from the onset (`limit_cycle`: its successive slips, solved to
   their events) until two successive cycles agree in force drop and period to
   `LIMIT_RTOL`: its period sets how long a path runs for a number of cycles, and the time
   it took sets the **burn-in**, the stretch of every path left out before the trace
   starts (the noise moves the motion about the same limit cycle; a model whose
   noise-free motion settles into steady sliding has no stick-slip trace to measure);
2. the motion, noise included, recorded at the data's sampling interval in chunks of
   `CHUNK` samples (the state carried from one to the next: one compiled solve for any
   length), every path from the onset, its burn-in dropped;
3. the force trace is the spring's extension, the force over the stiffness, in the units
   `si_scales` gives the data (a force over k, a time in seconds); its cycles for the
   keyed noise and the cut grid are read from the samples, where the slider outruns the
   drive (a slip) and falls back (a stick), placed between samples linearly.

What follows is a force trace's measurement as for any model (`TraceKind.synthesise`, then
`extract_cycles` with the data's settings).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import warnings

import numpy as np

from .._errors import DataError, ParameterError

# Successive noise-free cycles agree in force drop and period to this (relative) where the
# motion has reached its limit cycle: the velocity step's transient at the rate-and-state
# example's k = 1002 N/m grows its drops for some 7 cycles, by 1.6 % in the last of them.
LIMIT_RTOL = 1e-3
# The noise-free cycles followed at most; a motion that has not settled by then (a period
# doubling, chaos) is warned about, its burn-in all of them.
LIMIT_CYCLES = 200
# A noise-free motion whose force drops fall below this fraction of the first is settling
# into steady sliding (a decaying oscillation about the drive's speed).
DECAYED = 1e-4
# Samples of one recorded solve (each path's state carried into the next): a fixed count,
# so that the recorded motion compiles once for any trace's length.
CHUNK = 4096
# Paths of a measured trace, run side by side by the recorded solve (padded to a power of
# two, `creep._padded`): as many as keep every path's burn-in within `BURN_SHARE` of the
# cycles kept and at least `MIN_PATH_CYCLES` cycles a path, a power of two up to
# `MAX_PATHS`. The solve's throughput grows with the paths (the noisy slider at k = 1002
# N/m: 9-11, 13-16 and 26-28 path-seconds a second at 8, 16 and 32 paths): 1000 cycles
# after a burn-in of 9 go faster as 32 paths (1288 path-cycles) than as 11 padded to 16.
BURN_SHARE = 0.3
MIN_PATH_CYCLES = 20
MAX_PATHS = 32
# The noise's grid in a measured trace, in the noise's correlation times: a grid of tau / 10
# moved the measured cycles off an independent generator's (`benchmarks/rate_and_state_fit.py
# --law`: k = 1002 N/m, 300 um/s, tau 2 ms, 3000 cycles a side through one measurement): the
# mean drop by -3.0 standard errors, the slip by +2.6, the stick by -2.3 (at tau / 20: -2.1,
# +3.6, -1.3; at tau / 40: within 1.0; at tau / 80: within 0.7), and the likelihood's
# vertex in the noise intensity D on ten 30 s pieces of a trace lay 0.942 times as high as
# on tau / 40 (`--profile`). A tolerance of the steps 100 times tighter changed nothing: it
# is the grid. The cost: 1.7-2.6 times tau / 10's a trace.
NOISE_GRID = 40
# Bytes a recorded sample costs, all paths counted: the position and velocity kept, the
# chunk's states, the synthesised trace's arrays (about ten at a time, as for other models).
_SAMPLE_BYTES = 8 * 12


@dataclasses.dataclass(frozen=True)
class LimitCycle:
    """The noise-free motion's stationary cycle (`limit_cycle`): its `period`, `drop` (N)
    and `slip_time` (s), the `burn_in` (s) its transient takes from the onset, the
    `cycles` followed and whether they `settled` to `LIMIT_RTOL`."""

    period: float
    drop: float
    slip_time: float
    burn_in: float
    cycles: int
    settled: bool


def limit_cycle(model, owner: str = "measured_cycles") -> LimitCycle:
    """The noise-free motion of `model` from its onset state, followed slip by slip (each
    solve to its event, `creep.Motion.segment`) until two successive cycles agree in force
    drop and period to `LIMIT_RTOL` (a warning where they do not within `LIMIT_CYCLES`).
    A `DataError` where the motion settles into steady sliding (its drops fall below
    `DECAYED` of the first, or a stick outlasts any bound the earlier motion suggests)."""
    from .._jax import jax, jnp
    from .._simulate.creep import Motion

    rates = np.abs(np.real(np.asarray(model.linear_rates())))
    slow = 1.0 / float(np.min(rates[rates > 0])) if np.any(rates > 0) else 1.0
    motion = Motion(model, 1.0, math.inf, 0)
    motion.noisy = False  # the drift alone (`segment` solves the noise-free motion)
    force = jax.vmap(motion.model.spring_force)
    y = motion.onsets(1)
    t = np.zeros(1)
    slipping = motion.crossing(y) > 0.0
    peaks: list[tuple[float, float]] = []  # (time, force) at each slip's start
    drops: list[float] = []
    periods: list[float] = []
    slips: list[float] = []
    longest = 100.0 * slow
    while len(drops) < LIMIT_CYCLES:
        motion.t_max = float(t[0]) + max(longest, 100.0 * slow)
        t1, y1, hit, more = motion.segment(y, t, slipping)
        if not hit[0] and not more[0]:
            raise DataError(
                f"{owner}: the noise-free {type(model).__name__} settles into steady sliding "
                f"(no crossing of the drive's speed within {motion.t_max - t[0]:.3g} s after "
                f"t = {t[0]:.4g} s): no stick-slip trace to measure"
            )  # fmt: skip
        if hit[0]:
            F = float(np.asarray(force(jnp.asarray(y1)))[0])
            if slipping[0] and peaks:  # a slip ended: its drop
                drops.append(peaks[-1][1] - F)
                slips.append(float(t1[0]) - peaks[-1][0])
            elif not slipping[0]:  # a stick ended: the next slip starts
                if peaks:
                    periods.append(float(t1[0]) - peaks[-1][0])
                    longest = max(longest, 10.0 * periods[-1])
                peaks.append((float(t1[0]), F))
            slipping = ~slipping
        t, y = t1, y1
        if len(drops) >= 3 and drops[-1] < DECAYED * drops[0]:
            raise DataError(
                f"{owner}: the noise-free {type(model).__name__} settles into steady sliding "
                f"(its force drops fall from {drops[0]:.3g} to {drops[-1]:.3g} N in "
                f"{len(drops)} cycles): no stick-slip trace to measure"
            )  # fmt: skip
        if len(periods) >= 2 and len(drops) >= 2 and not slipping[0]:
            if _agree(drops[-2:]) and _agree(periods[-2:]):
                return LimitCycle(periods[-1], drops[-1], slips[-1], peaks[-1][0],
                                  len(drops), True)  # fmt: skip
    warnings.warn(
        f"{owner}: the noise-free {type(model).__name__}'s cycles do not settle within "
        f"{LIMIT_CYCLES} cycles (successive drops {drops[-2]:.4g}, {drops[-1]:.4g} N; periods "
        f"{periods[-2]:.4g}, {periods[-1]:.4g} s): each path's first {peaks[-1][0]:.4g} s "
        "are left out as its transient",
        stacklevel=3,
    )  # fmt: skip
    return LimitCycle(periods[-1], drops[-1], slips[-1], peaks[-1][0], len(drops), False)


def _agree(pair) -> bool:
    a, b = pair
    return abs(a - b) <= LIMIT_RTOL * max(abs(a), abs(b))


def paths(n_cycles: int, burn_cycles: int) -> int:
    """How many paths a trace of `n_cycles` cycles runs as, each after `burn_cycles`: the
    most, a power of two up to `MAX_PATHS`, whose burn-ins stay within `BURN_SHARE` of the
    cycles and whose paths keep `MIN_PATH_CYCLES` each."""
    n = 1
    while (2 * n <= MAX_PATHS and 2 * n * burn_cycles <= BURN_SHARE * n_cycles
           and n_cycles / (2 * n) >= MIN_PATH_CYCLES):  # fmt: skip
        n *= 2
    return n


def plan(model, n_cycles: int, h: float, owner: str):
    """How a measured trace of about `n_cycles` cycles runs: `(cycle, n_paths, samples,
    burn)`, the noise-free `LimitCycle`, the paths, the samples each records (from its
    onset) and the first of them kept (its burn-in over)."""
    from .._memory import check_memory

    cycle = limit_cycle(model, owner)
    n_paths = paths(n_cycles, max(cycle.cycles, 1))
    share = math.ceil(n_cycles / n_paths)
    burn = int(math.ceil(cycle.burn_in / h))
    samples = burn + int(math.ceil(share * cycle.period / h)) + 1
    check_memory(
        owner, f"a trace of {n_paths} x {samples:.3g} samples ({n_cycles} cycles of "
        f"{cycle.period:.3g} s at an interval of {h:.3g} s, each path after a burn-in of "
        f"{cycle.burn_in:.3g} s)", _SAMPLE_BYTES * n_paths * samples, "take fewer cycles",
    )  # fmt: skip
    return cycle, n_paths, samples, burn


def recorded(model, n_paths: int, samples: int, h: float, dt: float, seed: int):
    """Each path's extension (the force over the stiffness) and velocity at the times
    `k h`, `k < samples`, from the onset: shape `(n_paths, samples)` each, recorded in
    chunks of `CHUNK` samples (`creep.Motion.dense`, the noise on the grid `dt` keyed by
    `(seed, path, node)`). `nan` after a stretch the solver could not cross."""
    from .._simulate.creep import Motion

    motion = Motion(model, dt, samples * h, seed)
    keys = motion.keys(np.arange(n_paths, dtype=np.uint32))
    y = motion.onsets(n_paths)
    x = np.empty((n_paths, samples))
    v = np.empty((n_paths, samples))
    step = np.arange(CHUNK + 1) * h
    for start in range(0, samples - 1, CHUNK):
        ys = motion.dense(y, keys, start * h + step)  # (paths, CHUNK + 1, d)
        stop = min(samples, start + CHUNK + 1)
        xs, vs = _extension_velocity()(motion.model, ys)
        x[:, start:stop] = np.asarray(xs)[:, : stop - start]
        v[:, start:stop] = np.asarray(vs)[:, : stop - start]
        y = ys[:, -1]
    if motion.stats["failed"]:
        warnings.warn(
            f"measured_cycles: the recorded motion of the creeping slider failed on "
            f"{motion.stats['failed']} stretch(es); their paths end there",
            stacklevel=3,
        )
    return x, v


@functools.cache
def _extension_velocity():
    """`(model, ys) -> (extension, velocity)` of states `ys` (paths, samples, d), compiled
    once for a model class and shape (its parameters are inputs; jax imported on first
    use)."""
    import equinox as eqx

    from .._jax import jax

    @eqx.filter_jit
    def both(model, ys):
        return jax.vmap(jax.vmap(lambda y: (model.position(y), model.slider_velocity(y))))(ys)

    return both


def sampled_cycles(t, x, v, v_b: float) -> dict[str, np.ndarray]:
    """The cycles of one recorded path: a slip where the slider outruns the drive
    (`v > v_b`) from its start to its end, then the stick to the next slip's start, each
    crossing placed linearly between its samples; a trace that starts inside a slip
    starts its first cycle at the next slip, and the last slip's stick, unfinished, is
    `nan`. Returns `release_time`, `slip_time`, `stick_time`, `period`, `force_drop`
    (in the trace's units: the extension released) and `peak_force`."""
    c = v / v_b - 1.0
    up = np.flatnonzero((c[:-1] <= 0.0) & (c[1:] > 0.0))
    down = np.flatnonzero((c[:-1] > 0.0) & (c[1:] <= 0.0))

    def at(i):
        return t[i] + (t[i + 1] - t[i]) * c[i] / (c[i] - c[i + 1])

    if up.size == 0:
        empty = np.zeros(0)
        return dict(release_time=empty, slip_time=empty, stick_time=empty, period=empty,
                    force_drop=empty, peak_force=empty)  # fmt: skip
    down = down[down > up[0]]
    n = min(up.size, down.size)
    release, end = at(up[:n]), at(down[:n])
    nxt = np.full(n, np.nan)
    m = min(n, up.size - 1)
    nxt[:m] = at(up[1 : m + 1])
    peak = np.interp(release, t, x)
    trough = np.interp(end, t, x)
    return dict(
        release_time=release, slip_time=end - release, stick_time=nxt - end,
        period=nxt - release, force_drop=peak - trough, peak_force=peak,
    )  # fmt: skip


def in_sticks(v, v_b: float) -> tuple[int, int]:
    """`(first, last)`: the samples `v[first:last]` of a recorded path that begin and end
    in a stick (`v <= v_b`). A path recorded from the end of its burn-in starts at any
    phase: one that starts inside a slip starts after it ends, one that ends inside a
    slip ends where that slip began. A slip the trace holds only in part is none of its
    cycles (`sampled_cycles`), so the measurement's cut (`Cut`) would take it for a stick:
    a stretch of it marked far from every slip (on a stiff spring's short sticks, the only
    such stretch of a path) made the drops' noise read 7 times too high and the path show
    no cycles."""
    c = np.asarray(v, float) / v_b - 1.0
    first, last = 0, c.size
    if c.size and c[0] > 0.0:
        down = np.flatnonzero((c[:-1] > 0.0) & (c[1:] <= 0.0))
        first = int(down[0]) + 1 if down.size else c.size
    if last > first and c[-1] > 0.0:
        up = np.flatnonzero((c[first:-1] <= 0.0) & (c[first + 1 :] > 0.0))
        last = first + int(up[-1]) + 1 if up.size else first
    return first, last


def default_dt(model, h: float) -> float:
    """The noise's grid: half the sampling interval, at most `tau / NOISE_GRID` (`tau` the
    noise's correlation time, where it has one)."""
    tau = getattr(model, "tau", None)
    dt = 0.5 * h
    return dt if tau is None else min(dt, float(tau) / NOISE_GRID)


def creeping_trace(owner, model, measurement, n_cycles: int, seed: int, dt, sticks):
    """`measured_trace` of a creeping slider (the module's steps): a `MeasuredTrace`."""
    from .._cpu import on_two_threads
    from .._keyed import NOISE_STREAM
    from .._simulate.creep import check_args
    from .._trace_kind import SimulatedPath
    from .measurement import MeasuredTrace

    if measurement.signal != "force":
        raise ParameterError(
            owner, "measurement", f"is of a {measurement.signal} trace: a creeping slider "
            f"({type(model).__name__}) is measured as a force trace only",
        )  # fmt: skip
    h = measurement.sampling_interval
    dt = default_dt(model, h) if dt is None else dt
    check_args(owner, model, 1, dt, h, seed, "auto", "continuous")  # (dt: the noise's grid)
    cycle, n_paths, samples, burn = plan(model, n_cycles, h, owner)
    x, v = recorded(model, n_paths, samples, h, dt, seed)
    v_b = float(model.v_b)
    paths = []  # (path, times, extension, velocity, its cycles) after the burn-in
    for p in range(n_paths):
        keep = np.isfinite(x[p, burn:]) & np.isfinite(v[p, burn:])
        n = int(np.argmin(keep)) if not keep.all() else keep.size
        first, last = in_sticks(v[p, burn : burn + n], v_b)
        xp, vp = x[p, burn + first : burn + last], v[p, burn + first : burn + last]
        t = h * np.arange(xp.size)
        table = sampled_cycles(t, xp, vp, v_b)
        if xp.size >= 2 and table["release_time"].size:
            paths.append((p, t, xp, vp, table))
    if not paths:
        raise DataError(
            f"{owner}: the simulated {type(model).__name__} does not cross the drive's speed "
            "after its burn-in: no stick-slip trace to measure"
        )
    kind = measurement.kind
    kind.prepare(measurement, seed)  # (here, not by two paths' threads at once)

    def signals(i):
        p, t, xp, vp, table = paths[i]
        return kind.synthesise(measurement, SimulatedPath(
            t=t, x=xp, v=vp, release=table["release_time"], slip=table["slip_time"],
            stick=table["stick_time"], seed=seed, path=p, v_b=v_b,
            rng=np.random.default_rng([seed, NOISE_STREAM, p]), cut=sticks == "cut",
        ))  # fmt: skip

    traces = on_two_threads(signals, len(paths))
    truth = [dict(c, path=np.full(c["period"].size, p), cycle=np.arange(c["period"].size))
             for p, _, _, _, c in paths]  # fmt: skip
    joined = {k: np.concatenate([c[k] for c in truth]) for k in truth[0]}
    return MeasuredTrace(tuple(traces), joined, measurement, dt)
