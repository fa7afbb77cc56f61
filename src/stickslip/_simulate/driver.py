"""`simulate`: one slip-stick cycle for each of many paths."""

from __future__ import annotations

import dataclasses
import functools
import math
import sys
import threading
import time
import warnings

import diffrax
import equinox as eqx
import numpy as np

from .. import _background, _compile, _rng
from .._errors import ParameterError, check_choice, check_int, check_positive
from .._jax import jax, jnp
from .._memory import check_memory
from .._model import CreepingSlider, FrictionModel, LinearGaussian, to_arrays
from .._model_check import check_shapes, explain, structure_key, warn_nonfinite
from .._solver import EulerMaruyama, ExactGaussian
from .._solver.base import over_paths
from . import bridge, localise
from .ensemble import Ensemble
from .hybrid import (
    INACTIVE,
    PASSED,
    SLIPPING,
    SteppingPastHybrid,
    StickSlipHybrid,
    onset_states,
)
from .loop import HORIZON, solve

MIN_BUFFER = 128  # smallest buffer; below it a step costs the same whatever the size
# Buffer sizes: powers of two from FINE_BUFFER up, where a step's cost follows the size; below
# it, where fixed costs dominate a step, only MIN_BUFFER * 8**k (128, 1024): each size is a
# compilation of the loop (about 1.5 s cold on 2 cores), a few extra steps at a larger size
# cost milliseconds (measured per step: 48 us at 128, 228 us at 1024, 495 us at 4096).
FINE_BUFFER = 8192
LOCATE_BATCH = 4096  # paths located at once (bounds the memory of the dense nodes)
SPECULATE_BELOW = 16384  # buffers from this size down step past candidates (`HostRun._chunk`)
PAST_SLOTS = 2  # candidates a path steps past inside one stepping call (`SteppingPastHybrid`)
DEFAULT_CROSSING_TOL = 1e-5  # bound on the chance of a missed crossing per certified step
DEFAULT_CHUNK = 2**20  # about 100 bytes of state per path: 100 MB
# Interpolation sub-steps of the exact solver: chosen so that h_sub * rho(A) <= this, where
# the cubic pieces' relative error (h_sub rho)^4 / 384 stays below 1e-10.
_NODE_SCALE = 0.0125
_MAX_NODES = 256
_LOOP_NODES = 2  # the stepping loop's solver: it never interpolates (see `HostRun`)


# -- limits stated up front ------------------------------------------------------------------
# Time scales: `rho` is the slip's fastest rate, max |eig(A)|. Past SCALE_REFUSE = pi 2**20
# (dt rho), the finest level of the stick's location (dt / 2**MAX_DEPTH) is longer than the
# slip's time scale pi/rho itself, and the step's propagators have lost their precision
# (their error grows like (dt rho)^2 1e-16; measured at omega0 = 1e7, dt = 0.2, dt rho = 2e6:
# det Phi off by 0.6 %): the run is refused. Past SCALE_WARN, a tenth of that, the stick is
# located on intervals longer than a tenth of pi/rho, and the slip times are biased (measured,
# omega0 = 1e6 .. 1e7 at dt = 0.2 against dt / 64: bias 1e-5 at 0.06 pi/rho, 3e-4 at 0.12,
# 4e-3 at 0.3, -2.7e-2 at 0.6): a warning.
SCALE_REFUSE = math.pi * 2.0**bridge.MAX_DEPTH
SCALE_WARN = 0.1 * SCALE_REFUSE
# At the other end, steps too fine for float64 are refused:
# - with the bridge detector, a step shorter than bridge.CERTIFY_SCALE / rho, the finest
#   sub-interval it certifies (the bridge coefficients hold ~8 digits there and lose more
#   below; measured on the public set, rho = 10: the miss bound 0 down to dt rho = 1e-6,
#   2e-4 at 5e-7, 2.6e-3 at 2e-7, and at 1e-7 every path stuck in its first step);
# - with the other detectors, a step shorter than SCALE_FINE / rho, where a step's change of
#   the state, Phi - I ~ A dt, keeps fewer than half of float64's digits (at dt rho = 1e-16
#   it is lost in the rounding of v to v_b, and every path sticks in its first step).
SCALE_FINE = math.sqrt(np.finfo(np.float64).eps)  # 1.5e-8


def _round_up(x: float) -> float:
    """`x > 0` rounded up to three significant digits (a bound a user can type and pass)."""
    unit = 10.0 ** (math.floor(math.log10(x)) - 2)
    return math.ceil(x / unit * (1.0 - 1e-12)) * unit


def _simulate_bytes(n_paths: int, d: int, upcrossings: int, chunk_size: int) -> float:
    """Peak memory of `simulate` (bytes, an estimate from above): per path the outputs (seven
    per-path arrays, three states, the upcrossing record) held twice (blocks, then the joined
    result), the per-path work arrays and the onset and stick states; per chunk the stepping
    buffer (states, previous states, modes, counters, offsets, miss bounds, the device's
    copies)."""
    per_path = 8 * (2 * (6 + 3 * d + 2 * upcrossings + 2) + 10 + 3 * d)
    buffer = _buffer_size(min(n_paths, chunk_size)) * 8 * 4 * (2 * d + 6)
    return float(n_paths) * per_path + buffer


def _check_time_scales(owner: str, lg, dt: float, detect: str) -> None:
    """Refuse a step that the exact solver cannot follow, too coarse or too fine for float64;
    warn where the bridge detector locates the stick more coarsely than the slip's time scale
    (see `SCALE_REFUSE` and `SCALE_FINE`)."""
    A = np.asarray(lg.A, dtype=float)
    rho = float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0
    if not rho > 0:
        return
    ratio = dt * rho / math.pi  # steps of pi/rho (a half-period at the fastest rate) per dt
    scale = math.pi / rho
    where = f"dt = {dt:g} is {ratio:.2g} times the slip's time scale pi/rho(A) = {scale:.2g}"
    if dt * rho > SCALE_REFUSE:
        raise ParameterError(
            owner,
            "dt",
            f"is too coarse: {where} (rho(A) its fastest rate); past {SCALE_REFUSE / math.pi:.2g}"
            " times the stick cannot be located within that scale and the exact propagators "
            f"lose their precision; take dt <= {SCALE_WARN / rho:.3g}",
            dt,
        )
    floor = bridge.CERTIFY_SCALE if detect == "bridge" else SCALE_FINE
    if dt * rho < floor * (1.0 - 1e-9):  # (dt = floor / rho itself is kept)
        why = (
            "shorter than the finest interval the stick detector certifies" if detect == "bridge"
            else "too short for float64 (its change of the state keeps under half the digits)"
        )  # fmt: skip
        raise ParameterError(
            owner,
            "dt",
            f"is too fine: {where}; a step below {floor:.2g} / rho(A) is {why}; "
            f"take dt >= {_round_up(floor / rho):.3g}",
            dt,
        )
    if detect == "bridge" and dt * rho > SCALE_WARN:
        located = dt / 2.0**bridge.MAX_DEPTH
        warnings.warn(
            f"{owner}: {where}: the stick is located only to within dt / 2**{bridge.MAX_DEPTH}"
            f" = {located:.2g}, {located / scale:.2g} times that scale, and slip times are "
            f"biased by up to that much; take dt <= {SCALE_WARN / rho:.3g}",
            stacklevel=5,
        )


@dataclasses.dataclass(frozen=True)
class _Config:
    """The static (compile-time) description of a run."""

    solver: str
    monitor: str
    smooth: bool
    detect: str  # the in-step test: "grid", "cubic", "brownian", "bridge" or "none"


@_compile.quick
@eqx.filter_jit
def _linear_gaussian(model):
    return _lg_arrays(model.linear_gaussian())


def _lg_arrays(lg: LinearGaussian | None):
    return None if lg is None else tuple(getattr(lg, f) for f in _LG_FIELDS)


def _traces_nothing(fn, model=None) -> bool:
    """Whether `fn()` computes without a JAX operation (in NumPy, or constants): then it
    needs no compiling. With `model` (whose method `fn` is), the answer is kept per model
    structure (`_model_check`'s key: not its float values), as a fit's every point asked it
    again (2 ms of tracing). A kept answer can only cost time, never change a number: a
    JAX computation run op by op, or a NumPy one compiled."""
    key = None
    if model is not None:
        try:
            key = structure_key(model)
        except Exception:  # (the model's own checks say why)
            key = None
        if key in _NOTHING_TRACED:
            return _NOTHING_TRACED[key]
    try:
        nothing = not jax.make_jaxpr(fn)().eqns
    except Exception:  # (the compiled call meets it again, and raises)
        return False
    if key is not None:
        if len(_NOTHING_TRACED) > 256:
            _NOTHING_TRACED.clear()
        _NOTHING_TRACED[key] = nothing
    return nothing


_NOTHING_TRACED: dict = {}  # `_traces_nothing`'s answers by model structure


_LG_FIELDS = tuple(f.name for f in dataclasses.fields(LinearGaussian))


def _make_solver(lg, cfg: _Config, dt: float, nodes: int, owner: str = "simulate"):
    """The run's slip solver, its tables computed in NumPy (nothing to compile). `nodes` are
    the interpolation nodes of the exact solver's dense output."""
    if cfg.solver != "exact":
        return EulerMaruyama()
    arrays = tuple(np.asarray(x, dtype=np.float64) for x in (lg.A, lg.b, lg.B, lg.crossing))
    key = tuple((x.shape, x.tobytes()) for x in arrays)
    solver = _exact_solver(key, cfg.detect == "bridge", float(dt), nodes)
    if solver is None:
        raise ParameterError(
            owner,
            "model",
            f"gives covariances of the exact step at dt = {dt:g} that float64 cannot factor "
            "(a noise variance below its range): state the model in units where its length "
            "and time scales are near 1 (stickslip.Slider does so for SI units), or take "
            "solver='euler'",
        )
    return solver


@functools.lru_cache(maxsize=32)
def _exact_solver(key, bridged: bool, dt: float, nodes: int):
    """`_make_solver`'s exact solver, kept for the runs that repeat a model and a step (its
    tables took ~4 ms of a 0.2 s run of 1e5 paths; the solver is immutable). None where the
    step's covariances cannot be factored: a model in extreme units, whose noise variance over
    (part of) a step falls below float64's normal range (D = 1e-300 with x0 = 1e-100: 1e-323,
    and correlations past 1)."""
    A, b, B, crossing = (np.frombuffer(data).reshape(shape) for shape, data in key)
    with np.errstate(all="ignore"):
        try:
            tables = bridge.bridge_tables(A, b, B, crossing, dt, host=True) if bridged else None
            solver = ExactGaussian(A, b, B, dt, nodes=nodes, bridge=tables, host=True)
        except np.linalg.LinAlgError:
            return None
    leaves = jax.tree_util.tree_leaves(solver)
    return solver if all(np.all(np.isfinite(x)) for x in leaves if np.ndim(x)) else None


def _detector(lg, solver: str, monitor: str, smooth: bool) -> str:
    """The in-step stick test of a run (static): exact in law (`"bridge"`) wherever the slip
    is linear-Gaussian with noise reaching the differentiable crossing variable."""
    if monitor == "grid":
        return "grid"
    if not smooth:
        return "brownian"
    if solver == "exact":
        # Noise reaches c.X over any step iff c A^k B != 0 for some k < d (the crossing
        # variable's variance c Sigma(dt) c > 0; this test needs no propagators, 0.7 ms).
        A, B = np.asarray(lg.A, dtype=float), np.asarray(lg.B, dtype=float)
        row = np.asarray(lg.crossing, dtype=float)
        for _ in range(A.shape[0]):
            if np.any(row @ B != 0.0):
                return "bridge"
            row = row @ A
    return "cubic"  # noise-free (exact flow) or Euler-Maruyama


@_compile.quick
@eqx.filter_jit
def _onset(model, smooth: bool, key, path, counter, stick_state):
    """Per-path helpers, one program (each program is a compilation on a fresh machine):
    the onset states `X` of the paths' cycle `counter`, their positions and, for a smooth
    crossing variable, its rate there; and the stick times from `stick_state` to the
    release at `X` (the next cycle's onset) with the positions of `stick_state`. The
    first call of a run has no stick states yet: what it computes from them is unused."""
    X, position, rate = onset_states(model, smooth, _rng.path_keys(key, path, counter))
    T_st = over_paths(model.stick_duration)(stick_state, X)
    return X, position, rate, T_st, over_paths(model.position)(stick_state)


@eqx.filter_jit
def _release(model, key, path, counter, stick_state):
    """A model with memory (`FrictionModel.carries_state`): the stick times from
    `stick_state` and the onset states of the paths' cycle `counter` that the stick leads
    to (`FrictionModel.release`, keyed as `onset_state` would be), with the positions of
    `stick_state`."""
    keys = _rng.path_keys(key, path, counter)
    T_st, X = jax.vmap(model.release, in_axes=(0, -1), out_axes=(0, -1))(keys, stick_state)
    return X, T_st, over_paths(model.position)(stick_state)


@eqx.filter_jit
def _at_onset(model, smooth: bool, X):
    """Positions and, for a smooth crossing variable, its rate at given onset states `X`
    (the slips of a model with memory start where the last stick led)."""
    position = over_paths(model.position)(X)
    rate = over_paths(model.crossing_rate)(X) if smooth else jnp.zeros_like(position)
    return position, rate


@eqx.filter_jit
def _advance(
    model, solver, cfg, slots, X, X_prev, k_stick, miss, path, offset, horizon, dt, step_key,
    bridge_key, stop_at, tol,
):  # fmt: skip
    """Run the buffer, each path from its own global step `offset`, until at most `stop_at`
    paths slip (the solve heads for a far horizon and the event ends it; a path expires at
    global step `horizon`). Returns the new buffer and the number of steps taken, and with
    `slots > 0` (static) the record of the candidate steps stepped past
    (`SteppingPastHybrid`)."""

    def stop(t, y, args, **kwargs):
        mode = y[1][1]
        return jnp.sum((mode == SLIPPING) | (mode == PASSED)) <= stop_at

    record, wrapper = (), StickSlipHybrid
    if slots:
        n, shape = k_stick.shape[0], (slots,) + k_stick.shape
        record = (
            jnp.zeros(n, jnp.int32), jnp.zeros(shape), jnp.zeros(shape),
            jnp.zeros((slots,) + X.shape), jnp.zeros((slots,) + X.shape),
        )  # fmt: skip
        wrapper = functools.partial(SteppingPastHybrid, slots=slots)
    sol = solve(
        model, solver, cfg, (X, (X_prev, k_stick, miss, *record)), path, dt,
        (step_key, bridge_key), offset, t1=HORIZON, saveat=diffrax.SaveAt(t1=True),
        event=diffrax.Event(stop), wrapper=wrapper, horizon=horizon, tol=tol,
    )  # fmt: skip
    X, (X_prev, k_stick, miss, *record) = sol.ys
    return (X[0], X_prev[0], k_stick[0], miss[0], sol.ts[0]) + tuple(r[0] for r in record)


@_compile.quick
@eqx.filter_jit
def _locate(model, solver, cfg, X_prev, X, k_stick, path, dt, z_key, u_key):
    """Locate each stick inside the step (from X_prev to X) in which it happened."""
    step = jnp.maximum(k_stick, 0.0).astype(jnp.uint32)
    z = _rng.normals(z_key, path, step, 1)[0]
    u = _rng.uniforms(u_key, path, step, 1)[0]
    return localise.locate(
        model, solver, X_prev, X, dt, smooth=cfg.smooth, monitor=cfg.monitor, z=z, u=u
    )


_ARRAYS = (np.ndarray, np.generic, jax.Array)


def _repack(a, keep, pad, value):
    """The columns `keep` of `a`, followed by `pad` columns of `value` (gathered straight
    into the new array: one copy)."""
    out = np.empty(a.shape[:-1] + (keep.size + pad,), a.dtype)
    np.take(a, keep, axis=-1, out=out[..., : keep.size], mode="clip")
    out[..., keep.size :] = value
    return out


def _cols(a, idx):
    """`a[..., idx]` for an index array or a slice `idx` (`np.take`: 5x faster than fancy
    indexing of the columns of a `(d, n)` state)."""
    return a[..., idx] if isinstance(idx, slice) else np.take(a, idx, axis=-1)


def _set_cols(a, idx, values):
    """`a[:, idx] = values` for a `(d, n)` state, row by row (1.3x faster)."""
    for row, v in zip(a, values, strict=True):
        row[idx] = v


def check_exact_step(owner: str, lg, dt: float, *, monitor: str, smooth: bool) -> None:
    """Refuse, before a run starts, a step `dt` that the exact solver cannot follow for the
    linear-Gaussian form `lg` (far past the slip's time scale, or too fine for float64), as
    `simulate` would refuse it; the step's tables it builds are kept for the run."""
    detect = _detector(lg, "exact", monitor, smooth)
    config = _Config(solver="exact", monitor=monitor, smooth=smooth, detect=detect)
    _check_time_scales(owner, lg, dt, detect)
    _make_solver(lg, config, dt, _LOOP_NODES, owner)


def next_pow2(n: int) -> int:
    return 1 << max(0, (int(n) - 1).bit_length())


def _buffer_size(n: int) -> int:
    """The smallest buffer size (see `FINE_BUFFER`) that holds `n` paths."""
    size = max(MIN_BUFFER, next_pow2(n))
    if size < FINE_BUFFER:
        size = MIN_BUFFER
        while size < n:
            size *= 8
    return size


def _padded_size(n: int) -> int:
    """The size that per-path helper calls (onset states, stick times) of `n` paths run on:
    the buffer size that holds them (up to a chunk; above it, whole chunks), so that runs of
    any number of paths share the executables of a few sizes (each new size was a
    compilation of ~0.3 s on a cold cache, or a load from disk)."""
    return _buffer_size(n) if n <= DEFAULT_CHUNK else -(-n // DEFAULT_CHUNK) * DEFAULT_CHUNK


def _pad_paths(x, size: int):
    """`x` with its last axis (paths) padded to `size` by repeating its first path."""
    n = x.shape[-1]
    if n == size:
        return x
    if n == 0:
        return np.zeros(x.shape[:-1] + (size,), x.dtype)
    return np.concatenate([x, np.repeat(x[..., :1], size - n, axis=-1)], axis=-1)


def stand_in(shape, dtype=np.float64):
    """A read-only array of zeros of this shape (no memory: a stand-in argument whose shape
    and dtype are all a compiled call's key looks at)."""
    return np.broadcast_to(np.zeros((), dtype), shape)


def _stand_in_size(ready, want: int, most: int, smaller: bool = False, ladder=None):
    """The size that stands in for `want` (`_compile.STAND_IN`) among those for which
    `ready(size)` is true: the smallest above it, up to `STAND_IN` times it or `most`
    (padded); with `smaller`, else the largest down to `1 / STAND_IN` of it (in more calls);
    `None` if none. `ladder`: the caller's sizes, as the functions `(larger, smaller)` of
    a size (default: the buffer sizes, `_larger_buffer` and `_smaller_buffer`)."""
    larger, lower = ladder or (_larger_buffer, _smaller_buffer)
    size, top = want, min(_compile.STAND_IN * want, most)
    while size < top:
        size = min(larger(size), top)
        if ready(size):
            return size
    size = lower(want) if smaller else 0
    while size and size * _compile.STAND_IN >= want:
        if ready(size):
            return size
        size = lower(size)
    return None


def _larger_buffer(size: int) -> int:
    """The next buffer size above `size` (see `_smaller_buffer`)."""
    return size * 2 if size >= FINE_BUFFER else size * 8


def _smaller_buffer(size: int) -> int:
    """The next buffer size below `size` (0 below the smallest)."""
    if size <= MIN_BUFFER:
        return 0
    return size // 2 if size > FINE_BUFFER else max(MIN_BUFFER, size // 8)


def _nodes_for(A, dt: float, warn: bool) -> int:
    A = np.asarray(A, dtype=float)
    rho = float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0
    m = max(2, math.ceil(dt * rho / _NODE_SCALE))
    if m > _MAX_NODES and warn:
        err = (dt * rho / _MAX_NODES) ** 4 / 384
        warnings.warn(
            f"dt = {dt} is {dt * rho:.3g} times the model's fastest time scale: the stick is "
            f"located on {_MAX_NODES} interpolation pieces per step, to a relative error of "
            f"about {err:.1e} (take dt <= {_MAX_NODES * _NODE_SCALE / rho:.3g} for 1e-10)",
            stacklevel=4,
        )
    return min(_MAX_NODES, next_pow2(m))


def _scheduler(owner: str, scheduler: str, detect: str) -> str:
    """The scheduler a run takes (`simulate`'s `scheduler`): `"device"` runs the bridge
    detector only; `"auto"` takes it on an accelerator (on a CPU the host one is faster)."""
    if scheduler == "device" and detect != "bridge":
        raise ParameterError(
            owner, "scheduler", f"'device' runs the exact bridge detector only; this run "
            f"uses the {detect!r} detector (take solver 'exact', monitor 'continuous')", scheduler,
        )  # fmt: skip
    if scheduler == "auto":
        return "device" if detect == "bridge" and jax.default_backend() != "cpu" else "host"
    return scheduler


def validate_args(owner, model, n_paths, dt, t_max, seed, solver, monitor, chunk_size):  # noqa: C901
    """Check the arguments of `owner` (`simulate` or `simulate_cycles`); one-line errors."""
    if not isinstance(model, FrictionModel):
        raise TypeError(f"{owner}: model must be a stickslip.FrictionModel instance, got {model!r}")
    from .._model import ChainModel

    if isinstance(model, ChainModel):
        raise ParameterError(
            owner, "model", "is a chain of blocks: simulate it with stickslip.simulate_chain"
        )
    check_shapes(owner, model)
    n_paths = check_int(owner, "n_paths", n_paths, minimum=1)
    dt = check_positive(owner, "dt", dt)
    t_max = check_positive(owner, "t_max", t_max)
    if t_max < dt:
        raise ParameterError(owner, "t_max", f"must be >= dt = {dt}", t_max)
    if t_max / dt >= 2**30:
        raise ParameterError(owner, "t_max", "/ dt must be below 2**30 steps", t_max)
    seed = check_int(owner, "seed", seed, minimum=0)
    if seed >= 2**64:
        raise ParameterError(owner, "seed", "must be < 2**64", seed)
    check_choice(owner, "solver", solver, ("auto", "exact", "euler"))
    check_choice(owner, "monitor", monitor, ("continuous", "grid"))
    chunk_size = check_int(owner, "chunk_size", chunk_size, minimum=1)
    _compile.policy()  # (a bad STICKSLIP_COMPILE is said before anything runs)
    if n_paths >= 2**32:
        raise ParameterError(owner, "n_paths", "must be < 2**32", n_paths)
    return n_paths, dt, t_max, seed, chunk_size


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
        _simulate_bytes(n_paths, len(model.state_names), record_upcrossings, chunk_size),
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
    run = HostRun(
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
        if _traces_nothing(self.model.linear_gaussian, self.model):
            lg = _lg_arrays(self.model.linear_gaussian())
        else:
            lg = self.call(_linear_gaussian, self.model, paths=0)
        if lg is not None:
            lg = LinearGaussian(**{f: np.asarray(x) for f, x in zip(_LG_FIELDS, lg, strict=True)})
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
        detect = _detector(lg, solver, monitor, smooth)
        self.cfg = _Config(
            solver=solver,
            monitor=monitor,
            smooth=smooth,
            detect=detect,
        )
        # Interpolation nodes of the in-step location (`_locate`; the exact solver's only
        # dt-dependent static). The stepping loop never interpolates: its solver has a fixed
        # count, so one compiled loop serves every dt.
        if solver == "exact" and check_dt:
            _check_time_scales(owner, lg, dt, detect)
        self.nodes = 1
        if solver == "exact":
            self.nodes = _nodes_for(lg.A, dt, detect == "cubic" and check_dt)
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
        self.solver = _make_solver(lg, self.cfg, dt, _LOOP_NODES, owner)
        self.locator = self.solver
        if solver == "exact" and detect != "bridge":
            self.locator = _make_solver(lg, self.cfg, dt, self.nodes, owner)
        # The stepping loop, its model and solver flattened once for all its calls.
        self.advance = _compile.Fixed(
            _advance, self.slip, self.solver, self.cfg, 0, timer=self.timer
        )
        self.onset = _compile.Fixed(_onset, self.model, smooth, timer=self.timer)
        # Small buffers of the bridge detector (`_chunk`): the loop that steps past candidates.
        self.advance_past = _compile.Fixed(
            _advance, self.slip, self.solver, self.cfg, PAST_SLOTS, timer=self.timer
        )
        self.stats.update(path_steps=0, buffers=0)
        if detect == "bridge":
            self.stats.update(candidates=0, refined_nodes=0, unresolved=0)
        self.miss = None  # per-path miss bounds of the stepping of the last `first_passages`
        self.onset_positions = None  # and the positions at onset
        self.refined_miss = 0.0  # the summed miss bounds of every exact refinement
        self._refiner = None  # the exact refinement (compiled), made on first use
        self._locate = None  # the in-step location (`_locate_chunk`), made on first use
        self.scheduler = _scheduler(owner, scheduler, detect)
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
            size = _buffer_size(min(paths.size, chunk_size))
            chunk = functools.partial(device.first_passages, self, size)
        else:
            n = min(paths.size, chunk_size)
            want, chunk_size = _buffer_size(n), self._chunk_length(n)
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
            size = _buffer_size(rows.size)
            X, p = _pad_paths(X0[:, rows], size), _pad_paths(paths[rows], size)
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
        """`_onset` for the paths `paths` (and their stick states, if given), on the padded
        size (`_onset_size`; with `exact`, on `paths.size`: a chunk's buffer), as the device
        arrays of the call."""
        size = paths.size if exact else self._onset_size(paths.size)
        if stick_state is None:
            stick = np.zeros((len(self.model.state_names), size))
        else:
            stick = _pad_paths(np.asarray(stick_state, dtype=np.float64), size)
        return self._counted(
            self.onset(
                self.keys["onset"], _pad_paths(paths, size), np.uint32(counter), stick, paths=size
            )
        )

    def _released(self, paths, counter, stick_state):
        """`_release` for the paths `paths` from their stick states (a model with memory);
        the paths that never stuck (`nan` states) give `nan`."""
        size = self._onset_size(paths.size)
        stick = _pad_paths(np.nan_to_num(np.asarray(stick_state, dtype=np.float64)), size)
        X1, T_st, x_sl = self.call(
            _release, self.model, self.keys["onset"], _pad_paths(paths, size),
            np.asarray(counter, dtype=np.uint32), stick, paths=size,
        )  # fmt: skip
        lost = ~np.all(np.isfinite(np.asarray(stick_state)), axis=0)
        X1, T_st, x_sl = (np.array(a)[..., : paths.size] for a in (X1, T_st, x_sl))
        X1[:, lost], T_st[lost], x_sl[lost] = np.nan, np.nan, np.nan
        return X1, T_st, x_sl

    def _onset_size(self, n: int) -> int:
        """The size an onset call of `n` paths runs on (`_padded_size`, or a larger compiled
        one, `_size_at_hand`): the draws are keyed by path, the padding is discarded."""
        size = _padded_size(n)
        if size > DEFAULT_CHUNK:
            return size
        return self._size_at_hand(self.onset, self._onset_specimen, size, DEFAULT_CHUNK)

    def _onset_specimen(self, size: int):
        """Stand-ins for `_onset`'s arguments after its fixed ones, for `size` paths."""
        d = len(self.model.state_names)
        return self.keys["onset"], stand_in(size, np.uint32), np.uint32(0), stand_in((d, size))

    def _size_at_hand(
        self, fixed, specimen, want: int, most: int, smaller: bool = False, ladder=None
    ):
        """The size that a call of `fixed` (a `_compile.Fixed`) on `want` paths runs on:
        `want` where it is compiled (in memory or on disk) or under the `"eager"` policy,
        else a compiled one that stands in (`_stand_in_size`, on `ladder`; with `smaller`,
        the caller makes several calls of a smaller one), else `want` (compiled at the
        call). `specimen(size)`: the call's arguments after the fixed ones, for `size`
        paths."""
        ready = lambda m: fixed.ready(*specimen(m), paths=m)  # noqa: E731
        if _compile.policy() == "eager" or ready(want):
            return want
        return _stand_in_size(ready, want, most, smaller, ladder) or want

    def _chunk_onsets(self, path, count: int, size: int, onsets):
        """A chunk's onset states (on the device, and read here), their crossing variable,
        which paths stick at once, and the paths' first modes (padding inactive)."""
        # On the device for the calls below (a NumPy argument is copied at every call: the
        # states twice, ~2.5 ms at 131072 paths); read here through a zero-copy view.
        if onsets is None:
            X0_dev, x_start, rate = self._onset_states(path, exact=True)[:3]
        else:
            X0_dev = _pad_paths(onsets, size)
            x_start, rate = self.call(_at_onset, self.model, self.cfg.smooth, X0_dev, paths=size)
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
        want = _buffer_size(count)
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
            args = self._loop_args(
                X_dev, X_prev_dev, ks, miss_dev, p, offset, _smaller_buffer(want)
            )
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
            if alive.size and want > MIN_BUFFER and alive.size <= _smaller_buffer(want):
                want = _buffer_size(alive.size)
                new_size, past = self._stand_in(want, size, past)
                if new_size == size:
                    continue
                # Re-pack the survivors into a smaller buffer: finished paths cost nothing.
                size = new_size
                pad = size - alive.size
                # Every path left slips, and the loop's first step sets a slipping path's
                # `X_prev` (the start of its last step) before anything reads it: the repacked
                # states serve as both (one repack and one copy into the call fewer).
                X = X_prev = _repack(X, alive, pad, 0.0)
                ks = _repack(ks, alive, pad, INACTIVE)
                p, slot = _repack(p, alive, pad, 0), _repack(slot, alive, pad, -1)
                offset, miss = _repack(offset, alive, pad, 0.0), _repack(miss, alive, pad, 0.0)
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
                ends = _cols(Xa, i), _cols(Xb, i)
                pending.append((slot[i], step[i], miss_at[i], p[i], *ends))
        cand = np.nonzero(real & (ks >= 0))[0]
        below = self.crossing @ _cols(X, cand) < self.model_level
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
        _set_cols(stick_state, rows, _cols(state, f))
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
        in (`_stand_in_size`: a larger buffer, padded, or a smaller one, in more chunks);
        `None` if none."""
        spec = self._speculates(want)
        if self._loop(spec).ready(*self._loop_specimen(want), paths=want):
            return want, spec
        if _compile.policy() == "eager" or not _compile.STAND_IN:
            return None
        ready = lambda m: self._ready(m) is not None  # noqa: E731
        size = want if ready(want) else _stand_in_size(ready, want, 1 << 62, smaller=True)
        return None if size is None else (size, self._ready(size))

    def _chunk_length(self, n: int) -> int:
        """Paths per chunk for chunks of up to `n` paths: `n`, or the size of a smaller
        compiled buffer where that is the one at hand (`_at_hand`) and the wanted one is not
        to be compiled here (`_compile_here`): more chunks on a compiled loop, the same
        numbers (each path's are keyed by its index)."""
        want = _buffer_size(n)
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
        want = _buffer_size(count)
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
            candidate = _larger_buffer(candidate)
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
        Xa, Xb = _cols(Xa, order), _cols(Xb, order)
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
        _set_cols(stick_state, rows[stick], _cols(state, stick))
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
            _cols(X_prev, cand), _cols(X, cand), p[cand], ks[cand].astype(np.uint32)
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
            self._locate = _compile.Fixed(_locate, model, self.locator, cfg, timer=self.timer)
        d = len(model.state_names)
        batch = self._size_at_hand(
            self._locate,
            lambda m: (stand_in((d, m)), stand_in((d, m)), stand_in(m), stand_in(m, np.uint32),
                       self.dt_arr, keys["z"], keys["u"]),
            min(LOCATE_BATCH, _buffer_size(max(done.size, 1))), LOCATE_BATCH, smaller=True,
        )  # fmt: skip
        for start in range(0, done.size, batch):
            rows = done[start : start + batch]
            rows_padded = _pad_paths(rows, batch)
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
