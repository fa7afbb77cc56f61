"""`simulate`: one slip-stick cycle for each of many paths, run as blocks of paths (on
this host or a Dask cluster) and joined."""

from __future__ import annotations

import sys
import time
import warnings

import numpy as np

from .. import _rng
from .._errors import ParameterError, check_choice, check_int, check_positive
from .._memory import check_memory
from .._model import CreepingSlider, FrictionModel
from .._model_check import check_shapes, explain, warn_nonfinite
from . import host
from .buffers import DEFAULT_CHUNK
from .config import DEFAULT_CROSSING_TOL, simulate_bytes, validate_args
from .ensemble import Ensemble


def simulate(
    model: FrictionModel,
    n_paths: int,
    dt: float,
    t_max: float,
    seed: int = 0,
    *,
    solver: str = "auto",
    monitor: str = "continuous",
    chunk_size: int = DEFAULT_CHUNK,
    progress: bool | None = None,
    record_upcrossings: int = 0,
    crossing_tol: float = DEFAULT_CROSSING_TOL,
    client=None,
    scheduler: str = "auto",
) -> Ensemble:
    r"""Simulate one slip-stick cycle for each of `n_paths` paths.

    Each path starts a slip at the model's onset state, is integrated until its crossing
    variable first reaches the stick level (the stick) or until `t_max`, and then sticks for
    the closed-form stick time up to the next release.

    **Arguments:**

    - `model`: a `FrictionModel` instance.
    - `n_paths`: number of paths.
    - `dt`: step size. With the exact solver it sets only how often the stick is looked for.
    - `t_max`: longest slip followed; paths still slipping then get `nan`.
    - `seed`: results are a function of `(seed, path index)` alone: any `chunk_size` gives
      the same numbers.
    - `solver`: `"exact"` (exact Gaussian transitions; linear-Gaussian slips only),
      `"euler"` (Euler-Maruyama, any model) or `"auto"` (exact where possible).
    - `monitor`: `"continuous"` (default) looks for sticks inside each step as well. With the
      exact solver and noise reaching a differentiable crossing variable (OU friction noise)
      the test is exact in law: Rice's bound on the Gaussian bridge's upcrossings selects
      the steps to refine, and refinement samples the bridge until the first crossing is
      found or ruled out (`crossing_tol`; docs/simulator.md). Noise in the crossing variable
      itself: the Brownian-bridge test. Otherwise (Euler-Maruyama, or no noise) a cubic
      check through the end values, located on the solver's own interpolant. `"grid"` is the classic
      convention of the paper's simulations and the reference data: the first grid point
      at or above the level, placed by linear interpolation. It misses crossings inside a
      step (a bias that vanishes with `dt`) and, from a slip onset at the level, puts the
      paths that cross in the first step at $T_{sl} = 0$, $d = 0$.
    - `chunk_size`: paths per chunk (memory bound); inside a chunk, finished paths are
      dropped by re-packing the survivors into buffers half as large.
    - `progress`: show a progress bar (default: on a terminal, for 20000 paths or more).
    - `record_upcrossings`: if K > 0, also run every path on past its stick, without
      absorption, until `t_max`, and record its first K upcrossings of the stick level
      (`Ensemble.upcrossings`, for the empirical crossing statistics). The noise is the
      same; upcrossings inside a step are found by the cubic check (not exact in law).
    - `crossing_tol`: exact detector only: a step (or sub-step) whose bound on the chance of
      a crossing inside it is at most this is certified crossing-free. The summed bounds of
      the certified steps, a bound on the chance that a path's stick was missed, are
      reported as `Ensemble.stats["miss_bound"]` (mean over paths).
    - `client`: run blocks of paths as tasks on a Dask cluster: a `dask.distributed.Client`,
      a scheduler address, or `"local"` (a local cluster, one worker process per CPU it may
      use). The numbers are identical to a local run with the same seed
      (docs/distributed.md); the blocks hold about four per worker thread, at most
      `chunk_size` paths each.
    - `scheduler`: how a chunk is run. `"host"`: a sequence of short compiled calls with
      the compaction and refinement batches cut on the host (the fastest on a CPU);
      `"device"`: one compiled program per chunk, stepping, refinement and resolution on
      the device, one copy to the host at the end (for accelerators; the exact bridge
      detector only); `"auto"`: the device scheduler on an accelerator where the detector
      allows it, else the host one. The same sticks either way (`stats["dispatches"]`
      and `stats["transfers"]` count a run's compiled calls and arrays handed back).

    **Returns:** an `Ensemble`.
    """
    if isinstance(model, CreepingSlider):  # one motion through stick and slip, integrated
        from . import creep

        check_shapes("simulate", model)

        args = creep.check_args("simulate", model, n_paths, dt, t_max, seed, solver, monitor)
        creep.refuse_options(
            "simulate", record_upcrossings=(record_upcrossings, 0), client=(client, None),
            scheduler=(scheduler, "auto"),
        )  # fmt: skip
        out = creep.first_cycles(model, *args)
        return Ensemble(
            **{k: out[k] for k in ("slip_time", "stick_position", "slip_distance")},
            stick_time=out["stick_time"], period=out["period"], stuck=out["stuck"],
            immediate=np.zeros(args[0], dtype=bool), onset_state=out["onset"],
            stick_state=out["stick"], next_onset_state=out["next"],
            state_names=tuple(model.state_names), info=out["info"], stats=out["stats"],
        )  # fmt: skip
    n_paths, dt, t_max, seed, chunk_size = validate_args(
        "simulate", model, n_paths, dt, t_max, seed, solver, monitor, chunk_size
    )
    record_upcrossings = check_int("simulate", "record_upcrossings", record_upcrossings, minimum=0)
    crossing_tol = check_positive("simulate", "crossing_tol", crossing_tol)
    check_choice("simulate", "scheduler", scheduler, ("auto", "device", "host"))
    if crossing_tol >= 1.0:
        raise ParameterError("simulate", "crossing_tol", "must be < 1", crossing_tol)
    check_memory(
        "simulate",
        f"{n_paths} paths"
        + (f" with {record_upcrossings} upcrossings each" if record_upcrossings else ""),
        simulate_bytes(n_paths, len(model.state_names), record_upcrossings, chunk_size),
        "run fewer paths (results depend on (seed, path) alone: runs of consecutive blocks "
        "of paths can be joined)",
    )
    wall0 = time.perf_counter()
    if progress is None:
        progress = n_paths >= 20000 and sys.stderr.isatty()
    opts = dict(
        solver=solver, monitor=monitor, chunk_size=chunk_size, crossing_tol=crossing_tol,
        record_upcrossings=record_upcrossings, scheduler=scheduler,
    )  # fmt: skip
    if client is None:
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=n_paths, desc="simulate", unit="path", leave=False)
        try:
            parts = [_simulate_block(model, dt, t_max, seed, opts, 0, n_paths, bar=bar)]
        finally:
            if bar is not None:
                bar.close()
    else:
        from .. import _distributed

        with _distributed.connected("simulate", client) as client:
            blocks = _distributed.blocks(n_paths, client, chunk_size)
            parts = _distributed.run_blocks(
                client, _simulate_block, blocks, model, dt, t_max, seed, opts, progress=progress
            )
    return _join_blocks(parts, model, wall0, tasks=len(parts) if client is not None else 0)


def _simulate_block(model, dt, t_max, seed, opts, start, stop, bar=None) -> dict:
    """`simulate` for the paths `start` .. `stop` - 1 (a task of a distributed run)."""
    run = host.HostRun(
        "simulate", model, opts["solver"], opts["monitor"], dt, t_max, _rng.seed_key(seed), bar,
        opts["crossing_tol"], scheduler=opts.get("scheduler", "host"),
    )  # fmt: skip
    paths = np.arange(start, stop, dtype=np.uint32)
    X0, stick_state, t_stick, located = run.first_passages(paths, opts["chunk_size"])
    next_onset, out = run.cycle_outputs(paths, 1, stick_state, t_stick)
    upcrossings = None
    if opts["record_upcrossings"]:
        upcrossings = run.upcrossings(
            paths, X0, out["immediate"], opts["record_upcrossings"], opts["chunk_size"]
        )
    stats = dict(
        run.stats,
        miss_sum=run.miss_sum(),
        compile_seconds=run.timer.compile_seconds,
        unlocated=int(np.sum(~located & out["stuck"])),
        nonfinite=int(np.sum(run.nonfinite)),
    )
    info = run.info(model, seed=seed, chunk_size=opts["chunk_size"])
    return dict(
        out=out, onset_state=X0.T, stick_state=stick_state.T, next_onset_state=next_onset.T,
        upcrossings=upcrossings, info=info, stats=stats, nonfinite=run.nonfinite,
        nonfinite_at=run.nonfinite_at,
    )  # fmt: skip


def _join_blocks(parts, model, wall0, tasks) -> Ensemble:
    """One `Ensemble` from the results of consecutive blocks of paths."""
    join = lambda arrays: np.concatenate(arrays, axis=0)
    out = {k: join([p["out"][k] for p in parts]) for k in parts[0]["out"]}
    states = {
        k: join([p[k] for p in parts]) for k in ("onset_state", "stick_state", "next_onset_state")
    }
    upcrossings = parts[0]["upcrossings"]
    if upcrossings is not None and len(parts) > 1:
        from .upcrossings import Upcrossings

        ups = [p["upcrossings"] for p in parts]
        upcrossings = Upcrossings(
            **{k: join([getattr(u, k) for u in ups]) for k in Upcrossings.PER_PATH},
            t_max=upcrossings.t_max, dt=upcrossings.dt,
        )  # fmt: skip
    stats = {}
    for p in parts:
        for k, v in p["stats"].items():
            stats[k] = stats.get(k, 0) + v
    n_paths = out["slip_time"].size
    # The miss bound is Boole's bound: the sum, over a path's certified (sub-)intervals, of
    # Rice's bound on the chance of a crossing inside each (each at most `crossing_tol`), plus
    # up to 1 for each interval still undecided at the finest level. Where the step is too
    # coarse for the finest level to certify (dt rho / 2**MAX_DEPTH > CERTIFY_SCALE) a path can
    # hold many of those, and the sum reaches 1: it then bounds nothing ("unbounded").
    bound = stats.pop("miss_sum") / n_paths
    if bound >= 1.0:
        warnings.warn(
            f"simulate: the chance that a path's stick was missed is unbounded: the summed "
            f"bounds of the certified steps are {bound:.3g} per path, 1 or more (the step is too "
            "coarse for the detector to certify; take a smaller dt); stats['miss_bound'] is 1",
            stacklevel=3,
        )
        bound = 1.0
    stats["miss_bound"] = bound
    stats["wall_seconds"] = time.perf_counter() - wall0
    if tasks:
        stats["tasks"] = tasks  # compile_seconds: summed over the tasks
    nonfinite = join([p["nonfinite"] for p in parts])
    if stats["nonfinite"]:
        info = parts[0]["info"]
        at = next(p["nonfinite_at"] for p in parts if p["nonfinite_at"])
        where = explain(model, *at, dt=info["dt"], steps=int(info["t_max"] / info["dt"]))
        stats["nonfinite_where"] = where
        warn_nonfinite("simulate", model, stats["nonfinite"], n_paths, where, stacklevel=4)
    return Ensemble(
        **out, **states, upcrossings=upcrossings, state_names=tuple(model.state_names),
        info=parts[0]["info"], stats=stats, nonfinite=nonfinite,
    )  # fmt: skip
