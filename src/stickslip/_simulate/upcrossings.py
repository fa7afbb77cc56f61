"""Recording every upcrossing of the free slip-phase process (for empirical crossing
statistics): the paths run on past their stick, without absorption, until `t_max` or until
they have `max_crossings` upcrossings."""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import diffrax
import equinox as eqx
import numpy as np

from .._jax import jax, jnp
from .._solver import AbstractSlipSolver
from .._solver.base import over_paths
from .hybrid import AbstractCrossingSolver
from .loop import HORIZON, solve


@dataclasses.dataclass(frozen=True, eq=False)
class Upcrossings:
    """Upcrossings of the crossing variable through the stick level by the free slip-phase
    process (the slip SDE continued past the stick), from `simulate(record_upcrossings=K)`.

    - `times`, `positions`: `(n_paths, K)`, the first K upcrossings of each path (`nan`
      where there were fewer); time by linear interpolation inside the step;
    - `count`: upcrossings of each path up to `t_max`, possibly more than K;
    - `immediate`: paths whose crossing variable was already rising at onset (their slip
      has zero length; they are left out of the crossing statistics, which are those of the
      slipping paths, weighted by their share);
    - `t_complete`: up to this time no path had more than K upcrossings, so statistics from
      the record are complete before it.
    """

    times: np.ndarray
    positions: np.ndarray
    count: np.ndarray
    immediate: np.ndarray
    onset_position: np.ndarray
    t_max: float
    dt: float

    PER_PATH: ClassVar[tuple[str, ...]] = (
        "times", "positions", "count", "immediate", "onset_position",
    )  # fmt: skip

    @property
    def n_paths(self) -> int:
        return int(self.count.size)

    @property
    def max_crossings(self) -> int:
        return int(self.times.shape[1])

    @property
    def t_complete(self) -> float:
        full = self.count >= self.max_crossings
        if not full.any():
            return self.t_max
        return float(np.min(self.times[full, -1]))


class UpcrossingRecorder(AbstractCrossingSolver):
    """Advance every path and log its upcrossings (no stick, no freezing): from below the
    level (or from it, at the slip onset) to at or above it; with continuous monitoring also
    an excursion above the level inside the step, placed at mid-step (see
    `AbstractCrossingSolver` for the tests)."""

    inner: AbstractSlipSolver
    dt: jax.Array
    bridge_key: jax.Array
    path: jax.Array
    offset: jax.Array
    detect: str = eqx.field(static=True)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        model = args
        X, (count, times, positions) = y0
        X1, inner_state, result, u = self.advance(terms, t0, t1, y0, args, solver_state, made_jump)
        c0, c1, at_end, inside, _ = self.crossing_tests(model, X, X1, t0, t1, u)
        level = model.stick_level
        # c0 == level only at the slip onset: a path that dips and is back above the level at
        # the end of the first step has crossed upwards (as the stick detector says).
        from_below = c0 <= level
        through = from_below & at_end
        up = through | (from_below & ~at_end & inside)
        strictly = c0 < level
        linear = (level - c0) / jnp.where(through & strictly, c1 - c0, 1.0)
        frac = jnp.where(through & strictly, linear, 0.5)
        t_cross = (jnp.round(t0) + self.offset + frac) * self.dt
        pos = over_paths(model.position)
        x_cross = pos(X) + frac * (pos(X1) - pos(X))
        # one scatter per step (O(n), not O(K n)); a path with no upcrossing, or a full
        # record, writes out of bounds and is dropped
        slot = jnp.where(up, count, times.shape[0]).astype(jnp.int32)
        cols = jnp.arange(times.shape[1])
        times = times.at[slot, cols].set(t_cross, mode="drop")
        positions = positions.at[slot, cols].set(x_cross, mode="drop")
        y1 = (X1, (count + up, times, positions))
        return y1, None, dict(y0=y0, y1=y1), (inner_state, self._uniforms(t1)), result


@eqx.filter_jit
def record(model, solver, cfg, X, path, dt, step_key, bridge_key, n_steps, max_crossings, slots):
    """Run the free process from the onset states X for `n_steps` (a runtime value: one
    compiled solve serves every t_max) or until every path has `max_crossings` upcrossings
    (a runtime value too), logging them into `slots` rows (static, at least
    `max_crossings`: `crossing_slots`; the rows past `max_crossings` are the caller's to
    drop)."""
    n = X.shape[1]
    empty = jnp.full((slots, n), jnp.nan)

    def done(t, y, args, **kwargs):
        return jnp.all(y[1][0] >= max_crossings) | (t >= n_steps)

    sol = solve(
        model, solver, cfg, (X, (jnp.zeros(n), empty, empty)), path, dt, (step_key, bridge_key),
        0.0, t1=HORIZON, saveat=diffrax.SaveAt(t1=True), event=diffrax.Event(done),
        wrapper=UpcrossingRecorder,
    )  # fmt: skip
    _, (count, times, positions) = sol.ys
    return count[0], times[0], positions[0]


def crossing_slots(max_crossings: int) -> int:
    """The rows of `record`'s buffer for `max_crossings` upcrossings a path: a power of two
    (at least 4). The rows are part of the compiled solve, so K = 12 and 16 share one
    program, and 20 to 32 another, where each K compiled (and traced) its own; the stopping
    rule takes K itself, so the record is the same to the last bit."""
    return 1 << max(2, (int(max_crossings) - 1).bit_length())
