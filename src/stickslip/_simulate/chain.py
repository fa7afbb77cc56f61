"""Chains of blocks that stick and slip one by one (Burridge-Knopoff): per-block events in
a diffrax solve over the whole ensemble, run in segments whose events are streamed out.

Every block obeys, with unit mass, absolute position `u_i` and the driver at `v_b t`,
$$\\dot V_i = f_i - c_i F(V_i) + \\eta_i, \\qquad
f_i = k_c (u_{i+1} - 2 u_i + u_{i-1}) + k_p (v_b t - u_i),$$
while it slips (`V_i > 0`); a stuck block has `V_i = 0` and holds any force up to its
static limit $c_i F_s$. $c_i = 1$, or with a random threshold the block's contact strength,
drawn afresh each time the block sticks: it scales the whole law (static limit and kinetic
curve alike), so the drop at onset stays the fraction $1 - F(0^+)/F_s$ of the limit and a
released block always moves (docs/models.md). The step (fixed `dt`):

1. slipping blocks advance by Euler-Maruyama in V (the OU noise exactly), the position by
   the trapezoid rule; a block whose V falls to 0 inside the step sticks at the linearly
   interpolated time (the step's own interpolant), having moved the area under its
   velocity up to then, and draws its next strength;
2. release: a stuck block whose force at the end of the step exceeds its static limit
   released inside the step, where its force (linear in the step) reached the limit; it
   then slips for the rest of the step from V = 0 with the acceleration $f_i - c_i F(0^+)$
   (positive: $F(0^+) \\le F_s$ for every law) and its OU noise restarts at 0 (as
   `langevin`'s `eta0="zero"`).

White friction noise (`tau = None` with `D > 0`) is refused: a released block would re-stick
at once with a probability that tends to 1/2 as dt shrinks (the single block's degeneracy).

An event is a contiguous slipping episode of the chain: from the first release with every
block stuck to the moment every block is stuck again. Its size is the number of distinct
blocks that slipped, its slip the sum of their displacements (Carlson and Langer's moment).

The run is a sequence of segments of `SEGMENT` steps, each one solve of fixed size: the
events, quiet times, releases and time series of a segment are handed to the host and
appended, so memory does not grow with `t_max` beyond the events themselves. A segment's
time-series buffer holds its samples rounded up to a few sizes (`_series_slots`), so a new
`t_max` or `record_dt` compiles nothing unless its spacing in steps moves to another size.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import sys
import warnings
from typing import Any

import diffrax
import equinox as eqx
import numpy as np

from .. import _compile, _rng
from .._errors import ParameterError, check_int, check_positive
from .._jax import jax, jnp
from .._memory import check_memory
from .._model import ChainModel, to_arrays


@dataclasses.dataclass(frozen=True, eq=False)
class ChainRun:
    """A simulated chain: events and time series, per path.

    - `start`, `duration`, `size`, `slip`: lists (one array per path) of the events;
      `n_events`: events per path (more than kept when `max_events` is given);
    - `t`: recording times; `mean_velocity`, `slipping`, `mean_force` `(n_paths, len(t))`:
      the chain's mean sliding velocity, the fraction of blocks slipping and the mean
      loading force at those times; `velocity` `(n_paths, len(t), N)` if recorded;
    - `quiet_times`: per path, the times the mean sliding velocity fell to `event_level`
      (the crossing variable's upcrossings; the ends of events when the level is 0);
    - `releases` (with `record_releases`): per path, an array `(n, 3)` of every block
      release: its time, the block's index and the static limit it overcame (drawn when the
      block last stuck).
    """

    start: list
    duration: list
    size: list
    slip: list
    n_events: np.ndarray
    t: np.ndarray
    mean_velocity: np.ndarray
    slipping: np.ndarray
    mean_force: np.ndarray
    velocity: np.ndarray | None
    quiet_times: list
    releases: list | None
    n_blocks: int
    t_max: float
    dt: float
    info: dict

    def events(self, name: str) -> np.ndarray:
        """One event quantity (`"size"`, `"duration"`, `"slip"`, `"start"` or `"interval"`,
        the time from one event's start to the next) over every path."""
        if name == "interval":
            return np.concatenate([np.diff(s) for s in self.start]) if self.start else np.array([])
        if name not in ("size", "duration", "slip", "start"):
            raise ParameterError("ChainRun.events", "name", "unknown event quantity", name)
        return np.concatenate(getattr(self, name))

    def upcrossings(self, window: float, max_crossings: int = 16):
        """The crossing record of the empirical estimator: every event is a slip onset, and
        its upcrossings are the times (after its start, up to `window`) at which the chain
        fell quiet, this event's end and any later ones (the process runs on). Events whose
        window passes the end of the run are left out."""
        from .upcrossings import Upcrossings

        times, counts = [], []
        for starts, quiet in zip(self.start, self.quiet_times, strict=True):
            for s in starts[starts + window <= self.t_max]:
                q = quiet[(quiet > s) & (quiet <= s + window)] - s
                counts.append(q.size)
                row = np.full(max_crossings, np.nan)
                row[: min(q.size, max_crossings)] = q[:max_crossings]
                times.append(row)
        n = len(times)
        if n == 0:
            raise ParameterError("upcrossings", "window", "no event has a complete window", window)
        times = np.array(times)
        return Upcrossings(
            times=times, positions=np.zeros_like(times), count=np.array(counts),
            immediate=np.zeros(n, bool), onset_position=np.zeros(n), t_max=window, dt=self.dt,
        )  # fmt: skip


SEGMENT = 4096  # steps per solve; events per path per segment are at most SEGMENT / 2
RELEASES = 4 * SEGMENT  # block releases kept per path per segment (`record_releases`)


class _ChainStep(diffrax.AbstractSolver):
    """One step of every block of every path (see the module docstring). The solve's time
    counts the segment's steps, from `offset` (the global step of its first): global step k
    covers [k dt, (k + 1) dt]; the time series is recorded at the end of every `stride`-th
    step, into the slots of this segment from record `rec_lo` on."""

    model: Any
    noise_key: Any
    strength_key: Any
    dt: Any
    rec_lo: Any
    offset: Any
    stride: Any
    path0: Any  # the first path's index (a block of a distributed run starts past 0)
    n_paths: int = eqx.field(static=True)
    record_blocks: bool = eqx.field(static=True)
    record_releases: bool = eqx.field(static=True)

    term_structure = diffrax.AbstractTerm
    interpolation_cls = diffrax.LocalLinearInterpolation

    def order(self, terms):
        return 1

    def init(self, terms, t0, t1, y0, args):
        return None

    def func(self, terms, t0, y0, args):
        raise NotImplementedError

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        m = self.model
        P, N = self.n_paths, m.n_blocks
        h = self.dt
        k = jnp.round(t0) + self.offset  # global step index (whole numbers: exact)
        time0, time1 = k * h, (k + 1.0) * h
        y = dict(y0)
        # diffrax keeps the state floating-point: flags are 0/1, counters whole floats
        u, V, eta, strength = y["u"], y["V"], y["eta"], y["strength"]
        stuck = y["stuck"] > 0.5
        slipping = ~stuck
        counter = k.astype(jnp.uint32)
        paths = self.path0 + jnp.arange(P, dtype=jnp.uint32)
        ids = (paths[:, None] * N + jnp.arange(N, dtype=jnp.uint32)[None, :]).ravel()
        xi = _rng.normals(self.noise_key, ids, counter, 1)[0].reshape(P, N)
        limit = strength * m.friction.static_limit
        f0 = m.force(u, time0)
        # 1. slipping blocks: Heun's method in (u, V) with the OU noise exact at both ends
        #    of the step (its integral by the trapezoid rule), stick inside the step
        if m.tau is None:  # noise-free (white noise with D > 0 is refused)
            eta1 = eta
        else:
            a = jnp.exp(-h / m.tau)
            eta1 = eta * a + jnp.sqrt(m.D / m.tau * (1.0 - a * a)) * xi
        kinetic = lambda W: strength * m.friction.force(jnp.maximum(W, 0.0))
        accel0 = f0 - kinetic(V) + eta
        Vp = V + accel0 * h
        up = jnp.where(slipping, u + V * h, u)
        accel1 = m.force(up, time1) - kinetic(Vp) + eta1
        V1 = V + 0.5 * (accel0 + accel1) * h
        sticks = slipping & (V1 <= 0.0)
        theta = jnp.where(sticks, V / jnp.where(sticks, V - V1, 1.0), 1.0)
        u1 = jnp.where(slipping, u + jnp.where(sticks, 0.5 * theta * V, 0.5 * (V + Vp)) * h, u)
        V1 = jnp.where(slipping & ~sticks, V1, 0.0)
        # 2. release inside the step, where the (linear) force reached the limit
        f1 = m.force(u1, time1)
        release = stuck & (f1 > limit)
        rho = jnp.where(release, (limit - f0) / jnp.where(release, f1 - f0, 1.0), 0.0)
        rho = jnp.clip(rho, 0.0, 1.0)  # a force already above the limit releases at once
        rest = (1.0 - rho) * h
        onset = f1 - strength * m.friction.force(jnp.zeros_like(V))
        V_rel = onset * rest
        u1 = jnp.where(release, u + 0.5 * V_rel * rest, u1)
        V1 = jnp.where(release, V_rel, V1)
        eta1 = jnp.where(release, 0.0, eta1)
        stuck1 = (stuck & ~release) | sticks
        # the next strength of the blocks that stuck (drawn only in steps where one did)
        if m.threshold is not None:

            def draw(strength):
                keys = _rng.path_keys(self.strength_key, ids, counter)
                new = jax.vmap(m.threshold.sample)(keys).reshape(P, N)
                return jnp.where(sticks, new, strength)

            strength1 = jax.lax.cond(sticks.any(), draw, lambda s: s, strength)
        else:
            strength1 = strength
        # events
        active = y["active"] > 0.5
        begins = ~active & release.any(axis=1)
        t_rel = time0 + h * jnp.min(jnp.where(release, rho, 1.0), axis=1)
        ep_start = jnp.where(begins, t_rel, y["ep_start"])
        ep_u0 = jnp.where(begins, u.sum(axis=1), y["ep_u0"])
        ep_mask = jnp.where(begins[:, None], release, (y["ep_mask"] > 0.5) | release)
        active = active | begins
        ends = active & stuck1.all(axis=1)
        t_end = time0 + h * jnp.max(jnp.where(sticks, theta, 0.0), axis=1)
        record = jnp.stack(
            [ep_start, t_end - ep_start, ep_mask.sum(axis=1).astype(u.dtype),
             u1.sum(axis=1) - ep_u0],
            axis=1,
        )  # fmt: skip
        rows = jnp.arange(P)
        events, n_events = y["events"], y["n_events"]
        slot = jnp.where(ends, n_events, events.shape[1]).astype(jnp.int32)
        events = events.at[rows, slot].set(record, mode="drop")
        n_events = n_events + ends
        active = active & ~ends
        # the crossing variable: mean sliding velocity falling to the event level
        level = m.event_level
        if level == 0.0:
            quiet, t_quiet = ends, t_end
        else:
            Vm0, Vm1 = V.mean(axis=1), V1.mean(axis=1)
            quiet = (Vm0 > level) & (Vm1 <= level)
            t_quiet = time0 + h * (Vm0 - level) / jnp.where(quiet, Vm0 - Vm1, 1.0)
        qbuf, n_quiet = y["quiet"], y["n_quiet"]
        qslot = jnp.where(quiet, n_quiet, qbuf.shape[1]).astype(jnp.int32)
        qbuf = qbuf.at[rows, qslot].set(t_quiet, mode="drop")
        n_quiet = n_quiet + quiet
        y1 = dict(
            u=u1, V=V1, eta=eta1, stuck=stuck1.astype(u.dtype), strength=strength1,
            active=active.astype(u.dtype), ep_start=ep_start, ep_u0=ep_u0,
            ep_mask=ep_mask.astype(u.dtype), events=events, n_events=n_events,
            quiet=qbuf, n_quiet=n_quiet,
        )  # fmt: skip
        if self.record_releases:
            # each release: its time, block and the static limit it overcame (the strength
            # drawn at the block's previous stick)
            rel, n_rel = y["releases"], y["n_releases"]
            order = jnp.cumsum(release, axis=1) - 1 + n_rel[:, None]
            cap = rel.shape[1]
            where = jnp.where(release, order, cap).astype(jnp.int32)
            entry = jnp.stack(
                [time0 + h * rho, jnp.broadcast_to(jnp.arange(N, dtype=u.dtype), (P, N)), limit],
                axis=-1,
            )
            y1["releases"] = rel.at[rows[:, None], where].set(entry, mode="drop")
            y1["n_releases"] = n_rel + release.sum(axis=1)
        # time series, at the end of every `stride`-th step
        due = jnp.mod(k + 1.0, self.stride) == 0.0
        j = (jnp.round((k + 1.0) / self.stride) - self.rec_lo).astype(jnp.int32)
        series = y["series"]
        values = _series(m, time1, u1, V1, stuck1, self.record_blocks)
        size = next(iter(series.values())).shape[1]
        j = jnp.where(due & (j >= 0), j, size)
        y1["series"] = {
            name: series[name].at[:, j].set(values[name], mode="drop") for name in series
        }
        return y1, None, dict(y0=y0, y1=y1), None, diffrax.RESULTS.successful


def _series(model, t, u, V, stuck, record_blocks):
    out = dict(
        mean_velocity=V.mean(axis=1),
        slipping=(~stuck).mean(axis=1),
        mean_force=(model.k_p * (model.v_b * t - u)).mean(axis=1),
    )
    if record_blocks:
        out["velocity"] = V
    return out


# The order of the arguments before `simulate` set it for every simulation (model, n_paths,
# dt, t_max): read for one release, with a DeprecationWarning.
_OLD_ORDER = ("t_max", "dt", "n_paths", "seed", "record_dt", "record_blocks", "max_events",
              "record_releases", "progress", "client")  # fmt: skip
_OLD_DEFAULTS = {"dt": 0.01, "n_paths": 1}


def _is_count(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def _accepts_old_order(fn):
    """`simulate_chain` as it was called before it took `simulate`'s order: the call is read
    in the old order `(model, t_max, dt=0.01, n_paths=1, seed=0, ...)`, with a
    DeprecationWarning, when its first argument after the model cannot be a number of paths
    (not an integer), when `n_paths` is also given by name, or when `t_max` is given neither
    by position nor by name; or when, all by name, `n_paths` or `dt` is left out (they had
    defaults), or when the run's options come by position. A call whose first three
    arguments are integers is read in the new order."""

    @functools.wraps(fn)
    def simulate_chain(model, *args, **kwargs):
        old = bool(args) and (
            not _is_count(args[0])
            or "n_paths" in kwargs
            or (len(args) < 3 and "t_max" not in kwargs)
        )
        if not args and "t_max" in kwargs and not {"n_paths", "dt"} <= set(kwargs):
            old = True
        if len(args) > 4:  # the run's options were positional only in the old order
            old = True
        if old:
            if len(args) > len(_OLD_ORDER):
                raise TypeError(f"simulate_chain takes at most {len(_OLD_ORDER) + 1} arguments")
            named = dict(zip(_OLD_ORDER, args, strict=False))
            twice = sorted(set(named) & set(kwargs))
            if twice:
                raise TypeError(f"simulate_chain got multiple values for {twice[0]!r}")
            kwargs = {**_OLD_DEFAULTS, **named, **kwargs}
            warnings.warn(
                "simulate_chain(model, t_max, dt, n_paths) is deprecated: pass the arguments "
                "in simulate's order, simulate_chain(model, n_paths, dt, t_max), or by name "
                f"(read as n_paths={kwargs['n_paths']!r}, dt={kwargs['dt']!r}, "
                f"t_max={kwargs.get('t_max')!r})",
                DeprecationWarning,
                stacklevel=2,
            )
            args = ()
        return fn(model, *args, **kwargs)

    return simulate_chain


@_accepts_old_order
def simulate_chain(
    model: ChainModel,
    n_paths: int,
    dt: float,
    t_max: float,
    seed: int = 0,
    *,
    record_dt: float | None = None,
    record_blocks: bool = False,
    max_events: int | None = None,
    record_releases: bool = False,
    progress: bool | None = None,
    client=None,
) -> ChainRun:
    """Simulate `n_paths` independent chains for `t_max` time units, in steps of `dt`: the
    arguments in `simulate`'s order. (The order before, `simulate_chain(model, t_max, dt,
    n_paths)`, is still read, with a DeprecationWarning, for one release; a call whose
    first three arguments are integers is read in this order.)

    - `dt`: the time step; releases and sticks are located inside it (see the module
      docs); results converge as dt shrinks (tested);
    - `record_dt`: spacing of the time series (default: 1000 points over the run);
      `record_blocks` also keeps every block's velocity;
    - `max_events`: keep at most this many events per path (default: all; `n_events` counts
      them all). Events are streamed out segment by segment, not held in a buffer sized
      by `t_max`;
    - `record_releases`: also keep every block release (`ChainRun.releases`);
    - `progress`: a progress bar over the segments (default: on a terminal, for runs of
      over 10^9 block-steps; with a `client`, over the chains done across the cluster);
    - `client`: run the chains as tasks on a Dask cluster (as in `simulate`; identical
      numbers).

    Every chain starts relaxed: each block stuck at rest with its loading spring slack
    (and its strength drawn, with a random threshold); the driver then loads them. Results
    are a function of `(seed, path)`: a path's numbers do not depend on how many run
    together.
    """
    owner = "simulate_chain"
    if not isinstance(model, ChainModel):
        raise ParameterError(owner, "model", "must be a chain model (e.g. burridge-knopoff)")
    t_max = check_positive(owner, "t_max", t_max)
    dt = check_positive(owner, "dt", dt)
    n_paths = check_int(owner, "n_paths", n_paths, minimum=1)
    seed = check_int(owner, "seed", seed, minimum=0)
    if seed >= 2**64:
        raise ParameterError(owner, "seed", "must be < 2**64", seed)
    for name, flag in (("record_blocks", record_blocks), ("record_releases", record_releases)):
        if not isinstance(flag, (bool, np.bool_)):
            raise ParameterError(owner, name, "must be True or False", flag)
    if model.tau is None and model.D > 0:
        raise ParameterError(
            owner, "tau", "is None (white friction noise) with D > 0: a released block would "
            "re-stick at once with a probability that tends to 1/2 as dt shrinks, so results "
            "would depend on dt; give the noise a correlation time (tau > 0, OU noise)",
        )  # fmt: skip
    _check_step(model, dt)
    n_steps = int(math.ceil(t_max / dt - 1e-9))
    if n_steps >= 2**31:
        raise ParameterError(owner, "t_max", "/ dt must be below 2**31 steps", t_max)
    t_max = n_steps * dt
    record_dt = t_max / 1000 if record_dt is None else check_positive(owner, "record_dt", record_dt)
    if not record_dt / dt < 2**62:  # (a spacing in steps that an integer holds)
        raise ParameterError(
            owner, "record_dt", f"must be below 2**62 steps of dt = {dt}", record_dt
        )
    if max_events is not None:
        max_events = check_int(owner, "max_events", max_events, minimum=1)
    check_memory(
        owner,
        f"{n_paths} chains of {model.n_blocks} blocks",
        _chain_bytes(
            model.n_blocks, n_paths, n_steps, dt, record_dt, record_blocks, record_releases
        ),
        "run fewer chains at once (a chain's numbers do not depend on how many run together), "
        "or record less (record_dt, record_blocks, record_releases)",
    )
    if n_paths >= 2**32:  # the paths' counters
        raise ParameterError(owner, "n_paths", "must be < 2**32", n_paths)
    opts = dict(
        n_steps=n_steps, record_dt=record_dt, record_blocks=record_blocks,
        max_events=max_events, record_releases=record_releases,
    )  # fmt: skip
    if client is None:
        if progress is None:
            progress = sys.stderr.isatty() and n_steps * model.n_blocks * n_paths > 10**9
        return _chain_block(model, dt, seed, opts, 0, n_paths, progress=progress)
    from .. import _distributed

    with _distributed.connected(owner, client) as client:
        # chains are long: one task per path, or per equal block of paths past 4 per thread
        count = min(n_paths, _distributed.threads(client) * _distributed.BLOCKS_PER_THREAD)
        size = -(-n_paths // count)
        blocks = [(a, min(a + size, n_paths)) for a in range(0, n_paths, size)]
        parts = _distributed.run_blocks(
            client, _chain_block, blocks, model, dt, seed, opts, progress=progress, label="chain"
        )
    return _join_chains(parts)


def _series_slots(stride: int) -> int:
    """The slots of a segment's time-series buffer for samples every `stride` steps: the
    samples a segment can hold (`ceil(SEGMENT / stride)`, and the one at its start) rounded
    up to a power of two, or to a power of 8 where that is at most `SEGMENT / 8`. The
    buffer's shape is part of the compiled solve, so the slots come in a few sizes (7 for
    4096 steps a segment) rather than one per spacing: a new `t_max` (the default spacing is
    `t_max / 1000`) or `record_dt` compiles again only when it moves to another size.
    Rounding up costs little memory: at most twice the samples where the buffer is large,
    and where it is rounded to a power of 8 it stays below the events' buffers (three
    values per path and step of the segment)."""
    need = -(-SEGMENT // stride)
    size = 1
    while size < need:
        size *= 8 if 8 * size <= SEGMENT // 8 else 2
    return min(size, SEGMENT) + 1


def _chain_bytes(N, P, n_steps, dt, record_dt, record_blocks, record_releases) -> float:
    """Peak memory of `_chain_block` (bytes, an estimate from above): per chain the state
    (six arrays of N), a segment's buffers (events, quiet times, series samples, releases)
    three times over (the initial state, the solve's carry and its result), and the time
    series kept (the segments' parts, then joined)."""
    stride = max(1, int(round(record_dt / dt)))
    rec_cap = _series_slots(stride)
    width = 3 + (N if record_blocks else 0)
    segment = 6 * N + 4 * (SEGMENT // 2 + 1) + SEGMENT + rec_cap * width
    segment += 3 * RELEASES if record_releases else 0
    kept = 2 * (n_steps // stride + 1) * width
    return 8.0 * P * (3 * segment + kept)


def _chain_block(model, dt, seed, opts, start, stop, progress=False) -> ChainRun:
    """`simulate_chain` for the paths `start` .. `stop` - 1 (a task of a distributed run)."""
    n_steps, record_dt = opts["n_steps"], opts["record_dt"]
    record_blocks, record_releases = opts["record_blocks"], opts["record_releases"]
    max_events = opts["max_events"]
    t_max = n_steps * dt
    N, P = model.n_blocks, stop - start
    root = _rng.seed_key(seed)
    keys = {s: _rng.stream_key(root, s) for s in (_rng.STEP, _rng.ONSET, _rng.THRESHOLD)}
    strength = np.ones((P, N))
    if model.threshold is not None:
        ids = np.arange(start, stop)[:, None] * N + np.arange(N)[None, :]
        draw = _draw_strengths(model, keys[_rng.ONSET], ids.ravel())
        strength = np.asarray(draw).reshape(P, N)
    stride = max(1, int(round(record_dt / dt)))
    n_rec = n_steps // stride + 1
    zero = np.zeros((P, N))
    state = dict(
        u=zero, V=zero, eta=zero, stuck=np.ones((P, N)), strength=strength,
        active=np.zeros(P), ep_start=np.zeros(P), ep_u0=np.zeros(P), ep_mask=zero,
    )  # fmt: skip
    first_values = _series_host(model, zero, zero, record_blocks)
    series = {name: [v[:, None]] for name, v in first_values.items()}
    events, quiet, releases = [[] for _ in range(P)], [[] for _ in range(P)], [[] for _ in range(P)]
    counts = np.zeros(P, dtype=np.int64)
    n_quiet, n_rel = np.zeros(P, dtype=np.int64), np.zeros(P, dtype=np.int64)
    dropped = 0  # releases beyond a segment's buffer
    rec_cap = _series_slots(stride)
    solver_args = dict(
        model=to_arrays(model), noise_key=keys[_rng.STEP], strength_key=keys[_rng.THRESHOLD],
        dt=np.asarray(dt), stride=np.asarray(float(stride)), path0=np.uint32(start), n_paths=P,
        record_blocks=record_blocks, record_releases=record_releases,
    )  # fmt: skip
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=n_steps, desc="simulate_chain", unit="step", leave=False)
    try:
        for first in range(0, n_steps, SEGMENT):
            steps = min(SEGMENT, n_steps - first)
            # the series samples of this segment: the steps that end at a multiple of stride
            lo, hi = -(-(first + 1) // stride), (first + steps) // stride
            y0 = dict(state)
            y0.update(
                events=np.full((P, SEGMENT // 2 + 1, 4), np.nan), n_events=np.zeros(P),
                quiet=np.full((P, SEGMENT), np.nan), n_quiet=np.zeros(P),
                series={
                    name: np.zeros((P, rec_cap) + v.shape[1:]) for name, v in first_values.items()
                },
            )  # fmt: skip
            if record_releases:
                y0.update(releases=np.full((P, RELEASES, 3), np.nan), n_releases=np.zeros(P))
            out = _compile.call(
                _segment,
                _ChainStep(rec_lo=np.asarray(float(lo)), offset=np.asarray(float(first)),
                           **solver_args),
                y0, np.asarray(float(steps)), paths=0,
            )  # fmt: skip
            out = jax.tree.map(np.asarray, out)
            state = {name: out[name] for name in state}
            ne, nq = out["n_events"].astype(np.int64), out["n_quiet"].astype(np.int64)
            for p in range(P):
                keep = ne[p] if max_events is None else max(0, min(ne[p], max_events - counts[p]))
                events[p].append(out["events"][p, :keep])
                quiet[p].append(out["quiet"][p, : nq[p]])
            counts += ne
            n_quiet += nq
            if record_releases:
                nr = out["n_releases"].astype(np.int64)
                for p in range(P):
                    releases[p].append(out["releases"][p, : min(nr[p], RELEASES)])
                n_rel += nr
                dropped += int(np.sum(np.maximum(nr - RELEASES, 0)))
            for name in series:
                series[name].append(out["series"][name][:, : hi - lo + 1])
            if bar is not None:
                bar.update(steps)
    finally:
        if bar is not None:
            bar.close()
    ev = [np.concatenate(e) if e else np.zeros((0, 4)) for e in events]
    series = {name: np.concatenate(v, axis=1)[:, :n_rec] for name, v in series.items()}
    return ChainRun(
        start=[e[:, 0] for e in ev],
        duration=[e[:, 1] for e in ev],
        size=[e[:, 2].astype(int) for e in ev],
        slip=[e[:, 3] for e in ev],
        n_events=counts,
        t=np.arange(n_rec) * stride * dt,
        mean_velocity=series["mean_velocity"],
        slipping=series["slipping"],
        mean_force=series["mean_force"],
        velocity=series.get("velocity"),
        quiet_times=[np.concatenate(q) for q in quiet],
        releases=[np.concatenate(r) for r in releases] if record_releases else None,
        n_blocks=N,
        t_max=float(t_max),
        dt=float(dt),
        info=dict(
            n_steps=n_steps,
            seed=seed,
            segments=-(-n_steps // SEGMENT),
            **({"n_releases": n_rel, "releases_dropped": dropped} if record_releases else {}),
        ),  # fmt: skip
    )


# The step resolves the chain's fastest rate when dt times it is at most this (Heun's method:
# a relative error of about (dt rate)^2 / 12 per step of an oscillation).
RATE_SCALE = 0.25


def _join_chains(parts: list[ChainRun]) -> ChainRun:
    """One `ChainRun` from the runs of consecutive blocks of paths."""
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    lists = ("start", "duration", "size", "slip", "quiet_times")
    arrays = ("n_events", "mean_velocity", "slipping", "mean_force")
    joined = {k: sum((getattr(p, k) for p in parts), []) for k in lists}
    joined.update({k: np.concatenate([getattr(p, k) for p in parts]) for k in arrays})
    joined["velocity"] = (
        None if first.velocity is None else np.concatenate([p.velocity for p in parts])
    )
    joined["releases"] = None if first.releases is None else sum((p.releases for p in parts), [])
    info = dict(first.info, tasks=len(parts))
    if "n_releases" in info:
        info["n_releases"] = np.concatenate([p.info["n_releases"] for p in parts])
        info["releases_dropped"] = sum(p.info["releases_dropped"] for p in parts)
    return dataclasses.replace(first, **joined, info=info)


def fastest_rate(model) -> float:
    """The chain's fastest rate: its highest normal mode, sqrt(k_p + 4 k_c); the OU noise's
    1 / tau; the friction law's growth rate at slip onset, -dF/dV at V = 0+ (velocity
    weakening makes a sliding block unstable at that rate)."""
    law = model.friction
    eps = 1e-7 * max(1.0, float(model.v_b))
    slope = (float(law.force(eps)) - float(law.force(0.0))) / eps
    rates = [math.sqrt(float(model.k_p) + 4.0 * float(model.k_c)), max(0.0, -slope)]
    if model.tau is not None:
        rates.append(1.0 / float(model.tau))
    return max(rates)


def _check_step(model, dt):
    rate = fastest_rate(model)
    if dt * rate > RATE_SCALE:
        warnings.warn(
            f"simulate_chain: dt = {dt:g} is {dt * rate:.2g} times the chain's fastest time "
            f"scale (1/{rate:.3g}): events may depend on dt; take dt <= {RATE_SCALE / rate:.3g}",
            stacklevel=3,
        )


def _series_host(model, u, V, record_blocks):
    out = dict(
        mean_velocity=V.mean(axis=1),
        slipping=np.zeros(V.shape[0]),
        mean_force=(model.k_p * (0.0 - u)).mean(axis=1),
    )
    if record_blocks:
        out["velocity"] = V
    return out


@eqx.filter_jit
def _draw_strengths(model, key, ids):
    keys = _rng.path_keys(key, ids, 0)
    return jax.vmap(model.threshold.sample)(keys)


@eqx.filter_jit
def _segment(solver, y0, steps):
    """`steps` steps of every chain from the solver's `offset` on (at most `SEGMENT`; one
    compiled solve serves every segment). Its trace and executable are kept on disk
    (`_compile.call`): a new process neither traces nor compiles the chain again. The
    solve runs from 0 towards the static `SEGMENT` and an event ends it after `steps`:
    with end points known at trace time diffrax checks them there instead of inserting a
    host callback, which could not be exported."""
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, y, args: y),
        solver,
        t0=0.0,
        t1=float(SEGMENT),
        dt0=1.0,
        y0=y0,
        args=solver.model,
        saveat=diffrax.SaveAt(t1=True),
        stepsize_controller=diffrax.ConstantStepSize(),
        event=diffrax.Event(lambda t, y, args, **kwargs: t >= steps),
        max_steps=SEGMENT + 1,
        throw=False,
        adjoint=diffrax.ForwardMode(),
    )
    return jax.tree.map(lambda a: a[-1], sol.ys)
