"""Chains of blocks that stick and slip one by one (Burridge-Knopoff): per-block events in
one `diffrax.diffeqsolve` over the whole ensemble.

Every block obeys, with unit mass, absolute position `u_i` and the driver at `v_b t`,
$$\\dot V_i = f_i - F(V_i) + \\eta_i, \\qquad
f_i = k_c (u_{i+1} - 2 u_i + u_{i-1}) + k_p (v_b t - u_i),$$
while it slips (`V_i > 0`); a stuck block has `V_i = 0` and holds any force up to its
static limit. The step (fixed `dt`, as the simulator's other solvers):

1. release: a stuck block whose force exceeds its static limit starts to slip (its OU
   friction noise restarts at 0, as `langevin`'s `eta0="zero"`; with a random threshold its
   static limit was drawn when it stuck);
2. slipping blocks advance by Euler-Maruyama in V (the OU noise exactly), the position by
   the trapezoid rule;
3. stick: a block whose V falls to 0 inside the step sticks at the linearly interpolated
   time, having moved the area under its velocity up to then; V = 0.

An event is a contiguous slipping episode of the chain: from the first release with every
block stuck to the moment every block is stuck again. Its size is the number of distinct
blocks that slipped, its slip the sum of their displacements.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import diffrax
import equinox as eqx
import numpy as np

from .. import _rng
from .._errors import ParameterError, check_int, check_positive
from .._jax import jax, jnp
from .._model import ChainModel, _to_arrays


@dataclasses.dataclass(frozen=True, eq=False)
class ChainRun:
    """A simulated chain: events and time series, per path.

    - `start`, `duration`, `size`, `slip`: lists (one array per path) of the events;
      `n_events`: events per path (more than recorded if the buffer of `max_events` filled);
    - `t`: recording times; `mean_velocity`, `slipping`, `mean_force` `(n_paths, len(t))`:
      the chain's mean sliding velocity, the fraction of blocks slipping and the mean
      loading force at those times; `velocity` `(n_paths, len(t), N)` if recorded;
    - `quiet_times`: per path, the times the mean sliding velocity fell to `event_level`
      (the crossing variable's upcrossings; the ends of events when the level is 0).
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


class _ChainStep(diffrax.AbstractSolver):
    """One step of every block of every path (see the module docstring)."""

    model: Any
    key: Any
    n_paths: int = eqx.field(static=True)
    max_events: int = eqx.field(static=True)  # per path, for events and quiet times alike
    stride: int = eqx.field(static=True)
    record_blocks: bool = eqx.field(static=True)

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
        dt = t1 - t0
        y = dict(y0)
        # diffrax keeps the state floating-point: flags are 0/1, counters whole floats
        u, V, eta, limit = y["u"], y["V"], y["eta"], y["limit"]
        stuck, step = y["stuck"] > 0.5, y["step"]
        f = m.force(u, t0)
        release = stuck & (f > limit)
        stuck = stuck & ~release
        slipping = ~stuck
        ids = (jnp.arange(P)[:, None] * N + jnp.arange(N)[None, :]).ravel()
        counter = step.astype(jnp.uint32)
        xi = _rng.normals(self.key, ids, counter, 1)[0].reshape(P, N)
        eta = jnp.where(release, 0.0, eta)
        accel = f - m.friction.force(jnp.maximum(V, 0.0))
        if m.tau is None:
            V1 = V + accel * dt + jnp.sqrt(2.0 * m.D * dt) * xi
            eta1 = eta
        else:
            a = jnp.exp(-dt / m.tau)
            V1 = V + (accel + eta) * dt
            eta1 = eta * a + jnp.sqrt(m.D / m.tau * (1.0 - a * a)) * xi
        sticks = slipping & (V1 <= 0.0)
        theta = jnp.where(sticks, V / jnp.where(sticks, V - V1, 1.0), 1.0)
        u1 = jnp.where(slipping, u + jnp.where(sticks, 0.5 * theta * V, 0.5 * (V + V1)) * dt, u)
        V1 = jnp.where(slipping & ~sticks, V1, 0.0)
        stuck1 = stuck | sticks
        if m.threshold is not None:
            keys = _rng.path_keys(self.key, ids, counter)
            factor = jax.vmap(m.threshold.sample)(keys).reshape(P, N)
            limit = jnp.where(sticks, m.friction.static_limit * factor, limit)
        # events
        active = y["active"] > 0.5
        begins = ~active & release.any(axis=1)
        ep_start = jnp.where(begins, t0, y["ep_start"])
        ep_u0 = jnp.where(begins, u.sum(axis=1), y["ep_u0"])
        ep_mask = jnp.where(begins[:, None], release, (y["ep_mask"] > 0.5) | release)
        active = active | begins
        ends = active & stuck1.all(axis=1)
        t_end = t0 + dt * jnp.max(jnp.where(sticks, theta, 0.0), axis=1)
        record = jnp.stack(
            [ep_start, t_end - ep_start, ep_mask.sum(axis=1).astype(float),
             u1.sum(axis=1) - ep_u0],
            axis=1,
        )  # fmt: skip
        events, n_events = y["events"], y["n_events"]
        slot = jnp.minimum(n_events, self.max_events - 1).astype(jnp.int32)
        write = ends & (n_events < self.max_events)
        rows = jnp.arange(P)
        events = events.at[rows, slot].set(jnp.where(write[:, None], record, events[rows, slot]))
        n_events = n_events + ends
        active = active & ~ends
        # the crossing variable: mean sliding velocity falling to the event level
        level = m.event_level
        Vm0, Vm1 = V.mean(axis=1), V1.mean(axis=1)
        if level == 0.0:
            quiet, t_quiet = ends, t_end
        else:
            quiet = (Vm0 > level) & (Vm1 <= level)
            t_quiet = t0 + dt * (Vm0 - level) / jnp.where(quiet, Vm0 - Vm1, 1.0)
        qbuf, n_quiet = y["quiet"], y["n_quiet"]
        qslot = jnp.minimum(n_quiet, self.max_events - 1).astype(jnp.int32)
        qwrite = quiet & (n_quiet < self.max_events)
        qbuf = qbuf.at[rows, qslot].set(jnp.where(qwrite, t_quiet, qbuf[rows, qslot]))
        n_quiet = n_quiet + quiet
        # time series, every `stride` steps
        k = ((counter + 1) // self.stride).astype(jnp.int32)
        due = (counter + 1) % self.stride == 0
        series = y["series"]
        values = _series(m, t1, u1, V1, stuck1, self.record_blocks)
        series = {
            name: series[name].at[:, k].set(jnp.where(due, values[name], series[name][:, k]))
            for name in series
        }
        flag = lambda a: a.astype(u.dtype)
        y1 = dict(
            u=u1, V=V1, eta=eta1, stuck=flag(stuck1), limit=limit, step=step + 1,
            active=flag(active), ep_start=ep_start, ep_u0=ep_u0, ep_mask=flag(ep_mask),
            events=events, n_events=n_events,
            quiet=qbuf, n_quiet=n_quiet, series=series,
        )  # fmt: skip
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


def simulate_chain(
    model: ChainModel,
    t_max: float,
    dt: float = 0.01,
    n_paths: int = 1,
    seed: int = 0,
    record_dt: float | None = None,
    record_blocks: bool = False,
    max_events: int | None = None,
) -> ChainRun:
    """Simulate `n_paths` independent chains for `t_max` time units.

    - `dt`: the time step; events are resolved to a fraction of it (sticks are located
      inside the step; releases happen at step boundaries);
    - `record_dt`: spacing of the time series (default: 1000 points over the run);
      `record_blocks` also keeps every block's velocity;
    - `max_events`: event buffer per path (default from `t_max`); `n_events` counts them all;

    Every chain starts relaxed: each block stuck at rest with its loading spring slack
    (and its static limit drawn, with a random threshold); the driver then loads them.
    """
    owner = "simulate_chain"
    if not isinstance(model, ChainModel):
        raise ParameterError(owner, "model", "must be a chain model (e.g. burridge-knopoff)")
    t_max = check_positive(owner, "t_max", t_max)
    dt = check_positive(owner, "dt", dt)
    n_paths = check_int(owner, "n_paths", n_paths, minimum=1)
    n_steps = int(math.ceil(t_max / dt - 1e-9))
    t_max = n_steps * dt
    record_dt = t_max / 1000 if record_dt is None else check_positive(owner, "record_dt", record_dt)
    N = model.n_blocks
    if max_events is None:
        max_events = int(min(max(1000, 4 * n_steps // 10), 2_000_000))
    max_events = check_int(owner, "max_events", max_events, minimum=1)
    root = _rng.seed_key(seed)
    key = _rng.stream_key(root, _rng.STEP)
    P = n_paths
    limit = jnp.full((P, N), float(model.friction.static_limit))
    if model.threshold is not None:
        ids = (jnp.arange(P)[:, None] * N + jnp.arange(N)[None, :]).ravel()
        keys = _rng.path_keys(_rng.stream_key(root, _rng.ONSET), ids, 0)
        limit = limit * jax.vmap(model.threshold.sample)(keys).reshape(P, N)
    y0 = dict(
        u=jnp.zeros((P, N)), V=jnp.zeros((P, N)), eta=jnp.zeros((P, N)),
        stuck=jnp.ones((P, N)), limit=limit, step=jnp.zeros(()),
        active=jnp.zeros(P), ep_start=jnp.zeros(P), ep_u0=jnp.zeros(P),
        ep_mask=jnp.zeros((P, N)), events=jnp.full((P, max_events, 4), jnp.nan),
        n_events=jnp.zeros(P), quiet=jnp.full((P, max_events), jnp.nan),
        n_quiet=jnp.zeros(P),
    )  # fmt: skip
    stride = max(1, int(round(record_dt / dt)))
    n_rec = n_steps // stride + 1
    ts = np.arange(n_rec) * stride * dt
    z = jnp.zeros((P, N))
    first = _series(model, 0.0, z, z, y0["stuck"] > 0.5, record_blocks)
    y0["series"] = {
        name: jnp.zeros((P, n_rec) + v.shape[1:]).at[:, 0].set(v) for name, v in first.items()
    }
    solver = _ChainStep(_to_arrays(model), key, P, max_events, stride, record_blocks)
    sol = _solve(solver, solver.model, y0, jnp.asarray(dt), jnp.asarray(t_max), n_steps)
    final = jax.tree.map(lambda a: np.asarray(a)[-1], sol.ys)
    series = final["series"]
    n_events = final["n_events"].astype(np.int64)
    ev = final["events"]
    keep = [min(int(n), max_events) for n in n_events]
    n_quiet = final["n_quiet"].astype(np.int64)
    quiet = [final["quiet"][p, : min(int(n_quiet[p]), max_events)] for p in range(P)]
    return ChainRun(
        start=[ev[p, : keep[p], 0] for p in range(P)],
        duration=[ev[p, : keep[p], 1] for p in range(P)],
        size=[ev[p, : keep[p], 2].astype(int) for p in range(P)],
        slip=[ev[p, : keep[p], 3] for p in range(P)],
        n_events=np.asarray(n_events),
        t=ts,
        mean_velocity=series["mean_velocity"],
        slipping=series["slipping"],
        mean_force=series["mean_force"],
        velocity=series.get("velocity"),
        quiet_times=quiet,
        n_blocks=N,
        t_max=float(t_max),
        dt=float(dt),
        info=dict(
            n_steps=n_steps,
            max_events=max_events,
            seed=seed,
            overflow=bool((n_events > max_events).any() or (n_quiet > max_events).any()),
        ),  # fmt: skip
    )


@eqx.filter_jit
def _solve(solver, model, y0, dt, t_max, n_steps):
    saveat = diffrax.SaveAt(t1=True)
    return diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, y, args: y),
        solver,
        t0=0.0,
        t1=t_max,
        dt0=dt,
        y0=y0,
        args=model,
        saveat=saveat,
        stepsize_controller=diffrax.ConstantStepSize(),
        max_steps=n_steps + 1,
        throw=False,
        adjoint=diffrax.ForwardMode(),
    )
