"""The stick/slip hybrid as a diffrax solver wrapped around a slip-phase solver.

The state of the solve is the whole ensemble, `(X, (X_prev, k_stick, miss))`: `X` holds each
path's slip state, `(d, n)`; `k_stick` its mode, `-1` while slipping, otherwise the index of
the step in which the path stuck (or, with the exact bridge detector, the candidate step to
refine); `X_prev` the state at the start of the last step taken; `miss` the summed crossing
bound of the steps certified crossing-free (bridge detector). A path that sticks in step k
keeps `X = X_{k+1}` and `X_prev = X_k` from then on: the two ends of the step in which to
locate the stick. `-2` marks paths that never step (immediate re-sticks, padding), `-3` paths
that reached the horizon without sticking.

Freezing is deferred by design: the states written in a step depend only on the mode at the
start of the step, so the crossing test feeds one output (`k_stick`) and XLA does not
re-derive it inside every fused output (measured 1.6x faster than freezing at once). The
solve's time variable counts steps (`t = k`), so grid times are exact integers whatever
buffer a path is in: a solve starts at time 0 and `offset` is the global index of its first
step; `offset` is the global index of each path's first step (a scalar, or one per path: a
path set back to slipping after a refuted candidate resumes at its own step).
"""

from __future__ import annotations

from typing import ClassVar

import diffrax
import equinox as eqx

from .. import _rng
from .._jax import jax, jnp, materialised
from .._solver import AbstractSlipSolver
from .._solver.base import global_step, over_paths, steps
from . import bridge, localise

SLIPPING = -1.0
INACTIVE = -2.0
EXPIRED = -3.0
PASSED = -4.0  # slipping, after stepping past a candidate in the last step (`SteppingPastHybrid`)


class AbstractCrossingSolver(diffrax.AbstractItoSolver):
    """A diffrax solver that advances an ensemble with a slip solver (`inner`) and tests,
    path by path, whether the crossing variable reached the stick level in each step.

    The tests (`crossing_tests`, chosen by `detect`): the end value at or above the level
    (every detector but `"none"`); and inside the step: `"cubic"`, the cubic through the end
    values with the drift as slope (a differentiable crossing variable; not exact in law);
    `"brownian"`, the Brownian-bridge probability
    $\\exp(-2(L - c_k)(L - c_{k+1}) / (\\sigma^2 h))$ against a per-path uniform (noise in
    the crossing variable; the uniforms are drawn a step ahead and carried); `"bridge"`,
    Rice's bound on the Gaussian bridge's upcrossings above a tolerance, which makes the step
    a candidate for exact refinement (`bridge.py`); `"grid"`, the end value only.
    """

    inner: eqx.AbstractVar[AbstractSlipSolver]
    dt: eqx.AbstractVar[jax.Array]
    bridge_key: eqx.AbstractVar[jax.Array]
    path: eqx.AbstractVar[jax.Array]
    offset: eqx.AbstractVar[jax.Array]
    detect: eqx.AbstractVar[str]

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
        if self.detect == "brownian":
            return _rng.uniforms(self.bridge_key, self.path, global_step(t, self.offset), 1)[0]
        return None

    def advance(self, terms, t0, t1, y0, args, solver_state, made_jump):
        """Step the slip states: `(X1, inner_state, result, u)`, `u` the step's uniforms."""
        inner_state, u = solver_state
        (X1, _), _, _, inner_state, result = self.inner.step(
            terms, t0, t1, y0, args, inner_state, made_jump
        )
        return X1, inner_state, result, u

    def crossing_tests(self, model, X, X1, t0, t1, u, tol=None):
        """`(c0, c1, at_end, inside, bound)`: the crossing variable at both ends, whether it
        ends at or above the level, whether it crossed (or, `"bridge"`, may have crossed)
        inside the step, and the bridge's expected upcrossings (`"bridge"`; else zero)."""
        level = model.stick_level
        cross = over_paths(model.crossing)
        c0, c1 = cross(X), cross(X1)
        inside = jnp.zeros(c0.shape, dtype=bool)
        bound = jnp.zeros(c0.shape)
        h = self.dt * steps(t0, t1)
        if self.detect == "cubic":
            rate = over_paths(model.crossing_rate)
            inside = localise.interior_reaches(c0, c1, h * rate(X), h * rate(X1), level)
        elif self.detect == "brownian":
            var = over_paths(model.crossing_noise)(X)
            expo = -2.0 * (level - c0) * (level - c1) / jnp.where(var > 0, var * h, 1.0)
            p = jnp.where(var > 0, jnp.exp(jnp.minimum(expo, 0.0)), 0.0)
            inside = u < p
        elif self.detect == "bridge":

            def bound_of():
                return bridge.expected_upcrossings(self.inner.bridge, X, X1, level, cheap=True)

            # The bound feeds two outputs (the mode, through `inside`, and the summed miss).
            # Computed in a branch of its own it is materialised once; XLA on a CPU re-derived
            # the whole quadrature inside both fused outputs: twice the work, twice the code
            # to compile (measured: the stepping loop compiles in 1.1 s instead of 1.4 and
            # steps at dt 0.1 13 % faster, the same numbers). On an accelerator a branch in
            # the loop would wait for the host every step.
            if jax.default_backend() == "cpu":
                bound = materialised(bound_of, jnp.isfinite(t0))
            else:
                bound = bound_of()
            inside = bound > tol
        at_end = c1 >= level
        if self.detect == "none":
            at_end = jnp.zeros(c0.shape, dtype=bool)
        return c0, c1, at_end, inside, bound


class StickSlipHybrid(AbstractCrossingSolver):
    """Advance every slipping path and detect the paths that stuck (see
    `AbstractCrossingSolver` for the tests); a path sticks (or becomes a candidate) in the
    first step that passes one, and expires after global step `horizon - 1`."""

    inner: AbstractSlipSolver
    dt: jax.Array
    bridge_key: jax.Array
    path: jax.Array
    offset: jax.Array
    detect: str = eqx.field(static=True)
    horizon: jax.Array = jnp.inf
    tol: jax.Array = 0.0

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        X, (X_prev, k_stick, miss) = y0
        X1, inner_state, result, u = self.advance(terms, t0, t1, y0, args, solver_state, made_jump)
        _, _, at_end, inside, bound = self.crossing_tests(args, X, X1, t0, t1, u, self.tol)
        hit = at_end | inside
        slipping = k_stick == SLIPPING
        k_here = jnp.round(t0) + self.offset
        expired = slipping & ~hit & (k_here + 1.0 >= self.horizon)
        X_out = jnp.where(slipping[None], X1, X)
        X_prev_out = jnp.where(slipping[None], X, X_prev)
        k_out = jnp.where(slipping & hit, k_here, jnp.where(expired, EXPIRED, k_stick))
        miss_out = miss + jnp.where(slipping & ~hit, bound, 0.0)
        y1 = (X_out, (X_prev_out, k_out, miss_out))
        state = (inner_state, self._uniforms(t1))
        return y1, None, dict(y0=y0, y1=y1), state, result


class SteppingPastHybrid(StickSlipHybrid):
    """`StickSlipHybrid` (bridge detector) that steps past a candidate step ending below the
    level, up to `slots` of them per path and solve, and records each: its step, the miss
    bound before it and both end states, for refinement after the solve. A path's candidate
    past its slots ends its stepping as in `StickSlipHybrid`.

    The state gains the record, `(count, step, miss, X_start, X_end)`, `(n,)`, `(slots, n)`,
    `(slots, n)`, `(slots, d, n)`, `(slots, d, n)`. A candidate stepped past is marked in
    the mode (`PASSED`: slipping on) and recorded at the path's next step, from the state at
    its start (`X_prev`, `X` are then the candidate's end states): as with freezing, the
    crossing test feeds the mode alone, not every written record (measured: recording at
    once made a step 30x slower, XLA re-deriving the test in each). A path still `PASSED`
    when the solve ends is recorded by the caller."""

    slots: int = eqx.field(static=True, default=2)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        X, (X_prev, k_stick, miss, count, steps, misses, starts, ends) = y0
        # Record the candidate stepped past in the last step: its ends are X_prev and X.
        was_passed = k_stick == PASSED
        k_here = jnp.round(t0) + self.offset
        into = [was_passed & (count == r) for r in range(self.slots)]
        steps = jnp.stack([jnp.where(w, k_here - 1.0, steps[r]) for r, w in enumerate(into)])
        misses = jnp.stack([jnp.where(w, miss, misses[r]) for r, w in enumerate(into)])
        starts = jnp.stack([jnp.where(w[None], X_prev, starts[r]) for r, w in enumerate(into)])
        ends = jnp.stack([jnp.where(w[None], X, ends[r]) for r, w in enumerate(into)])
        count = count + was_passed
        # The step itself is `StickSlipHybrid`'s; of the paths that became candidates in it,
        # those that end below the level step on while they have slots.
        base = (X, (X_prev, jnp.where(was_passed, SLIPPING, k_stick), miss))
        (X1, (X_prev1, k1, miss1)), _, _, state, result = super().step(
            terms, t0, t1, base, args, solver_state, made_jump
        )
        below = over_paths(args.crossing)(X1) < args.stick_level
        k1 = jnp.where((k1 == k_here) & below & (count < self.slots), PASSED, k1)
        y1 = (X1, (X_prev1, k1, miss1, count, steps, misses, starts, ends))
        return y1, None, dict(y0=y0, y1=y1), state, result


def onset_states(model, smooth: bool, keys):
    """The onset states `X` of the paths whose onset keys are `keys` (one a path), their
    positions and, for a smooth crossing variable, its rate there (zeros otherwise): where
    every slip starts, for the host and the device scheduler alike."""
    X = jax.vmap(model.onset_state, out_axes=-1)(keys)
    position = over_paths(model.position)(X)
    rate = over_paths(model.crossing_rate)(X) if smooth else jnp.zeros_like(position)
    return X, position, rate
