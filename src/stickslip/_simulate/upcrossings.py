"""Recording every upcrossing of the free slip-phase process (for empirical crossing
statistics): the paths run on past their stick, without absorption, until `t_max` or until
they have `max_crossings` upcrossings."""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import diffrax
import equinox as eqx
import numpy as np

from .. import _rng
from .._jax import jax, jnp
from .._solver import AbstractSlipSolver
from .._solver.base import global_step, over_paths, steps
from . import localise


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


class UpcrossingRecorder(diffrax.AbstractItoSolver):
    """Advance every path with `inner` and log its upcrossings (no stick, no freezing).

    An upcrossing in a step: the crossing variable goes from below the level to at or above
    it; with continuous monitoring also an excursion above the level inside the step (the
    cubic check, or the Brownian-bridge test), placed at mid-step.
    """

    inner: AbstractSlipSolver
    dt: jax.Array
    bridge_key: jax.Array
    path: jax.Array
    offset: jax.Array
    smooth: bool = eqx.field(static=True)
    monitor: str = eqx.field(static=True)

    term_structure: ClassVar = diffrax.AbstractTerm
    interpolation_cls: ClassVar = diffrax.LocalLinearInterpolation

    def order(self, terms):
        return self.inner.order(terms)

    def strong_order(self, terms):
        return self.inner.strong_order(terms)

    def func(self, terms, t0, y0, args):
        return self.inner.func(terms, t0, y0, args)

    def init(self, terms, t0, t1, y0, args):
        return self.inner.init(terms, t0, t1, y0, args), self._uniforms(t0)

    def _uniforms(self, t):
        if self.monitor == "continuous" and not self.smooth:
            return _rng.uniforms(self.bridge_key, self.path, global_step(t, self.offset), 1)[0]
        return None

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        model = args
        X, (count, times, positions) = y0
        inner_state, u = solver_state
        (X1, _), _, _, inner_state, result = self.inner.step(
            terms, t0, t1, y0, args, inner_state, made_jump
        )
        level = model.stick_level
        cross = over_paths(model.crossing)
        c0, c1 = cross(X), cross(X1)
        below = c0 < level
        # c0 == level only at the slip onset: a path that dips and is back above the level at
        # the end of the first step has crossed upwards (as the stick detector says).
        through = (c0 <= level) & (c1 >= level)
        inside = jnp.zeros_like(through)
        h = self.dt * steps(t0, t1)
        if self.monitor == "continuous":
            if self.smooth:
                rate = over_paths(model.crossing_rate)
                reach = localise.interior_reaches(c0, c1, h * rate(X), h * rate(X1), level)
                inside = (c0 <= level) & (c1 < level) & reach
            else:
                var = over_paths(model.crossing_noise)(X)
                expo = -2.0 * (level - c0) * (level - c1) / jnp.where(var > 0, var * h, 1.0)
                p = jnp.where(var > 0, jnp.exp(jnp.minimum(expo, 0.0)), 0.0)
                inside = below & (c1 < level) & (u < p)
        up = through | inside
        linear = (level - c0) / jnp.where(through & below, c1 - c0, 1.0)
        frac = jnp.where(through & below, linear, 0.5)
        t_cross = (jnp.round(t0) + self.offset + frac) * self.dt
        pos = over_paths(model.position)
        x_cross = pos(X) + frac * (pos(X1) - pos(X))
        slot = jnp.arange(times.shape[0])[:, None] == count[None, :]
        write = up[None, :] & slot
        times = jnp.where(write, t_cross[None, :], times)
        positions = jnp.where(write, x_cross[None, :], positions)
        y1 = (X1, (count + up, times, positions))
        return y1, None, dict(y0=y0, y1=y1), (inner_state, self._uniforms(t1)), result


@eqx.filter_jit
def record(model, solver, cfg, X, path, dt, step_key, bridge_key, n_steps, max_crossings):
    """Run the free process from the onset states X for n_steps, logging upcrossings."""
    from .._solver import PathwiseBrownian, SlipTerm

    n = X.shape[1]
    control = PathwiseBrownian(step_key, path, dt, solver.noise_dim(model), offset=0.0)
    recorder = UpcrossingRecorder(solver, dt, bridge_key, path, 0.0, cfg.smooth, cfg.monitor)
    empty = jnp.full((max_crossings, n), jnp.nan)
    y0 = (X, (jnp.zeros(n), empty, empty))

    def full(t, y, args, **kwargs):
        return jnp.all(y[1][0] >= max_crossings)

    sol = diffrax.diffeqsolve(
        SlipTerm(model, control),
        recorder,
        t0=0.0,
        t1=n_steps,
        dt0=1.0,
        y0=y0,
        args=model,
        saveat=diffrax.SaveAt(t1=True),
        stepsize_controller=diffrax.ConstantStepSize(),
        event=diffrax.Event(full),
        max_steps=None,
        throw=False,
        adjoint=diffrax.ForwardMode(),
    )
    _, (count, times, positions) = sol.ys
    return count[0], times[0], positions[0]
