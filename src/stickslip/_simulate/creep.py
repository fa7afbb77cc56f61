r"""The motion of a `CreepingSlider` (friction with memory, e.g. rate-and-state): one
implicit integration through stick and slip, with the force's peaks and troughs as events.

Without noise, each solve runs every path of a batch (vmapped) from where it is to the end
of its slip or of its stick: the first time `sign * crossing` rises through zero, with
`crossing` the slider's velocity over the drive's less one (sign -1: the slider falls back
to the drive's speed, the force's trough; sign +1: it outruns the drive again, the next
peak). The solves alternate on the host, so a path's state runs on from one cycle into the
next. With noise, every path runs on through its crossings to `t_max` in windows
(`rosenbrock.window`), and the cycles are read from the crossings in order.

The creep is stiff: the velocity relaxes in $M v / (N a)$, 1e-8 s at 1 nm/s for a 30 g
slider, against a stick of seconds. Hence, without noise, diffrax's `Kvaerno5` (ESDIRK,
L-stable) with a PID controller. Friction noise is white noise on the grid `dt`,
interpolated linearly between its nodes (Wong-Zakai), keyed by `(seed, path, node)`: a
path's noise does not depend on how its solves are cut. With noise the motion goes in
linearly implicit steps that end at the grid's nodes (`rosenbrock`): an adaptive solver
shrank its steps at every node's kink (163 000 steps a cycle of the paper-like slider).
"""

from __future__ import annotations

import math
import time
import warnings

import diffrax
import equinox as eqx
import numpy as np
import optimistix as optx

from .. import _compile, _rng
from .._errors import ParameterError, check_choice, check_int, check_positive
from .._jax import jax, jnp
from .._model import CreepingSlider, to_arrays
from . import rosenbrock

_NOISE_STREAM = 8  # the noise grid's stream (beside the hybrid simulator's, `_rng`)
# Relative and absolute tolerances of the integration, of the state in the model's own
# (O(1)) variables. With them the cycles of the paper-like slider agree with an independent
# Radau integration at 1e-11 to 1e-5 (slip and stick times, force drops).
RTOL, ATOL = 1e-8, 1e-8
# The PID coefficients suggested for stiff problems (Hairer and Wanner): on 15 s of the
# paper-like slider at 1e-9, 63 k steps with 23 k rejected against 68 k with 37 k for the
# integral controller.
_PID = dict(pcoeff=0.3, icoeff=0.4)
# With friction noise: linearly implicit steps that end at the noise grid's nodes
# (`rosenbrock`), their local error held to 1e-5 of the state's O(1) variables, each step
# taken as the Richardson extrapolation of two half steps and one. A noisy path amplifies
# its errors (a slip that starts at another of the noise's crossings near a peak changes
# the rest of the path), so the tolerance is set by the cycles it gives against an
# independent Radau driven by the same noise (k = 1002 N/m, tau 2 ms, grid tau/10, 4 s from
# a velocity step, two paths, drops above 1 mN; `tests/test_rate_and_state.py`). Without
# the extrapolation, at 1e-5 one path's seventh drop differed by 4.5 % (its stick by 5 %),
# at 1e-6 by 6e-3; with it, at 1e-5 every drop agrees to 7.7e-4 in half the steps of 1e-6
# without (at 1e-6 with it, to 3.3e-4).
NOISY_RTOL = NOISY_ATOL = 1e-5
_MAX_STEPS = 200_000  # steps of one solve (a longer stick or slip takes several)
# Crossings of the drive's speed a path keeps in one noisy window (`Motion.events`): its
# paths run on, all busy, until each has as many or reaches t_max (a path that fills its
# buffer goes on in the next window). The paper-like slider with noise at k = 1002 N/m
# makes 5.7 cycles for each slip above 1 mN (the others the noise's micro-slips near the
# force's peak): about 37 a path in 4 s.
_WINDOW_EVENTS = 128
_BATCH = 4096  # paths a window runs at once (their buffers: 13 kB a path for 4 state variables)
# An event's time by bisection on the solver's dense output, to 1e-10 relative (1e-12 s
# absolute): far below the time scales of a slip (ms) and the tests' 1e-5.
_EVENT_RTOL, _EVENT_ATOL = 1e-10, 1e-12
_RECORD_SAMPLES = 20_000  # samples of a recorded trajectory at most (evenly spaced)
COLUMNS = (
    "release_time", "slip_time", "stick_position", "slip_distance", "stick_time", "period",
    "peak_force", "force_drop",
)  # fmt: skip


def check_args(owner, model, n_paths, dt, t_max, seed, solver, monitor) -> tuple:
    """The arguments of `simulate` or `simulate_cycles` that a creeping slider uses: `dt` is
    the noise's grid (at most half the noise's correlation time `tau`, where it has one)."""
    n_paths = check_int(owner, "n_paths", n_paths, minimum=1)
    dt = check_positive(owner, "dt", dt)
    t_max = check_positive(owner, "t_max", t_max)
    seed = check_int(owner, "seed", seed, minimum=0)
    check_choice(owner, "solver", solver, ("auto",))
    check_choice(owner, "monitor", monitor, ("continuous",))
    tau = getattr(model, "tau", None)
    if _noisy(model) and tau is not None and dt > 0.5 * float(tau):
        raise ParameterError(
            owner, "dt",
            f"is the friction noise's grid: at most tau / 2 = {0.5 * float(tau):.3g} "
            "so that the noise's correlation is resolved",
            dt,
        )  # fmt: skip
    return n_paths, dt, t_max, seed


def refuse_options(owner: str, **given) -> None:
    """Refuse, in one line naming it, an option of the hybrid simulator that a creeping
    slider does not take: `given` maps its name to `(value, default)`."""
    for name, (value, default) in given.items():
        if value is not default and value != default:
            raise ParameterError(
                owner, name, "is not available for a creeping slider (rate-and-state)", value
            )


def _noisy(model) -> bool:
    y = np.asarray(model.steady_state())
    return bool(np.any(np.asarray(model.diffusion(jnp.asarray(y))) != 0.0))


def _term(model):
    return diffrax.ODETerm(lambda t, y, args: model.drift(y))


@eqx.filter_jit
def _segment(model, y0, t0, sign, t_end, rtol, atol):
    """Integrate each path of the noise-free motion from `t0` until `sign * crossing` rises
    through zero, or to `t_end`. Returns the end time and state, whether the event ended
    it, whether the solve succeeded, and its steps. The path axis is every array's last
    (`_compile.call`'s convention: one trace for every batch size, kept on disk). With
    friction noise, `rosenbrock.window` instead."""

    def one(y0, t0, sign):
        def cond(t, y, args, **kwargs):
            return sign * model.crossing(y)

        finder = optx.Bisection(rtol=_EVENT_RTOL, atol=_EVENT_ATOL, expand_if_necessary=True)
        sol = diffrax.diffeqsolve(
            _term(model), diffrax.Kvaerno5(), t0, t_end, None, y0,
            stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol, **_PID),
            event=diffrax.Event(cond, root_finder=finder, direction=True),
            saveat=diffrax.SaveAt(t1=True), max_steps=_MAX_STEPS, throw=False,
        )  # fmt: skip
        # An event whose root the bisection placed within its tolerance but reported as
        # unconverged (a trough is steep: the slider stops in M v / (N a)) still ends the
        # segment where the crossing vanishes.
        y1 = sol.ys[-1]
        hit = jnp.asarray(sol.event_mask) & (jnp.abs(model.crossing(y1)) < 1e-6)
        # Out of steps (a long stick): no failure, the next solve goes on from here.
        more = ~hit & (sol.result == diffrax.RESULTS.max_steps_reached)
        ok = hit | more | (sol.result == diffrax.RESULTS.successful)
        ok = ok | (sol.result == diffrax.RESULTS.event_occurred)
        return sol.ts[-1], y1, hit, ok, more, sol.stats["num_steps"]

    return jax.vmap(one, in_axes=-1, out_axes=-1)(y0, t0, sign)


@eqx.filter_jit
def _dense(model, y0, ts, rtol, atol):
    """Each path's states of the noise-free motion at the times `ts` (one solve through).
    Traced in each process, not kept on disk as `_segment` is: diffrax checks the times
    with a host callback, which cannot be exported. With friction noise,
    `rosenbrock.dense` instead (kept on disk)."""

    def one(y0):
        sol = diffrax.diffeqsolve(
            _term(model), diffrax.Kvaerno5(), ts[0], ts[-1], None, y0,
            saveat=diffrax.SaveAt(ts=ts), max_steps=16 * _MAX_STEPS, throw=False,
            stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol, **_PID),
        )  # fmt: skip
        return sol.ys

    return jax.vmap(one)(y0)


def _padded(n: int):
    """A batch of `n` padded to the next power of two with copies of its first member:
    `(size, rows)` (each member's solve is its own under `vmap`, so that as paths finish
    the solves compile for a few sizes, not for every count still running)."""
    size = 1 << (n - 1).bit_length()
    return size, np.r_[np.arange(n), np.zeros(size - n, dtype=int)]


class Motion:
    """One configured run of a creeping slider: `(model, dt, t_max, seed)`, its paths' noise
    keys, and the solves that advance them (with what they cost, `stats`)."""

    def __init__(self, model: CreepingSlider, dt: float, t_max: float, seed: int):
        self.model = to_arrays(model)
        self.noisy = _noisy(model)
        self.dt, self.t_max, self.seed = dt, t_max, seed
        self.stats = {"segments": 0, "steps": 0, "failed": 0}

    def keys(self, paths):
        root = _rng.stream_key(_rng.seed_key(self.seed), _NOISE_STREAM)
        return jax.vmap(lambda p: jax.random.fold_in(jnp.asarray(root), p))(jnp.asarray(paths))

    def onsets(self, n: int) -> np.ndarray:
        # (the seed's root key, as the noise's: any seed in [0, 2**64))
        root = _rng.stream_key(_rng.seed_key(self.seed), _rng.ONSET)
        keys = jax.random.split(jax.random.wrap_key_data(jnp.asarray(root)), n)
        return np.array(jax.vmap(self.model.onset_state)(keys))  # (a copy: written to)

    def segment(self, y, t, slipping):
        """One noise-free solve for these paths: each ends its slip (where `slipping`) or
        its stick (the batch `_padded`: a new size compiles in ~3 s)."""
        n = t.size
        size, pad = _padded(n)
        t1, y1, hit, ok, more, steps = _compile.call(
            _segment, self.model, jnp.asarray(y[pad].T), jnp.asarray(t[pad]),
            jnp.asarray(np.where(slipping[pad], -1.0, 1.0)), jnp.asarray(self.t_max), RTOL,
            ATOL, paths=size,
        )  # fmt: skip
        self.stats["segments"] += 1
        self.stats["steps"] += int(np.sum(np.asarray(steps)[:n]))
        self.stats["failed"] += int(np.sum(~np.asarray(ok)[:n]))
        y1 = np.array(y1).T[:n]
        return (np.array(t1[:n]), y1, np.asarray(hit[:n]), np.asarray(more[:n]))

    def events(self, y, t, limit, keys):
        """The noisy motion of these paths on to `t_max` (`rosenbrock.window`), each
        stopping early once it has `limit` crossings of the drive's speed or
        `_WINDOW_EVENTS` (then called again from where it stopped). Returns the end times
        and states and, per path, its events' times, states and directions (+1: a peak)."""
        n = t.size
        size, pad = _padded(n)
        t1, y1, buf, count, failed, steps = _compile.call(
            rosenbrock.window, self.model, jnp.asarray(y[pad].T), jnp.asarray(t[pad]),
            jnp.asarray(limit[pad]), jnp.asarray(keys[pad].T), jnp.asarray(self.dt),
            jnp.asarray(self.t_max), NOISY_RTOL, NOISY_ATOL, _MAX_STEPS, _WINDOW_EVENTS,
            paths=size,
        )  # fmt: skip
        count = np.asarray(count)[:n]
        self.stats["segments"] += 1
        self.stats["steps"] += int(np.sum(np.asarray(steps)[:n]))
        self.stats["failed"] += int(np.sum(np.asarray(failed)[:n]))
        # the events' brackets, path by path, to `locate` in one batch
        path = np.repeat(np.arange(n), count)
        row = np.concatenate([np.arange(c) for c in count]) if n else np.zeros(0, int)
        found = {k: np.asarray(v)[row, :, path] if np.ndim(v) == 3 else
                 np.asarray(v)[row, path] for k, v in buf.items()}  # fmt: skip
        t_ev, y_ev = self._locate(found)
        up = found["up"]
        split = np.cumsum(count)[:-1]
        events = [(a, b, c) for a, b, c in zip(np.split(t_ev, split), np.split(y_ev, split),
                                                np.split(up, split), strict=True)]  # fmt: skip
        return np.array(t1[:n]), np.array(y1).T[:n], events, np.asarray(failed)[:n]

    def _locate(self, b):
        k = b["ta"].size
        if k == 0:
            return np.zeros(0), np.zeros((0, self.model.steady_state().shape[0]))
        size, pad = _padded(k)
        args = [jnp.asarray(b[x][pad].T) for x in rosenbrock.BRACKET]
        t_ev, y_ev = _compile.call(rosenbrock.locate, self.model, *args, paths=size)
        return np.asarray(t_ev)[:k], np.asarray(y_ev).T[:k]

    def dense(self, y0, keys, ts) -> np.ndarray:
        """Each path's states at the times `ts`, shape `(paths, len(ts), d)`."""
        if not self.noisy:
            return np.asarray(_dense(self.model, jnp.asarray(y0), jnp.asarray(ts), RTOL, ATOL))
        n = y0.shape[0]
        size, pad = _padded(n)
        ys = _compile.call(
            rosenbrock.dense, self.model, jnp.asarray(np.asarray(y0)[pad].T),
            jnp.asarray(np.asarray(keys)[pad].T), jnp.asarray(self.dt), jnp.asarray(ts),
            NOISY_RTOL, NOISY_ATOL, _MAX_STEPS, paths=size,
        )  # fmt: skip
        return np.moveaxis(np.asarray(ys), -1, 0)[:n]

    def crossing(self, ys) -> np.ndarray:
        return np.asarray(jax.vmap(self.model.crossing)(jnp.asarray(ys)))


def run_cycles(owner, model, n_paths, dt, t_max, seed, max_cycles, first_only=False):
    """Successive cycles of `n_paths` paths to `t_max` (with `first_only`, each path's first
    slip and the stick after it). A cycle is a slip and the stick that follows; a run that
    starts inside a slip (the slider faster than the drive) starts its first cycle there,
    one that starts in a stick starts it at the first peak.

    **Returns:** `(table, onsets, stats)`: the cycles (dict of arrays, a row per cycle,
    ordered by path and cycle; `onset`, `stick`, `next`: the states at its peak, its trough
    and the next peak), the paths' starting states and what the run cost."""
    motion = Motion(model, dt, t_max, seed)
    keys = motion.keys(np.arange(n_paths, dtype=np.uint32))
    y = motion.onsets(n_paths)
    y_start = y.copy()
    if motion.noisy:
        rows = _noisy_rows(motion, keys, y, max_cycles, first_only)
        return _join(rows, y.shape[1]), y_start, _warned(owner, motion)
    t = np.zeros(n_paths)
    slipping = motion.crossing(y) > 0.0
    alive = np.ones(n_paths, dtype=bool)
    count = np.zeros(n_paths, dtype=np.int64)
    # The cycle in the making: where its slip started (time, state) and ended.
    peak_t = np.where(slipping, 0.0, np.nan)
    peak_y = np.where(slipping[:, None], y, np.nan)
    trough_t, trough_y = np.full(n_paths, np.nan), np.full_like(y, np.nan)
    rows: list[dict[str, np.ndarray]] = []
    while alive.any():
        idx = np.nonzero(alive)[0]
        t1, y1, hit, more = motion.segment(y[idx], t[idx], slipping[idx])
        slip_end = slipping[idx] & hit
        stick_end = ~slipping[idx] & hit
        trough_t[idx[slip_end]], trough_y[idx[slip_end]] = t1[slip_end], y1[slip_end]
        done = idx[stick_end & np.isfinite(peak_t[idx])]
        if done.size:
            sel = np.isin(idx, done)
            peak, trough = (peak_t[done], peak_y[done]), (trough_t[done], trough_y[done])
            rows.append(_rows(motion.model, done, peak, trough, (t1[sel], y1[sel]), count[done]))
            count[done] += 1
        peak_t[idx[stick_end]], peak_y[idx[stick_end]] = t1[stick_end], y1[stick_end]
        t[idx], y[idx] = t1, y1
        slipping[idx] = np.where(hit, ~slipping[idx], slipping[idx])
        alive[idx] = (hit | more) & (t1 < t_max) & (count[idx] < max_cycles)
        if first_only:
            alive[idx] &= count[idx] == 0
    # A slip that ended before t_max but whose stick outlasted it: a row without a stick.
    open_ = np.isfinite(peak_t) & np.isfinite(trough_t) & (trough_t > peak_t)
    open_ &= (count < max_cycles) & ~(first_only & (count > 0))
    if np.any(open_):
        o = np.nonzero(open_)[0]
        nowhere = (np.full(o.size, np.nan), np.full_like(y[o], np.nan))
        rows.append(
            _rows(
                motion.model,
                o,
                (peak_t[o], peak_y[o]),
                (trough_t[o], trough_y[o]),
                nowhere,
                count[o],
            )  # fmt: skip
        )
    return _join(rows, y.shape[1]), y_start, _warned(owner, motion)


def _warned(owner, motion) -> dict:
    """The run's costs; a warning where a solve failed."""
    if motion.stats["failed"]:
        warnings.warn(
            f"{owner}: {motion.stats['failed']} solve(s) of the creeping slider failed (an "
            "implicit step that did not converge at the smallest step); their paths end there",
            stacklevel=4,
        )
    return dict(motion.stats)


def _noisy_rows(motion, keys, y, max_cycles, first_only) -> list:
    """The cycle rows of the noisy motion: each path run on through its events in windows
    (`Motion.events`, `_BATCH` paths at a time), its crossings of the drive's speed read in
    order as `run_cycles` reads a solve's events (up: a peak, the slip's start; down: a
    trough, its end)."""
    n, d = y.shape
    y0 = y.copy()
    slipping = motion.crossing(y) > 0.0
    # crossings a path needs: a peak where it starts in a stick, then two a cycle
    need = (~slipping).astype(np.int64) + 2 * (1 if first_only else max_cycles)
    need = np.minimum(need, np.iinfo(np.int32).max)
    found = []
    for lo in range(0, n, _BATCH):
        part = np.arange(lo, min(n, lo + _BATCH))
        got = _events(motion, keys[part], y[part], need[part])
        for p, (ts, ys, ups) in zip(part, got, strict=True):
            start = (0.0, y0[p]) if slipping[p] else None
            found += _path_cycles(p, ts, ys, ups, start, max_cycles, first_only)
    if not found:
        return []
    p, cycle, t0, y0_, t1, y1, t2, y2 = (np.array(v) for v in zip(*found, strict=True))
    return [_rows(motion.model, p, (t0, y0_), (t1, y1), (t2, y2.reshape(-1, d)), cycle)]


def _events(motion, keys, y, need) -> list:
    """Each path's crossings of the drive's speed, `(times, states, up)`, in order, until
    it has `need` of them or reaches `t_max`."""
    n = y.shape[0]
    y, t = y.copy(), np.zeros(n)
    got = [[] for _ in range(n)]
    alive = np.ones(n, dtype=bool)
    count = np.zeros(n, dtype=np.int64)
    while alive.any():
        idx = np.nonzero(alive)[0]
        t1, y1, events, failed = motion.events(y[idx], t[idx], need[idx] - count[idx], keys[idx])
        for i, ev in zip(idx, events, strict=True):
            got[i].append(ev)
        count[idx] += [ev[0].size for ev in events]
        t[idx], y[idx] = t1, y1
        alive[idx] = (t1 < motion.t_max) & (count[idx] < need[idx]) & ~failed
    d = y.shape[1]
    return [tuple(np.concatenate(part) for part in zip(*g, strict=True)) if g else
            (np.zeros(0), np.zeros((0, d)), np.zeros(0, bool)) for g in got]  # fmt: skip


def _path_cycles(p, ts, ys, ups, start, max_cycles, first_only) -> list:
    """One path's cycles from its crossings in order, each `(path, cycle, peak time,
    state, trough time, state, next peak's time, state)`: a slip from a peak (an up
    crossing, or the start where the path starts in a slip) to the next trough, and the
    stick from there to the next peak; a last slip whose stick outlasts the run, without
    its stick (nan). `start`: `(0, state)` where the path starts in a slip."""
    peak, trough = start, None
    out, cycle = [], 0
    last = 1 if first_only else max_cycles
    for k in range(ts.size):
        if cycle >= last:
            return out
        if ups[k]:
            if peak is not None and trough is not None:
                out.append((p, cycle, *peak, *trough, ts[k], ys[k]))
                cycle += 1
            peak, trough = (ts[k], ys[k]), None
        elif peak is not None:
            trough = (ts[k], ys[k])
    if peak is not None and trough is not None and cycle < last:
        out.append((p, cycle, *peak, *trough, np.nan, np.full(ys.shape[1], np.nan)))
    return out


def _join(rows, d: int) -> dict[str, np.ndarray]:
    if not rows:
        table = {k: np.zeros(0) for k in COLUMNS}
        table.update(path=np.zeros(0, np.int64), cycle=np.zeros(0, np.int64))
        table.update({k: np.zeros((0, d)) for k in ("onset", "stick", "next")})
        return table
    table = {k: np.concatenate([r[k] for r in rows]) for k in rows[0]}
    order = np.lexsort((table["cycle"], table["path"]))
    return {k: v[order] for k, v in table.items()}


def _rows(model, paths, peak, trough, next_peak, cycle):
    """Cycle rows of `paths`: each a slip from `peak` to `trough` and the stick to
    `next_peak`, as `(times, states)`."""
    force = jax.vmap(model.spring_force)
    F0 = np.asarray(force(jnp.asarray(peak[1])))
    F1 = np.asarray(force(jnp.asarray(trough[1])))
    slip_time = trough[0] - peak[0]
    stick_time = next_peak[0] - trough[0]
    return dict(
        path=paths.astype(np.int64), cycle=cycle.copy(), release_time=peak[0],
        slip_time=slip_time,
        stick_position=np.asarray(jax.vmap(model.position)(jnp.asarray(trough[1]))),
        slip_distance=(F0 - F1) / float(np.asarray(model.stiffness)), stick_time=stick_time,
        period=slip_time + stick_time, peak_force=F0, force_drop=F0 - F1,
        onset=peak[1], stick=trough[1], next=next_peak[1],
    )  # fmt: skip


def first_cycles(model, n_paths, dt, t_max, seed) -> dict:
    """`simulate` of a creeping slider: each path's first slip and the stick after it, as
    the arrays of an `Ensemble` (`nan` where the path has not completed its slip by
    `t_max`), with the run's `info` and `stats`."""
    wall0 = time.perf_counter()
    table, y0, stats = run_cycles("simulate", model, n_paths, dt, t_max, seed, 1, True)
    d = y0.shape[1]
    first = table["cycle"] == 0
    rows = table["path"][first]
    out = {k: np.full(n_paths, np.nan) for k in COLUMNS}
    for k in COLUMNS:
        out[k][rows] = table[k][first]
    for k in ("onset", "stick", "next"):
        out[k] = np.full((n_paths, d), np.nan)
        out[k][rows] = table[k][first]
    out["stuck"] = np.isfinite(out["slip_time"])
    out["stuck"] &= out["release_time"] + np.nan_to_num(out["slip_time"]) <= t_max
    out["info"] = info(model, dt, t_max, seed)
    out["stats"] = dict(stats, wall_seconds=time.perf_counter() - wall0)
    return out


def cycle_series(model, n_paths, dt, t_max, seed, record: bool, max_cycles: int) -> dict:
    """`simulate_cycles` of a creeping slider: the cycle table, the recorded time series
    (with `record`), `info` and `stats`."""
    wall0 = time.perf_counter()
    table, y0, stats = run_cycles("simulate_cycles", model, n_paths, dt, t_max, seed, max_cycles)
    cycles = {k: table[k] for k in ("path", "cycle", *COLUMNS)}
    cycles["immediate"] = np.zeros(cycles["path"].size, dtype=bool)
    traces = _traces(model, n_paths, dt, t_max, seed, y0) if record else None
    return dict(
        cycles=cycles, traces=traces, info=info(model, dt, t_max, seed, n_paths=n_paths),
        stats=dict(stats, wall_seconds=time.perf_counter() - wall0),
    )  # fmt: skip


def info(model, dt, t_max, seed, **extra) -> dict:
    """A run's settings: the solver is Kvaerno5 without noise, ROS2 (`rosenbrock`) with."""
    noisy = _noisy(model)
    tol = NOISY_RTOL if noisy else RTOL
    return dict(
        model=type(model).__name__, params=model.params(),
        solver="ros2" if noisy else "kvaerno5", monitor="events", dt=dt, t_max=t_max,
        seed=seed, rtol=tol, atol=NOISY_ATOL if noisy else ATOL, **extra,
    )  # fmt: skip


def _traces(model, n_paths, dt, t_max, seed, y0):
    """Each path's time series on an even grid of at most `_RECORD_SAMPLES` samples (step
    `dt` where that fits), with the cycles' noise: one solve through, so the events and
    the samples agree within the integration's tolerances."""
    motion = Motion(model, dt, t_max, seed)
    ts = np.linspace(0.0, t_max, int(min(_RECORD_SAMPLES, max(2, math.ceil(t_max / dt) + 1))))
    ys = motion.dense(y0, motion.keys(np.arange(n_paths, dtype=np.uint32)), ts)
    short = ~np.all(np.isfinite(ys), axis=(1, 2))
    if short.any():
        warnings.warn(
            f"simulate_cycles: the recorded time series of {int(short.sum())} path(s) stopped "
            f"short (more than {16 * _MAX_STEPS} steps); the samples after are nan",
            stacklevel=4,
        )
        ys = np.where(np.isfinite(ys), ys, np.nan)
    return tuple((ts.copy(), ys[p], motion.crossing(ys[p]) > 0.0) for p in range(n_paths))


def least_velocity(model, y0, duration: float, samples: int = 2001) -> float:
    """The least slider velocity of the noise-free motion over `duration` from `y0` (at
    `samples` even times)."""
    motion = Motion(model, duration / (samples - 1), duration, 0)
    ts = np.linspace(0.0, float(duration), samples)
    ys = motion.dense(np.asarray(y0)[None], motion.keys(np.zeros(1, np.uint32)), ts)[0]
    return float(np.min(np.asarray(jax.vmap(motion.model.slider_velocity)(jnp.asarray(ys)))))
