"""`simulate_cycles`: successive stick-slip cycles of a few paths, as time series."""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import time
import warnings
from typing import Any

import diffrax
import equinox as eqx
import numpy as np

from .. import _background, _compile, _rng
from .._errors import ParameterError, check_int
from .._jax import jnp
from .._memory import check_memory
from .._model import CreepingSlider, FrictionModel
from .._model_check import explain
from .buffers import next_pow2, stand_in
from .config import validate_args
from .host import HostRun
from .hybrid import INACTIVE, SLIPPING
from .loop import solve

_CYCLE_BITS = 20  # a slot's counter is path * 2**20 + cycle
_MAX_RECORD_FLOATS = 2**25  # memory bound of one recording solve (about 256 MB)
# Steps of one recording solve (`_record`): one compiled program for every slip length and
# step (a longer slip takes several solves), which `prefetch_cycles` can compile ahead.
_RECORD_STEPS = 128
_FIRST_BATCH = 16  # cycles of each path in the first round (then twice as many each round)


@dataclasses.dataclass(frozen=True, eq=False)
class CycleSeries:
    """Successive slip-stick cycles of a few paths, from `simulate_cycles`.

    - `cycles`: a table (dict of arrays, one row per cycle, ordered by path then cycle) with
      `path`, `cycle`, `release_time` (slip onset), `slip_time`, `stick_position`,
      `slip_distance`, `stick_time`, `period`, `immediate`;
    - `trajectory(path)`: the time series of one path, `(t, states, slipping)`: during a slip
      one sample per step; a stick is the segment from the stick sample (`slipping` False)
      to the next release, along which the stick phase is linear (eq. 9);
    - `periods(path)`: successive periods, e.g. for return maps $T_{n+1}$ against $T_n$.

    Every cycle starts from the model's onset state (the sharp reset of the paper), so the
    cycles of a path are independent given their keys; a model with memory
    (`FrictionModel.carries_state`) starts each slip where the last stick led
    (`FrictionModel.release`), so that successive cycles depend on each other.
    """

    cycles: dict[str, np.ndarray]
    traces: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...] | None
    state_names: tuple[str, ...]
    info: dict[str, Any]
    stats: dict[str, Any]

    @property
    def n_paths(self) -> int:
        return int(self.info["n_paths"])

    def _rows(self, path: int) -> np.ndarray:
        if not 0 <= path < self.n_paths:
            raise IndexError(f"path {path} out of range (n_paths={self.n_paths})")
        return self.cycles["path"] == path

    def periods(self, path: int = 0) -> np.ndarray:
        return self.cycles["period"][self._rows(path)]

    def trajectory(self, path: int = 0):
        """`(t, states, slipping)` of one path: times `(K,)`, states `(K, d)`, flags `(K,)`."""
        self._rows(path)
        if self.traces is None:
            raise ValueError("this series was run with record=False: no trajectories")
        return self.traces[path]

    def __repr__(self) -> str:
        n = self.cycles["period"].size
        return (
            f"CycleSeries(n_paths={self.n_paths}, cycles={n}, model={self.info['model']!r}, "
            f"t_max={self.info['t_max']})"
        )


@_compile.quick
@eqx.filter_jit
def _record(model, solver, cfg, X, k_stick, path, offset, dt, step_key, bridge_key):
    """`_RECORD_STEPS` steps with the same noise as in `simulate`, from global step `offset`,
    saving the state after every step. Nothing sticks (the slips are cut at their known
    stick times), so no candidate step of the exact detector freezes a path early; a longer
    slip takes several solves, each from where the last ended (the noise is keyed by global
    step: the same numbers as one solve)."""
    cfg = dataclasses.replace(cfg, detect="none")
    y0 = (X, (X, k_stick, jnp.zeros(X.shape[-1])))
    sol = solve(
        model, solver, cfg, y0, path, dt, (step_key, bridge_key), offset,
        t1=float(_RECORD_STEPS), saveat=diffrax.SaveAt(steps=True), max_steps=_RECORD_STEPS,
    )  # fmt: skip
    return sol.ys[0]


def simulate_cycles(
    model: FrictionModel,
    n_paths: int,
    dt: float,
    t_max: float,
    seed: int = 0,
    *,
    solver: str = "auto",
    monitor: str = "continuous",
    record: bool = True,
    max_cycles: int = 100_000,
    client=None,
) -> CycleSeries:
    """Run a few paths through successive slip-stick cycles until time `t_max`.

    Arguments as in `simulate`; `record` keeps the time series of every slip (one sample per
    step) for plots of the motion and phase portraits; `max_cycles` bounds the cycles of a
    path (a model whose cycles have zero length, such as white friction noise under
    continuous monitoring, would otherwise never reach `t_max`: a warning says so).
    `client`: run each path as a task on a Dask cluster (as in `simulate`; identical
    numbers).

    **Returns:** a `CycleSeries`.
    """
    if isinstance(model, CreepingSlider):  # one motion through stick and slip, integrated
        from . import creep

        owner = "simulate_cycles"
        args = creep.check_args(owner, model, n_paths, dt, t_max, seed, solver, monitor)
        creep.refuse_options(owner, client=(client, None))
        max_cycles = check_int(owner, "max_cycles", max_cycles, minimum=1)
        out = creep.cycle_series(model, *args, record=bool(record), max_cycles=max_cycles)
        return CycleSeries(
            out["cycles"], out["traces"], tuple(model.state_names), out["info"], out["stats"]
        )
    n_paths, dt, t_max, seed, _ = validate_args(
        "simulate_cycles", model, n_paths, dt, t_max, seed, solver, monitor, 1
    )
    if n_paths > 2 ** (32 - _CYCLE_BITS):
        raise ParameterError(
            "simulate_cycles", "n_paths", f"must be <= {2 ** (32 - _CYCLE_BITS)}", n_paths
        )
    max_cycles = check_int("simulate_cycles", "max_cycles", max_cycles, minimum=1)
    if max_cycles > 2**_CYCLE_BITS - 1:
        raise ParameterError(
            "simulate_cycles", "max_cycles", f"must be < {2**_CYCLE_BITS}", max_cycles
        )
    if not isinstance(record, (bool, np.bool_)):
        raise ParameterError("simulate_cycles", "record", "must be True or False", record)
    if record:
        # The time series hold one sample (time, state, flag) per step of slip: at most
        # t_max / dt per path, kept twice (per cycle, then joined).
        samples = n_paths * (t_max / dt + 1.0)
        check_memory(
            "simulate_cycles",
            f"recording {n_paths} path(s) to t_max = {t_max:g} at dt = {dt:g}",
            2.0 * 8.0 * (len(model.state_names) + 2) * samples,
            "take a larger dt, a shorter t_max or fewer paths, or record=False",
        )
    wall0 = time.perf_counter()
    opts = dict(solver=solver, monitor=monitor, record=record, max_cycles=max_cycles,
                count=None)  # fmt: skip
    if client is None:
        parts = [_cycles_block(model, dt, t_max, seed, opts, 0, n_paths)]
    else:
        from .. import _distributed

        with _distributed.connected("simulate_cycles", client) as client:
            blocks = [(p, p + 1) for p in range(n_paths)]  # a few long paths: one task each
            parts = _distributed.run_blocks(
                client, _cycles_block, blocks, model, dt, t_max, seed, opts, label="path"
            )
    return _series(model, parts, n_paths, dt, t_max, max_cycles, record, wall0)


def counted_cycles(model: FrictionModel, n_paths: int, dt: float, horizon: float,
                   seed: int, count: int, check=None) -> CycleSeries:  # fmt: skip
    """`simulate_cycles` (recorded) of `count` successive cycles a path, each slip followed
    up to `horizon` (a slip still going then ends its path's series there, as one past
    `t_max` does in `simulate_cycles`): for a caller that wants a number of cycles, not a
    duration, without a pilot run to learn the mean period. A memoryless model's cycles
    run in one round (every path's `count` cycles at once: they are independent given
    their keys), a model with memory one cycle a round. Not for a `CreepingSlider`.
    `check(table)`, where given, sees the cycles' table before their slips are recorded
    (a caller's refusal, e.g. of a trace past the memory limit, raised from it)."""
    n_paths, dt, horizon, seed, _ = validate_args(
        "simulate_cycles", model, n_paths, dt, horizon, seed, "auto", "continuous", 1
    )
    if not 1 <= count < 2**_CYCLE_BITS:  # (a slot's counter holds the cycle)
        raise ParameterError("simulate_cycles", "count", f"must be in [1, {2**_CYCLE_BITS})",
                             count)  # fmt: skip
    wall0 = time.perf_counter()
    opts = dict(solver="auto", monitor="continuous", record=True, max_cycles=count,
                count=count, check=check)  # fmt: skip
    parts = [_cycles_block(model, dt, horizon, seed, opts, 0, n_paths)]
    return _series(model, parts, n_paths, dt, horizon, count, True, wall0)


def _series(model, parts, n_paths, dt, t_max, max_cycles, record, wall0) -> CycleSeries:
    """The `CycleSeries` of the blocks' results `parts` (`_cycles_block`), their warnings
    said."""
    table = {
        k: np.concatenate([p["cycles"][k] for p in parts], axis=-1) for k in parts[0]["cycles"]
    }
    traces = sum((p["traces"] for p in parts), ()) if record else None
    late = [p["late"] for p in parts if p["late"] is not None]
    if late:
        count = sum(n for n, _ in late)
        mean = sum(n * m for n, m in late) / count
        warnings.warn(
            f"simulate_cycles: {count} path(s) did not reach t_max = {t_max} in "
            f"{max_cycles} cycles (mean period {mean:.3g}); "
            "zero-length cycles, as with white friction noise, never advance time",
            stacklevel=2,
        )
    info = dict(parts[0]["info"], n_paths=n_paths)
    stats = {}
    for p in parts:
        for k, v in p["stats"].items():
            stats[k] = stats.get(k, 0) + v
    if stats.get("nonfinite"):
        at = next(p["nonfinite_at"] for p in parts if p["nonfinite_at"])
        where = explain(model, *at, dt=dt, steps=int(t_max / dt))
        stats["nonfinite_where"] = where
        warnings.warn(
            f"simulate_cycles: {stats['nonfinite']} cycle(s) left the finite numbers, {where}: "
            "each ends its path's series there, not counted as a stick "
            "(stats['nonfinite']); check the model there",
            RuntimeWarning,
            stacklevel=2,
        )
    stats["wall_seconds"] = time.perf_counter() - wall0
    return CycleSeries(table, traces, tuple(model.state_names), info, stats)


def prefetch_cycles(
    model: FrictionModel,
    n_paths: int,
    dt: float,
    t_max: float,
    *,
    solver: str = "auto",
    monitor: str = "continuous",
    record: bool = True,
):
    """Start compiling, in a thread, the programs that `simulate_cycles` with these arguments
    will start on (`HostRun.prefetch`; with `record`, the recording solve for as many cycles as
    its first round runs), unless they are compiled already: a caller that runs other work
    first (a study: its ensemble) overlaps their compiling with it (XLA compiles without
    Python's lock). Returns the thread (join it before the `simulate_cycles` call, which
    would otherwise compile them again beside it), or `None` for arguments
    `simulate_cycles` would refuse. Nothing changes but when they compile."""
    import threading

    try:
        n_paths, dt, t_max, _, _ = validate_args(
            "simulate_cycles", model, n_paths, dt, t_max, 0, solver, monitor, 1
        )
    except Exception:  # (the call itself says why)
        return None
    if n_paths > 2 ** (32 - _CYCLE_BITS):
        return None

    def build():
        with contextlib.suppress(Exception):  # (the call compiles them then, and says why)
            root = _rng.stream_key(_rng.seed_key(0), _rng.SERIES)
            run = HostRun(
                "simulate_cycles", model, solver, monitor, dt, t_max, root, check_dt=False
            )
            run.prefetch(n_paths * _FIRST_BATCH)
            if record:
                d = len(model.state_names)
                _record_size(run, _recorder(run), d, n_paths * _FIRST_BATCH, 1 << 62, build=True)

    thread = threading.Thread(target=build, name="stickslip-cycles-prefetch", daemon=True)
    thread.start()
    return thread


def _cycles_block(model, dt, t_max, seed, opts, start, stop) -> dict:
    """`simulate_cycles` for the paths `start` .. `stop` - 1 (a task of a distributed run)."""
    root = _rng.stream_key(_rng.seed_key(seed), _rng.SERIES)
    run = HostRun("simulate_cycles", model, opts["solver"], opts["monitor"], dt, t_max, root)
    max_cycles = opts["max_cycles"]
    # `count` (`counted_cycles`): that many cycles a path, t_max the longest slip followed
    counted = opts["count"] is not None
    path_ids = np.arange(start, stop)
    n_paths = path_ids.size
    rows: list[dict[str, np.ndarray]] = []
    elapsed = np.zeros(n_paths)
    active = np.ones(n_paths, dtype=bool)
    # A model with memory runs its cycles one after the other, each slip from where the last
    # stick led (`FrictionModel.release`); without, a round runs many cycles of every path
    # at once (they are independent given their keys).
    memory = bool(model.carries_state)
    first, batch = 0, (1 if memory else max_cycles if counted else _FIRST_BATCH)
    onsets = None  # (d, paths): where the next slips start (a model with memory)
    nonfinite = 0  # cycles whose state left the finite numbers (`HostRun.cycle_outputs`)
    while active.any() and first < max_cycles:
        count = min(batch, max_cycles - first)
        ids = np.nonzero(active)[0]
        slots = (
            ((path_ids[ids, None].astype(np.uint64) << _CYCLE_BITS) + first + np.arange(count))
            .ravel()
            .astype(np.uint32)
        )
        given = None if onsets is None else onsets[:, ids]
        X0, stick_state, t_stick, _ = run.first_passages(slots, 2**16, onsets=given)
        X1, out = run.cycle_outputs(slots + np.uint32(1), 0, stick_state, t_stick)
        nonfinite += int(np.sum(run.nonfinite))  # (their series end: the period is inf)
        if memory:
            onsets = np.zeros((X1.shape[0], n_paths)) if onsets is None else onsets
            onsets[:, ids] = X1
        out.update(
            path=np.repeat(path_ids[ids], count),
            cycle=np.tile(np.arange(first, first + count), ids.size),
            onset=X0,
            stick=stick_state,
        )
        period = np.where(out["stuck"], out["period"], np.inf).reshape(ids.size, count)
        begin = elapsed[ids, None] + np.concatenate(
            [np.zeros((ids.size, 1)), np.cumsum(period, axis=1)[:, :-1]], axis=1
        )
        out["release_time"] = begin.ravel()
        keep = np.isfinite(out["release_time"]) if counted else out["release_time"] < t_max
        rows.append({k: v[..., keep] for k, v in out.items()})
        elapsed[ids] = begin[:, -1] + period[:, -1]
        active[ids] = np.isfinite(elapsed[ids]) if counted else elapsed[ids] < t_max
        first += count
        batch *= 1 if memory else 2
    late = None
    if active.any() and not counted:
        late = (int(active.sum()), float(np.mean(elapsed[active]) / max_cycles))
    table = {k: np.concatenate([r[k] for r in rows], axis=-1) for k in rows[0]}
    order = np.lexsort((table["cycle"], table["path"]))
    table = {k: v[..., order] for k, v in table.items()}
    if opts.get("check") is not None:
        opts["check"](table)
    traces = _traces(run, table, path_ids) if opts["record"] else ()
    cycles = {
        k: table[k]
        for k in (
            "path", "cycle", "release_time", "slip_time", "stick_position", "slip_distance",
            "stick_time", "period", "immediate",
        )
    }  # fmt: skip
    info = run.info(model, seed=seed, n_paths=n_paths)
    stats = dict(run.stats, compile_seconds=run.timer.compile_seconds, nonfinite=nonfinite)
    return dict(cycles=cycles, traces=traces, late=late, info=info, stats=stats,
                nonfinite_at=run.nonfinite_at)  # fmt: skip


def _traces(run, table, path_ids):
    """Re-run every kept slip with the same noise, saving each step, and join the cycles."""
    from ._assemble import place  # (Numba imported on first use)

    dt = run.dt
    slots = ((table["path"].astype(np.uint64) << _CYCLE_BITS) + table["cycle"]).astype(np.uint32)
    slip_time = np.where(np.isfinite(table["slip_time"]), table["slip_time"], run.n_steps * dt)
    steps = np.where(table["immediate"], 0, np.floor(slip_time / dt + 1e-9).astype(int))
    d = table["onset"].shape[0]
    # Group slots so that the samples of one group's solves stay within the memory bound.
    n_rec = _RECORD_STEPS * max(1, -(-int(steps.max()) // _RECORD_STEPS))
    group = max(1, _MAX_RECORD_FLOATS // (n_rec * d * 2))
    fixed = _recorder(run)
    n = _record_size(run, fixed, d, min(group, slots.size), group)
    group = min(group, n)
    # each row's slip samples at release + k dt (k = 0 .. steps: its onset, then the
    # recording solves' states), then its stick (where the slip ended)
    ended = np.isfinite(table["slip_time"])
    size = steps + 1 + ended
    at = np.cumsum(size) - size
    total = int(size.sum())
    t = np.empty(total)
    states = np.empty((total, d))
    flags = np.ones(total, dtype=bool)
    k = np.arange(int(np.sum(steps + 1))) - np.repeat(np.cumsum(steps + 1) - (steps + 1),
                                                      steps + 1)  # fmt: skip
    into = np.repeat(at, steps + 1) + k
    t[into] = np.repeat(table["release_time"], steps + 1) + dt * k
    states[at] = table["onset"].T
    for start in range(0, slots.size, group):
        idx = np.arange(start, min(start + group, slots.size))
        pad = n - idx.size
        X0 = np.concatenate([table["onset"][:, idx], np.zeros((d, pad))], axis=1)
        ks = np.concatenate(
            [np.where(table["immediate"][idx], INACTIVE, SLIPPING), np.full(pad, INACTIVE)]
        )
        path = np.concatenate([slots[idx], np.zeros(pad, dtype=np.uint32)])
        X = X0
        for first in range(0, int(steps[idx].max()), _RECORD_STEPS):
            offset = np.asarray(float(first))
            ys = np.asarray(run._counted(fixed(X, ks, path, offset, *_record_tail(run), paths=n)))
            place(ys, first, idx, steps, at, states)
            X = ys[-1]
    end = (at + size - 1)[ended]
    t[end] = (table["release_time"] + table["slip_time"])[ended]
    states[end] = table["stick"][:, ended].T
    flags[end] = False
    traces = []
    for p in path_ids:
        rows = np.nonzero(table["path"] == p)[0]
        lo, hi = (at[rows[0]], at[rows[-1]] + size[rows[-1]]) if rows.size else (0, 0)
        traces.append((t[lo:hi], states[lo:hi], flags[lo:hi]))
    return tuple(traces)


def _record_tail(run):
    """`_record`'s arguments after the buffer and its offset: the step and the keys."""
    return run.dt_arr, run.keys["step"], run.keys["bridge"]


def _record_specimen(run, d: int, m: int):
    """Stand-ins for `_record`'s arguments after its fixed ones, for `m` slots."""
    return (stand_in((d, m)), stand_in(m), stand_in(m, np.uint32), stand_in(()), *_record_tail(run))


def _recorder(run) -> _compile.Fixed:
    """`_record` with the run's slip phase, solver and configuration."""
    return _compile.Fixed(_record, run.slip, run.solver, run.cfg, timer=run.timer)


def _record_size(run, fixed, d: int, count: int, most: int, build: bool = False) -> int:
    """The slots of a recording solve for `count` slips (at least 128; `most`: the memory
    bound): that size where it is compiled, else another size of the same program at hand
    (`HostRun._size_at_hand`: a larger one within the bound, padded, or a smaller one, in more
    solves; each slot's noise is its own; the background compiler is asked for the size
    itself, as for the stepping loop), else that size (compiled then, or here with
    `build`)."""
    want = max(_MIN_RECORD, next_pow2(count))
    specimen = functools.partial(_record_specimen, run, d)
    top = max(want, 1 << (most.bit_length() - 1))
    n = run._size_at_hand(fixed, specimen, want, top, smaller=True, ladder=_RECORD_LADDER)
    if n != want:
        _background.request(fixed.fn, *fixed.fixed, *specimen(want), paths=want)
    if build:
        # (`paths`: kept on disk, as the stepping's programs: without it every process
        # compiled it again, 0.5-3 s)
        fixed.ready(*specimen(n), paths=n, build=True)
    return n


_MIN_RECORD = 128  # slots of the smallest recording solve
# The recording solve's sizes (powers of two from `_MIN_RECORD`): the ladder on which another
# compiled size stands in for the one wanted (`_record_size`). Searched on the simulator's
# buffer sizes (steps of 8 below 8192) it passed over the powers of two between, so every
# new count of cycles (another t_max or number of paths) compiled the solve again.
_RECORD_LADDER = (lambda size: 2 * size, lambda size: size // 2 if size > _MIN_RECORD else 0)
