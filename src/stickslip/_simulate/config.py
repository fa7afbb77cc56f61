"""A run's configuration, checked: its arguments, the slip solver and the in-step stick
detector, the scheduler, the limits of the step, the memory a run needs."""

from __future__ import annotations

import dataclasses
import functools
import math
import warnings

import equinox as eqx
import numpy as np

from .. import _compile
from .._errors import ParameterError, check_choice, check_int, check_positive
from .._jax import jax
from .._model import FrictionModel, LinearGaussian
from .._model_check import check_shapes, structure_key
from .._solver import EulerMaruyama, ExactGaussian
from . import bridge
from .buffers import buffer_size, next_pow2

DEFAULT_CROSSING_TOL = 1e-5  # bound on the chance of a missed crossing per certified step


# Interpolation sub-steps of the exact solver: chosen so that h_sub * rho(A) <= this, where
# the cubic pieces' relative error (h_sub rho)^4 / 384 stays below 1e-10.
NODE_SCALE = 0.0125


MAX_NODES = 256


LOOP_NODES = 2  # the stepping loop's solver: it never interpolates (see `host.HostRun`)


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


def simulate_bytes(n_paths: int, d: int, upcrossings: int, chunk_size: int) -> float:
    """Peak memory of `simulate` (bytes, an estimate from above): per path the outputs (seven
    per-path arrays, three states, the upcrossing record) held twice (blocks, then the joined
    result), the per-path work arrays and the onset and stick states; per chunk the stepping
    buffer (states, previous states, modes, counters, offsets, miss bounds, the device's
    copies)."""
    per_path = 8 * (2 * (6 + 3 * d + 2 * upcrossings + 2) + 10 + 3 * d)
    buffer = buffer_size(min(n_paths, chunk_size)) * 8 * 4 * (2 * d + 6)
    return float(n_paths) * per_path + buffer


def check_time_scales(owner: str, lg, dt: float, detect: str) -> None:
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
class Config:
    """The static (compile-time) description of a run."""

    solver: str
    monitor: str
    smooth: bool
    detect: str  # the in-step test: "grid", "cubic", "brownian", "bridge" or "none"


@_compile.quick
@eqx.filter_jit
def linear_gaussian(model):
    return lg_arrays(model.linear_gaussian())


def lg_arrays(lg: LinearGaussian | None):
    return None if lg is None else tuple(getattr(lg, f) for f in LG_FIELDS)


def traces_nothing(fn, model=None) -> bool:
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


_NOTHING_TRACED: dict = {}  # `traces_nothing`'s answers by model structure


LG_FIELDS = tuple(f.name for f in dataclasses.fields(LinearGaussian))


def make_solver(lg, cfg: Config, dt: float, nodes: int, owner: str = "simulate"):
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
    """`make_solver`'s exact solver, kept for the runs that repeat a model and a step (its
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


def detector(lg, solver: str, monitor: str, smooth: bool) -> str:
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


def check_exact_step(owner: str, lg, dt: float, *, monitor: str, smooth: bool) -> None:
    """Refuse, before a run starts, a step `dt` that the exact solver cannot follow for the
    linear-Gaussian form `lg` (far past the slip's time scale, or too fine for float64), as
    `simulate` would refuse it; the step's tables it builds are kept for the run."""
    detect = detector(lg, "exact", monitor, smooth)
    config = Config(solver="exact", monitor=monitor, smooth=smooth, detect=detect)
    check_time_scales(owner, lg, dt, detect)
    make_solver(lg, config, dt, LOOP_NODES, owner)


def nodes_for(A, dt: float, warn: bool) -> int:
    A = np.asarray(A, dtype=float)
    rho = float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0
    m = max(2, math.ceil(dt * rho / NODE_SCALE))
    if m > MAX_NODES and warn:
        err = (dt * rho / MAX_NODES) ** 4 / 384
        warnings.warn(
            f"dt = {dt} is {dt * rho:.3g} times the model's fastest time scale: the stick is "
            f"located on {MAX_NODES} interpolation pieces per step, to a relative error of "
            f"about {err:.1e} (take dt <= {MAX_NODES * NODE_SCALE / rho:.3g} for 1e-10)",
            stacklevel=4,
        )
    return min(MAX_NODES, next_pow2(m))


def choose_scheduler(owner: str, scheduler: str, detect: str) -> str:
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
