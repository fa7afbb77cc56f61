"""The host scheduler, `HostRun`: one configured run (model, solver, detector, step,
horizon, keys), its chunks of paths stepped as a sequence of short compiled calls, the
compaction and refinement batches cut on the host."""

from __future__ import annotations

import dataclasses
import functools
import math
import threading
import time

import numpy as np

from .. import _background, _compile, _rng
from .._errors import ParameterError
from .._jax import jax
from .._model import LinearGaussian, to_arrays
from . import bridge, steps
from .buffers import (
    DEFAULT_CHUNK,
    MIN_BUFFER,
    buffer_size,
    cols,
    larger_buffer,
    pad_paths,
    padded_size,
    repack,
    set_cols,
    smaller_buffer,
    stand_in,
    stand_in_size,
)
from .config import (
    DEFAULT_CROSSING_TOL,
    LG_FIELDS,
    LOOP_NODES,
    Config,
    check_time_scales,
    choose_scheduler,
    detector,
    lg_arrays,
    linear_gaussian,
    make_solver,
    nodes_for,
    traces_nothing,
)
from .hybrid import (
    INACTIVE,
    PASSED,
    SLIPPING,
)

LOCATE_BATCH = 4096  # paths located at once (bounds the memory of the dense nodes)


SPECULATE_BELOW = 16384  # buffers from this size down step past candidates (`HostRun._chunk`)


PAST_SLOTS = 2  # candidates a path steps past inside one stepping call (`SteppingPastHybrid`)


_ARRAYS = (np.ndarray, np.generic, jax.Array)


class HostRun:
    """One configured run (model, solver, monitoring, step, horizon, keys): first passages
    for any set of path counters. `owner` names the public function in error messages."""

    def __init__(
        self, owner, model, solver, monitor, dt, t_max, root, bar=None,
        crossing_tol=DEFAULT_CROSSING_TOL, scheduler="host", check_dt=True,
    ):  # fmt: skip
        # (`check_dt`: refuse or warn about a step too coarse for the slip's time scale;
        # False only for a run made for its programs alone, `prefetch`, whose caller's run
        # checks)
        self.timer = _compile.Timer()
        # Compiled calls made and arrays they handed back (`count_call`).
        self.stats = {"dispatches": 0, "transfers": 0}
        # Paths that left the finite numbers (`first_passages`), and one's last finite and
        # first non-finite states, to say where (`_model_check.explain`).
        self.nonfinite, self.nonfinite_at, self.onsets = None, None, None
        self._count_lock = threading.Lock()
        self.model = to_arrays(model)
        # What the compiled slip-phase code (stepping, in-step location, upcrossings) is
        # given: `FrictionModel.slip_phase` (models that differ only at release share it).
        slip = model.slip_phase()
        self.slip = self.model if slip is model else to_arrays(slip)
        self._fixed: dict = {}  # `call`'s executables with the model as first argument
        # The slip's linear-Gaussian description on the host: as it is where it computes in
        # NumPy (nothing to trace: the built-in models), else by one compiled call (evaluated
        # op by op, its first use in a process would compile each operation).
        if traces_nothing(self.model.linear_gaussian, self.model):
            lg = lg_arrays(self.model.linear_gaussian())
        else:
            lg = self.call(linear_gaussian, self.model, paths=0)
        if lg is not None:
            lg = LinearGaussian(**{f: np.asarray(x) for f, x in zip(LG_FIELDS, lg, strict=True)})
        if solver == "auto":
            solver = "exact" if lg is not None else "euler"
        if solver == "exact" and lg is None:
            raise ParameterError(
                owner,
                "solver",
                f"'exact' needs a linear-Gaussian model; {type(model).__name__} has none "
                "(use 'euler')",
                solver,
            )
        smooth = bool(model.crossing_is_smooth)
        detect = detector(lg, solver, monitor, smooth)
        self.cfg = Config(
            solver=solver,
            monitor=monitor,
            smooth=smooth,
            detect=detect,
        )
        # Interpolation nodes of the in-step location (`steps.locate`; the exact solver's only
        # dt-dependent static). The stepping loop never interpolates: its solver has a fixed
        # count, so one compiled loop serves every dt.
        if solver == "exact" and check_dt:
            check_time_scales(owner, lg, dt, detect)
        self.nodes = 1
        if solver == "exact":
            self.nodes = nodes_for(lg.A, dt, detect == "cubic" and check_dt)
        self.depths = None  # (location, certification) levels of the bridge detector
        # The crossing functional and level on the host (`_chunk`'s speculative stepping).
        self.crossing = np.asarray(lg.crossing, dtype=np.float64) if lg is not None else None
        self.model_level = float(np.asarray(self.model.stick_level))
        if detect == "bridge":
            self.depths = (
                bridge.depth_for(lg.A, dt, bridge.LOCATE_SCALE),
                bridge.depth_for(lg.A, dt, bridge.CERTIFY_SCALE),
            )
        self.tol = float(crossing_tol)
        streams = {
            "step": (_rng.STEP, 0),
            "bridge": (_rng.BRIDGE, 0),
            "z": (_rng.LOCATE, 0),
            "u": (_rng.LOCATE, 1),
            "onset": (_rng.ONSET, 0),
            "tree": (_rng.TREE, 0),
        }
        self.keys = dict(zip(streams, _rng.stream_keys(root, streams.values()), strict=True))
        self.dt, self.t_max, self.bar = dt, t_max, bar
        self.n_steps = max(1, math.ceil(t_max / dt - 1e-9))
        self.dt_arr = np.asarray(dt, dtype=np.float64)
        self.solver = make_solver(lg, self.cfg, dt, LOOP_NODES, owner)
        self.locator = self.solver
        if solver == "exact" and detect != "bridge":
            self.locator = make_solver(lg, self.cfg, dt, self.nodes, owner)
        # The stepping loop, its model and solver flattened once for all its calls.
        self.advance = _compile.Fixed(
            steps.advance, self.slip, self.solver, self.cfg, 0, timer=self.timer
        )
        self.onset = _compile.Fixed(steps.onset, self.model, smooth, timer=self.timer)
        # Small buffers of the bridge detector (`_chunk`): the loop that steps past candidates.
        self.advance_past = _compile.Fixed(
            steps.advance, self.slip, self.solver, self.cfg, PAST_SLOTS, timer=self.timer
        )
        self.stats.update(path_steps=0, buffers=0)
        if detect == "bridge":
            self.stats.update(candidates=0, refined_nodes=0, unresolved=0)
        self.miss = None  # per-path miss bounds of the stepping of the last `first_passages`
        self.onset_positions = None  # and the positions at onset
        self.refined_miss = 0.0  # the summed miss bounds of every exact refinement
        self._refiner = None  # the exact refinement (compiled), made on first use
        self._locate = None  # the in-step location (`_locate_chunk`), made on first use
        self.scheduler = choose_scheduler(owner, scheduler, detect)
        self._programs: dict = {}  # the device scheduler's programs, by buffer size

    def info(self, model, **extra):
        """How the run was made, for the result's `info`."""
        cfg = self.cfg
        return dict(
            model=type(model).__name__,
            params=model.params(),
            solver=cfg.solver,
            monitor=cfg.monitor,
            dt=self.dt,
            t_max=self.t_max,
            detector=cfg.detect,
            interpolation_nodes=self.nodes,
            **({"crossing_tol": self.tol, "refine_depths": self.depths} if self.depths else {}),
            **extra,
        )

    def call(self, fn, *args, paths=None):
        """`_compile.call`; a call whose first argument is the run's model (or its slip phase,
        `slip`) and whose others are arrays goes through a `_compile.Fixed` of the run (the
        model partitioned once, not at every call: ~0.5 ms a call)."""
        first = args[0] if args else None
        if (first is self.model or first is self.slip) and all(
            isinstance(a, _ARRAYS) for a in args[1:]
        ):
            fixed = self._fixed.get((fn, first is self.model))
            if fixed is None:
                fixed = self._fixed[(fn, first is self.model)] = _compile.Fixed(
                    fn, first, timer=self.timer
                )
            return self._counted(fixed(*args[1:], paths=paths))
        return self._counted(_compile.call(fn, *args, timer=self.timer, paths=paths))

    def count_call(self, transfers: int) -> None:
        """Count one compiled call (`stats["dispatches"]`) and the arrays read back from it
        (`stats["transfers"]`: on an accelerator each is a copy to the host)."""
        with self._count_lock:  # (the refinement's two threads)
            self.stats["dispatches"] += 1
            self.stats["transfers"] += transfers

    def _counted(self, out):
        """`out`, a compiled call's result, counted with all its arrays (an upper bound of
        the copies: the host scheduler leaves some on the device for its next call)."""
        self.count_call(len(jax.tree_util.tree_leaves(out)))
        return out

    def device_program(self, size: int) -> _compile.Fixed:
        """The device scheduler's program for a chunk buffer of `size` paths."""
        program = self._programs.get(size)
        if program is None:
            from . import device

            program = self._programs[size] = device.program_for(self, size)
        return program

    def first_passages(self, paths, chunk_size, onsets=None):
        """Onset state, stick state, stick time (`nan` if none by the last step) and whether
        the stick was located, for the paths with counters `paths`, chunk by chunk. The
        slips start from `onsets` `(d, n)` where given (a model with memory: where the last
        stick led), else from the model's onset states."""
        self.refined_miss = 0.0
        chunk = self._chunk
        if onsets is not None:
            if self.scheduler == "device":  # (`simulate_cycles` runs the host scheduler)
                raise NotImplementedError("given onsets need the host scheduler")
            given = np.asarray(onsets, dtype=np.float64)
            chunk = lambda p, i: self._chunk(p, given[:, i : i + p.size])  # noqa: E731
        if self.scheduler == "device":
            from . import device

            # (one program for all the chunks of the run: its buffer holds the largest)
            size = buffer_size(min(paths.size, chunk_size))
            chunk = functools.partial(device.first_passages, self, size)
        else:
            n = min(paths.size, chunk_size)
            want, chunk_size = buffer_size(n), self._chunk_length(n)
        start = time.perf_counter()
        if onsets is None:
            parts = [chunk(paths[i : i + chunk_size]) for i in range(0, paths.size, chunk_size)]
        else:
            parts = [chunk(paths[i : i + chunk_size], i) for i in range(0, paths.size, chunk_size)]
        if self.scheduler != "device" and chunk_size < n:
            # Chunks of a smaller buffer: the fraction of the time a buffer of the size
            # wanted would have saved, about, is rent for it (`_compile.rent`).
            wasted = (time.perf_counter() - start) * (1.0 - chunk_size / want)
            _compile.rent(self._want_key(want), wasted)
        # Paths whose state left the finite numbers: found while stepping (`_chunk`), or
        # from a non-finite onset (and at the stick: `cycle_outputs`).
        stepped = [p[6] if len(p) > 6 else np.zeros(p[2].size, dtype=bool) for p in parts]
        self.nonfinite = np.concatenate(stepped) if len(parts) > 1 else stepped[0]
        if len(parts) == 1:  # as they are (the onset states: a read-only view; callers copy)
            self.miss, self.onset_positions = parts[0][4:6]
            out = parts[0][:4]
        else:
            self.miss = np.concatenate([p[4] for p in parts])
            self.onset_positions = np.concatenate([p[5] for p in parts])
            out = tuple(np.concatenate([p[i] for p in parts], axis=-1) for i in range(4))
        self.onsets = out[0]
        onset_bad = ~np.isfinite(out[0]).all(axis=0)
        if onset_bad.any():
            self.nonfinite = self.nonfinite | onset_bad
            if self.nonfinite_at is None:
                self.nonfinite_at = (None, out[0][:, np.argmax(onset_bad)].copy(), None)
        return out

    def miss_sum(self) -> float:
        """Summed bounds on a missed crossing over the paths of the last `first_passages`:
        of the steps the stepping loop certified, and of the refined sub-intervals."""
        stepped = float(np.sum(self.miss)) if self.miss is not None else 0.0
        return stepped + self.refined_miss

    def cycle_outputs(self, paths, counter, stick_state, t_stick):
        """The next onset states `(d, n)` (of the cycle `counter` of the paths `paths`) and
        the per-path outputs of an `Ensemble`, from the raw first-passage results of the
        last `first_passages`."""
        n = paths.size
        if self.model.carries_state:
            X1, T_st, x_sl = self._released(paths, counter, stick_state)
        else:
            X1, _, _, T_st, x_sl = self._onset_states(paths, counter, stick_state)
        X1, T_st, x_sl = (np.asarray(a)[..., :n] for a in (X1, T_st, x_sl))
        x_start = self.onset_positions
        stuck = np.isfinite(t_stick) & (t_stick <= self.t_max)
        # A stick reached in a non-finite state (an infinite drift crosses any level at
        # once) is no stick: those paths are counted apart (`nonfinite`), as are the ones
        # that left the finite numbers while slipping.
        at_stick = stuck & ~(np.isfinite(stick_state).all(axis=0) & np.isfinite(T_st))
        if at_stick.any() and self.nonfinite_at is None:
            k = np.argmax(at_stick)
            self.nonfinite_at = (self.onsets[:, k].copy(), stick_state[:, k].copy(), None)
        self.nonfinite = self.nonfinite | at_stick
        stuck &= ~self.nonfinite
        nan = np.where(stuck, 1.0, np.nan)
        stick_state *= nan  # no stick state for the paths that never stuck
        slip_time = t_stick * nan
        stick_time = T_st * nan
        return X1, dict(
            slip_time=slip_time,
            stick_position=x_sl * nan,
            slip_distance=(x_start - x_sl) * nan,
            stick_time=stick_time,
            period=slip_time + stick_time,
            immediate=stuck & (t_stick == 0.0),
            stuck=stuck,
        )

    def upcrossings(self, paths, X0, immediate, max_crossings, chunk_size):
        """The free run (no absorption) of the paths, recording their upcrossings."""
        from .upcrossings import Upcrossings, crossing_slots, record

        n = paths.size
        times = np.full((n, max_crossings), np.nan)
        positions = np.full((n, max_crossings), np.nan)
        count = np.zeros(n, dtype=np.int64)
        for start in range(0, n, chunk_size):
            rows = np.arange(start, min(start + chunk_size, n))
            size = buffer_size(rows.size)
            X, p = pad_paths(X0[:, rows], size), pad_paths(paths[rows], size)
            # The free run counts upcrossings with the cubic check (the exact detector
            # refines only a path's first crossing).
            cfg = self.cfg
            if cfg.detect == "bridge":
                cfg = dataclasses.replace(cfg, detect="cubic")
            c, t, x = self.call(
                record, self.slip, self.solver, cfg, X, p, self.dt_arr,
                self.keys["step"], self.keys["bridge"], np.asarray(float(self.n_steps)),
                np.asarray(float(max_crossings)), crossing_slots(max_crossings), paths=size,
            )  # fmt: skip
            count[rows] = np.asarray(c)[: rows.size].astype(np.int64)
            times[rows] = np.asarray(t)[:max_crossings, : rows.size].T
            positions[rows] = np.asarray(x)[:max_crossings, : rows.size].T
        pos = np.array(self.onset_positions, dtype=float)  # (of X0: the last first passages)
        return Upcrossings(times, positions, count, immediate.copy(), pos, self.t_max, self.dt)

    def onsets(self, paths, counter=0):
        """Onset states of the paths with counters `paths`."""
        return np.asarray(self._onset_states(paths, counter)[0])[:, : paths.size]

    def _onset_states(self, paths, counter=0, stick_state=None, exact=False):
        """`steps.onset` for the paths `paths` (and their stick states, if given), on the padded
        size (`_onset_size`; with `exact`, on `paths.size`: a chunk's buffer), as the device
        arrays of the call."""
        size = paths.size if exact else self._onset_size(paths.size)
        if stick_state is None:
            stick = np.zeros((len(self.model.state_names), size))
        else:
            stick = pad_paths(np.asarray(stick_state, dtype=np.float64), size)
        return self._counted(
            self.onset(
                self.keys["onset"], pad_paths(paths, size), np.uint32(counter), stick, paths=size
            )
        )

    def _released(self, paths, counter, stick_state):
        """`steps.release` for the paths `paths` from their stick states (a model with memory);
        the paths that never stuck (`nan` states) give `nan`."""
        size = self._onset_size(paths.size)
        stick = pad_paths(np.nan_to_num(np.asarray(stick_state, dtype=np.float64)), size)
        X1, T_st, x_sl = self.call(
            steps.release, self.model, self.keys["onset"], pad_paths(paths, size),
            np.asarray(counter, dtype=np.uint32), stick, paths=size,
        )  # fmt: skip
        lost = ~np.all(np.isfinite(np.asarray(stick_state)), axis=0)
        X1, T_st, x_sl = (np.array(a)[..., : paths.size] for a in (X1, T_st, x_sl))
        X1[:, lost], T_st[lost], x_sl[lost] = np.nan, np.nan, np.nan
        return X1, T_st, x_sl

    def _onset_size(self, n: int) -> int:
        """The size an onset call of `n` paths runs on (`padded_size`, or a larger compiled
        one, `_size_at_hand`): the draws are keyed by path, the padding is discarded."""
        size = padded_size(n)
        if size > DEFAULT_CHUNK:
            return size
        return self._size_at_hand(self.onset, self._onset_specimen, size, DEFAULT_CHUNK)

    def _onset_specimen(self, size: int):
        """Stand-ins for `steps.onset`'s arguments after its fixed ones, for `size` paths."""
        d = len(self.model.state_names)
        return self.keys["onset"], stand_in(size, np.uint32), np.uint32(0), stand_in((d, size))

    def _size_at_hand(
        self, fixed, specimen, want: int, most: int, smaller: bool = False, ladder=None
    ):
        """The size that a call of `fixed` (a `_compile.Fixed`) on `want` paths runs on:
        `want` where it is compiled (in memory or on disk) or under the `"eager"` policy,
        else a compiled one that stands in (`stand_in_size`, on `ladder`; with `smaller`,
        the caller makes several calls of a smaller one), else `want` (compiled at the
        call). `specimen(size)`: the call's arguments after the fixed ones, for `size`
        paths."""
        ready = lambda m: fixed.ready(*specimen(m), paths=m)  # noqa: E731
        if _compile.policy() == "eager" or ready(want):
            return want
        return stand_in_size(ready, want, most, smaller, ladder) or want

    def _chunk_onsets(self, path, count: int, size: int, onsets):
        """A chunk's onset states (on the device, and read here), their crossing variable,
        which paths stick at once, and the paths' first modes (padding inactive)."""
        # On the device for the calls below (a NumPy argument is copied at every call: the
        # states twice, ~2.5 ms at 131072 paths); read here through a zero-copy view.
        if onsets is None:
            X0_dev, x_start, rate = self._onset_states(path, exact=True)[:3]
        else:
            X0_dev = pad_paths(onsets, size)
            x_start, rate = self.call(steps.at_onset, self.model, self.cfg.smooth, X0_dev,
                                      paths=size)  # fmt: skip
        X0, x_start, rate = np.asarray(X0_dev), np.asarray(x_start), np.asarray(rate)
        k_stick = np.full(size, INACTIVE)
        k_stick[:count] = SLIPPING
        immediate = np.zeros(size, dtype=bool)
        if self.cfg.smooth:
            # A crossing variable already rising at onset ends the slip at once (T_sl = 0).
            immediate[:count] = rate[:count] >= 0.0
            k_stick[immediate] = INACTIVE
        if self.bar is not None:
            self.bar.update(int(np.sum(immediate)))
        return X0_dev, X0, x_start, immediate, k_stick

    def _chunk(self, paths, onsets=None):
        """First passages of one chunk of paths (from `onsets` `(d, count)` where given);
        see `simulate`. Also returns each path's miss bound (bridge detector; zeros
        otherwise)."""
        refine = self.cfg.detect == "bridge"
        count = paths.size
        want = buffer_size(count)
        size, past = self._first_buffer(want)
        path = np.zeros(size, dtype=np.uint32)
        path[:count] = paths
        X0_dev, X0, x_start, immediate, k_stick = self._chunk_onsets(path, count, size, onsets)
        # Chunk-level results; buffers are written back into them by `slot` (-1: padding).
        if not refine:  # (the bridge detector writes sticks as it refines them)
            X_end, X_prev_end, k_end = X0.copy(), X0.copy(), k_stick.copy()
        t_stick = np.full(count, np.nan)
        stick_state = X0[:, :count].copy()
        located = np.ones(count, dtype=bool)
        nonfinite = np.zeros(count, dtype=bool)
        miss_end = np.zeros(size)
        slot = np.arange(size)
        slot[count:] = -1
        # Buffer: states, modes, path counters, each path's next global step, miss bounds.
        X, X_prev, ks, p = X0, X0, k_stick, path
        offset, miss = np.zeros(size), np.zeros(size)
        X_dev, X_prev_dev, miss_dev = X0_dev, X0_dev, miss
        # Small buffers step past candidate steps that end below the level (as if refuted)
        # and refine them all at the end, each path's in step order: the same first crossing
        # as refining each before going on (the draws are keyed by path, step and node), in
        # one refinement instead of one per stepping round (each ~1 ms whatever its size).
        pending = []
        # `want`: the buffer size the paths left call for; `size`: the one they run on, larger
        # where `want` has no executable yet (`_first_buffer`, `_stand_in`; the same numbers
        # either way).
        first = True
        while True:
            n_slip = np.count_nonzero(ks == SLIPPING)
            if n_slip == 0:
                if pending:
                    self._settle(pending, t_stick, stick_state, miss_end)
                break
            args = self._loop_args(X_dev, X_prev_dev, ks, miss_dev, p, offset, smaller_buffer(want))
            loop = self._loop(past)
            if first and refine:
                # (a speculating loop holds up to 1 + PAST_SLOTS candidates a path for the end)
                self._prefetch_refiner(loop, args, size, count * (1 + PAST_SLOTS if past else 1),
                                       X0.shape[0], exact=not past)  # fmt: skip
            first = False
            slipping = ks == SLIPPING
            out, taken = self._step_buffer(loop, args, size, want)
            # The states stay where the loop left them for its next call (read here through
            # zero-copy views; copying them in and out cost ~3 ms a call at 131072 paths).
            X_dev, X_prev_dev, miss_dev = out[0], out[1], out[3]
            X, X_prev, miss = np.asarray(X_dev), np.asarray(X_prev_dev), np.asarray(miss_dev)
            ks = np.array(out[2])  # a copy: the host sets modes in it
            passing = ks == PASSED
            ks[passing] = SLIPPING
            self._stop_nonfinite(X, X_prev, X0, ks, slipping, slot, nonfinite)
            # (+ 0.0 elsewhere: the same numbers as a select, without its branches; 2x faster)
            offset = offset + (ks == SLIPPING) * float(taken)
            real = slot >= 0
            if past:
                self._step_past(out, real, passing, ks, offset, miss, X_prev, X, p, slot, pending)
            elif refine:
                self._refine_candidates(real, ks, offset, X_prev, X, p, slot, t_stick,
                                        stick_state)  # fmt: skip
            else:
                X_end[:, slot[real]] = X[:, real]
                X_prev_end[:, slot[real]] = X_prev[:, real]
                k_end[slot[real]] = ks[real]
            miss_end[np.compress(real, slot)] = np.compress(real, miss)
            alive = np.nonzero(ks == SLIPPING)[0]
            if self.bar is not None:
                self.bar.update(n_slip - alive.size)
            if alive.size and want > MIN_BUFFER and alive.size <= smaller_buffer(want):
                want = buffer_size(alive.size)
                new_size, past = self._stand_in(want, size, past)
                if new_size == size:
                    continue
                # Re-pack the survivors into a smaller buffer: finished paths cost nothing.
                size = new_size
                pad = size - alive.size
                # Every path left slips, and the loop's first step sets a slipping path's
                # `X_prev` (the start of its last step) before anything reads it: the repacked
                # states serve as both (one repack and one copy into the call fewer).
                X = X_prev = repack(X, alive, pad, 0.0)
                ks = repack(ks, alive, pad, INACTIVE)
                p, slot = repack(p, alive, pad, 0), repack(slot, alive, pad, -1)
                offset, miss = repack(offset, alive, pad, 0.0), repack(miss, alive, pad, 0.0)
                X_dev, X_prev_dev, miss_dev = X, X_prev, miss
        if not refine:
            self._locate_chunk(X_end, X_prev_end, k_end, path, count, t_stick, stick_state, located)
        imm = immediate[:count]
        t_stick[imm] = 0.0
        return (X0[:, :count], stick_state, t_stick, located, miss_end[:count], x_start[:count],
                nonfinite)  # fmt: skip

    def _prefetch_refiner(self, loop, args, size: int, candidates: int, d: int, exact: bool):
        """The refinement's first buffer compiles in a thread while the stepping loop
        compiles: started once the loop is traced (tracing holds Python's lock, XLA's
        compiling does not)."""
        loop.trace(*args, paths=size)
        self.refiner().prefetch(candidates, d, exact=exact)

    def _step_buffer(self, loop, args, size: int, want: int):
        """One call of the stepping loop on a buffer of `size` paths: its outputs and the
        steps it took; the rent of the size wanted where it ran on a larger one
        (`_compile.rent`: the call is done) and the run's counts."""
        start = time.perf_counter()
        out = self._counted(loop(*args, paths=size))
        taken = int(round(float(out[4])))
        if size > want:
            wasted = (time.perf_counter() - start) * (1.0 - want / size)
            _compile.rent(self._want_key(want), wasted)
        self.stats["path_steps"] += size * taken
        self.stats["buffers"] += 1
        return out, taken

    def _stop_nonfinite(self, X, X_prev, X0, ks, slipping, slot, nonfinite) -> None:
        """A slipping path whose state left the finite numbers (a model's drift that is
        nan somewhere) never sticks: its crossing variable compares false. It is stopped
        here (its mode set inactive in `ks`) and counted apart (`nonfinite`, by chunk row;
        `cycle_outputs`), not run on to t_max."""
        gone = np.flatnonzero(~np.isfinite(X).all(axis=0) & slipping & (slot >= 0))
        if gone.size:
            nonfinite[slot.take(gone)] = True
            ks[gone] = INACTIVE
            if self.nonfinite_at is None or not np.isfinite(self.nonfinite_at[0]).all():
                # (one that left in the call's last step: its step's start is finite)
                last = np.isfinite(X_prev[:, gone]).all(axis=0)
                g = gone[np.argmax(last)]
                self.nonfinite_at = (X_prev[:, g].copy(), X[:, g].copy(), X0[:, slot[g]])

    def _step_past(self, out, real, passing, ks, offset, miss, X_prev, X, p, slot, pending):
        """Candidates left to the end (a speculating loop): step on past those that end
        below the level. The loop stepped past up to PAST_SLOTS of them per path (its
        record, and the paths that stepped past one in their last step); a candidate beyond
        them ended the path's stepping and is stepped past here. Each is held in `pending`
        (its chunk row, step, miss bound before it, path, both ends); `ks` and `offset` are
        updated in place."""
        # (which paths, their candidate's step, miss bound before it, both ends)
        held = [(passing, offset - 1.0, miss, X_prev, X), (ks >= 0, ks, miss, X_prev, X)]
        if len(out) > 5:  # the loop's record (PAST_SLOTS > 0)
            held_n, rec_step, rec_miss, rec_a, rec_b = (np.asarray(a) for a in out[5:])
            held += [
                (held_n > r, rec_step[r], rec_miss[r], rec_a[r], rec_b[r])
                for r in range(rec_step.shape[0])
            ]
        for mask, step, miss_at, Xa, Xb in held:
            i = np.nonzero(real & mask)[0]
            if i.size:
                ends = cols(Xa, i), cols(Xb, i)
                pending.append((slot[i], step[i], miss_at[i], p[i], *ends))
        cand = np.nonzero(real & (ks >= 0))[0]
        below = self.crossing @ cols(X, cand) < self.model_level
        back = np.compress(below, cand)
        offset[back] = ks.take(back) + 1.0
        ks[back] = SLIPPING
        ks[np.compress(~below, cand)] = INACTIVE

    def _refine_candidates(self, real, ks, offset, X_prev, X, p, slot, t_stick, stick_state):
        """The bridge detector: refine this round's candidate steps now; a found stick's
        time and state go to its chunk row, a refuted candidate's path resumes at the next
        step (`ks`, `offset`, `t_stick`, `stick_state` updated in place)."""
        cand = np.nonzero(real & (ks >= 0))[0]
        found, frac, state, refined = self._refine(cand, X_prev, X, ks, p)
        self.refined_miss += float(np.sum(refined))
        f = np.flatnonzero(found)  # integer indices: ~2x faster than the mask here
        # (`take` and `compress`: 1.5x and 4x faster than fancy and mask indexing)
        hit, back = cand.take(f), np.compress(~found, cand)
        rows = slot.take(hit)
        t_stick[rows] = (ks.take(hit) + frac.take(f)) * self.dt
        set_cols(stick_state, rows, cols(state, f))
        offset[back] = ks.take(back) + 1.0  # refuted: resume at the next step
        ks[back] = SLIPPING
        ks[hit] = INACTIVE

    def _speculates(self, size: int) -> bool:
        """Whether a buffer of `size` paths steps past candidates (leaves them for the end;
        the loop itself steps past up to `PAST_SLOTS`, `_loop`)."""
        return self.cfg.detect == "bridge" and size <= SPECULATE_BELOW

    def _loop(self, past: bool) -> _compile.Fixed:
        """The stepping loop of a buffer that steps past candidates (`past`) or not."""
        return self.advance_past if past and PAST_SLOTS else self.advance

    def _want_key(self, size: int):
        """The rent key (`_compile.rent`) of the stepping loop wanted for `size` paths: the
        loop's, one for all its sizes."""
        return self._loop(self._speculates(size)).key

    def _loop_args(self, X, X_prev, ks, miss, p, offset, stop_at):
        """The stepping loop's arguments after its model, solver and configuration: the
        buffer's states, modes, miss bounds, paths and step offsets, and where to stop (the
        paths left slipping at or below `stop_at`)."""
        keys = self.keys
        return (
            X, X_prev, ks, miss, p, offset, np.asarray(float(self.n_steps)), self.dt_arr,
            keys["step"], keys["bridge"], np.asarray(stop_at), np.asarray(self.tol),
        )  # fmt: skip

    def _ready(self, size: int):
        """Whether the stepping loop of a buffer of `size` paths is compiled (in memory or
        on disk; nothing is traced or compiled here): the `past` flag of the loop to run it
        with (a buffer that steps past candidates can also run the loop that does not: the
        same numbers), else `None`."""
        for spec in (True, False) if self._speculates(size) else (False,):
            if self._loop(spec).ready(*self._loop_specimen(size), paths=size):
                return spec
        return None

    def _loop_specimen(self, size: int):
        """Stand-ins for the stepping loop's arguments on a buffer of `size` paths."""
        X, f = stand_in((len(self.model.state_names), size)), stand_in(size)
        return self._loop_args(X, X, f, f, stand_in(size, np.uint32), f, 0)

    def _compile_here(self, want: int) -> bool:
        """Whether the stepping loop of `want` paths is to be compiled now if it is not at
        hand: under the `"eager"` policy, or once its rent has passed a compilation's cost
        (then paid); otherwise the background compiler is asked for it (`policy`)."""
        if _compile.policy() == "eager":
            return True
        key = self._want_key(want)
        if _compile.due(key):
            _compile.pay(key)
            return True
        loop = self._loop(self._speculates(want))
        _background.request(loop.fn, *loop.fixed, *self._loop_specimen(want), paths=want)
        return False

    def _at_hand(self, want: int):
        """`(size, past)` of a compiled stepping loop (`_ready`) for a chunk that wants a
        buffer of `want` paths: its own loop at `want`; else (not under the `"eager"`
        policy, nor with `_compile.STAND_IN` 0) the other loop at `want` (one that does or
        does not step past candidates: the same numbers), else a compiled size that stands
        in (`stand_in_size`: a larger buffer, padded, or a smaller one, in more chunks);
        `None` if none."""
        spec = self._speculates(want)
        if self._loop(spec).ready(*self._loop_specimen(want), paths=want):
            return want, spec
        if _compile.policy() == "eager" or not _compile.STAND_IN:
            return None
        ready = lambda m: self._ready(m) is not None  # noqa: E731
        size = want if ready(want) else stand_in_size(ready, want, 1 << 62, smaller=True)
        return None if size is None else (size, self._ready(size))

    def _chunk_length(self, n: int) -> int:
        """Paths per chunk for chunks of up to `n` paths: `n`, or the size of a smaller
        compiled buffer where that is the one at hand (`_at_hand`) and the wanted one is not
        to be compiled here (`_compile_here`): more chunks on a compiled loop, the same
        numbers (each path's are keyed by its index)."""
        want = buffer_size(n)
        found = self._at_hand(want)
        if found is not None and found[0] < want and not self._compile_here(want):
            return found[0]
        return n

    def prefetch(self, count: int) -> None:
        """Compile the programs that a chunk of `count` paths will start on, unless a compiled
        stepping loop is at hand for it (`_at_hand`): its onset and its stepping loop at the
        buffer size it wants. For a caller that runs them later and has the compiling, which
        XLA does without Python's lock, overlap other work (in a thread). Nothing changes
        but when they are compiled."""
        want = buffer_size(count)
        if self._at_hand(want) is not None:
            return
        self.onset.ready(*self._onset_specimen(want), paths=want, build=True)
        self._loop(self._speculates(want)).ready(*self._loop_specimen(want), paths=want, build=True)

    def _first_buffer(self, want: int):
        """The buffer size (and whether it steps past candidates) that a chunk wanting a
        buffer of `want` paths starts on: a larger compiled one where that is the one at
        hand (`_at_hand`) and the wanted one is not to be compiled here (`_compile_here`):
        padded, the same numbers (the time it wastes is rent for `want`); else `want`."""
        found = self._at_hand(want)
        if found is None or (found[0] != want and (found[0] < want or self._compile_here(want))):
            return want, self._speculates(want)
        return found

    def _stand_in(self, want, size, past):
        """The buffer size (and whether it speculates) that `want` paths run on, at most
        `size` (the current one, whose loop `past` is at hand): `want` itself where its loop
        is compiled (in memory or on disk) or is to be compiled here (`_compile_here`);
        otherwise the smallest size between them whose loop is compiled."""
        candidate = want
        while candidate < size:
            spec = self._ready(candidate)
            if spec is not None:
                return candidate, spec
            if candidate == want and self._compile_here(want):
                return want, self._speculates(want)
            candidate = larger_buffer(candidate)
        return size, past

    def _settle(self, pending, t_stick, stick_state, miss_end):
        """Refine the candidate steps that `_chunk` stepped past (`pending`: per stepping
        round, their chunk rows, steps, stepping miss bounds so far, paths and both end
        states) and write each path's stick, in its first candidate (in step order) that
        holds a crossing, with its miss bound there. The refinements of candidates past a
        path's stick are not counted in the miss bound: it is the one of refining each
        candidate before stepping on. A path's last candidate ends at or above the level
        (on the host's reckoning); should its refinement find no crossing there (an end
        within rounding of the level), the stick is placed at the step's end."""
        rows, step, miss, path, Xa, Xb = (
            np.concatenate(x, axis=-1) for x in zip(*pending, strict=True)
        )
        # By chunk row, then step (one integer key: 4x faster than `np.lexsort` here; the keys
        # are distinct and come in sorted runs, one per record, which timsort merges: 3.5x
        # faster than the default quicksort).
        order = np.argsort((rows.astype(np.int64) << 32) | step.astype(np.int64), kind="stable")
        rows, step, miss, path = rows[order], step[order], miss[order], path[order]
        Xa, Xb = cols(Xa, order), cols(Xb, order)
        found, frac, state, refined = self._refine(np.arange(rows.size), Xa, Xb, step, path)
        first = np.r_[True, rows[1:] != rows[:-1]]
        ended = np.r_[first[1:], True] & ~found & (self.crossing @ Xb >= self.model_level)
        frac[ended], state[:, ended] = 1.0, Xb[:, ended]
        hit = found | ended
        # A candidate was needed if no earlier one of its path holds the stick.
        seen = np.cumsum(hit) - hit
        needed = seen == np.maximum.accumulate(np.where(first, seen, 0))
        stick = np.nonzero(hit & needed)[0]
        t_stick[rows[stick]] = (step[stick] + frac[stick]) * self.dt
        set_cols(stick_state, rows[stick], cols(state, stick))
        miss_end[rows[stick]] = miss[stick]
        self.refined_miss += float(np.sum(refined[needed]))
        self.stats["speculated"] = self.stats.get("speculated", 0) + int(np.sum(~needed))

    def _refine(self, cand, X_prev, X, ks, p):
        """Refine the candidate steps `cand` of the buffer exactly (bridge detector): for
        each, whether it crossed, where (fraction of its step), the state there and the
        summed bounds of its certified sub-intervals."""
        n = cand.size
        if n == 0:
            return np.zeros(0, bool), np.zeros(0), np.zeros((X.shape[0], 0)), np.zeros(0)
        self.stats["candidates"] += n
        if cand[-1] - cand[0] + 1 == n:  # a range (a buffer's onset steps): slices, no gathers
            cand = slice(cand[0], cand[-1] + 1)
        found, frac, state, add, unresolved, splits = self.refiner().first_crossing(
            cols(X_prev, cand), cols(X, cand), p[cand], ks[cand].astype(np.uint32)
        )
        self.stats["unresolved"] += int(np.sum(unresolved))
        self.stats["refined_nodes"] += int(splits)
        return found, frac, state, add

    def refiner(self) -> bridge.Refiner:
        """The run's exact refinement (bridge detector), made on first use."""
        if self._refiner is None:
            self._refiner = bridge.Refiner(
                self.solver.bridge, self.model.stick_level, self.keys["tree"], self.depths,
                self.tol, self.timer,
            )  # fmt: skip
            # Its compiled calls counted as the run's (the class's `_call`, looked up at
            # each call).
            refiner = self._refiner
            refiner._call = lambda *a, **k: self._counted(type(refiner)._call(refiner, *a, **k))
        return self._refiner

    def _locate_chunk(self, X_end, X_prev_end, k_end, path, count, t_stick, stick_state, located):
        """Locate each stick inside its step (all detectors but the bridge), in batches that
        bound the memory of the dense nodes."""
        model, cfg, keys = self.slip, self.cfg, self.keys
        done = np.nonzero(k_end[:count] >= 0)[0]
        if self._locate is None:
            self._locate = _compile.Fixed(steps.locate, model, self.locator, cfg, timer=self.timer)
        d = len(model.state_names)
        batch = self._size_at_hand(
            self._locate,
            lambda m: (stand_in((d, m)), stand_in((d, m)), stand_in(m), stand_in(m, np.uint32),
                       self.dt_arr, keys["z"], keys["u"]),
            min(LOCATE_BATCH, buffer_size(max(done.size, 1))), LOCATE_BATCH, smaller=True,
        )  # fmt: skip
        for start in range(0, done.size, batch):
            rows = done[start : start + batch]
            rows_padded = pad_paths(rows, batch)
            frac, state, found = self._counted(
                self._locate(
                    X_prev_end[:, rows_padded], X_end[:, rows_padded], k_end[rows_padded],
                    path[rows_padded], self.dt_arr, keys["z"], keys["u"], paths=batch,
                )
            )  # fmt: skip
            n = rows.size
            t_stick[rows] = (k_end[rows] + np.asarray(frac)[:n]) * self.dt
            stick_state[:, rows] = np.asarray(state)[:, :n]
            located[rows] = np.asarray(found)[:n]
