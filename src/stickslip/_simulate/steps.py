"""The compiled pieces of a path's cycle that the host scheduler calls: the onset (and a
model with memory's release), the stepping loop's call, the stick's location."""

from __future__ import annotations

import functools

import diffrax
import equinox as eqx

from .. import _compile, _rng
from .._jax import jax, jnp
from .._solver.base import over_paths
from . import localise
from .hybrid import (
    PASSED,
    SLIPPING,
    SteppingPastHybrid,
    StickSlipHybrid,
    onset_states,
)
from .loop import HORIZON, solve


@_compile.quick
@eqx.filter_jit
def onset(model, smooth: bool, key, path, counter, stick_state):
    """Per-path helpers, one program (each program is a compilation on a fresh machine):
    the onset states `X` of the paths' cycle `counter`, their positions and, for a smooth
    crossing variable, its rate there; and the stick times from `stick_state` to the
    release at `X` (the next cycle's onset) with the positions of `stick_state`. The
    first call of a run has no stick states yet: what it computes from them is unused."""
    X, position, rate = onset_states(model, smooth, _rng.path_keys(key, path, counter))
    T_st = over_paths(model.stick_duration)(stick_state, X)
    return X, position, rate, T_st, over_paths(model.position)(stick_state)


@eqx.filter_jit
def release(model, key, path, counter, stick_state):
    """A model with memory (`FrictionModel.carries_state`): the stick times from
    `stick_state` and the onset states of the paths' cycle `counter` that the stick leads
    to (`FrictionModel.release`, keyed as `onset_state` would be), with the positions of
    `stick_state`."""
    keys = _rng.path_keys(key, path, counter)
    T_st, X = jax.vmap(model.release, in_axes=(0, -1), out_axes=(0, -1))(keys, stick_state)
    return X, T_st, over_paths(model.position)(stick_state)


@eqx.filter_jit
def at_onset(model, smooth: bool, X):
    """Positions and, for a smooth crossing variable, its rate at given onset states `X`
    (the slips of a model with memory start where the last stick led)."""
    position = over_paths(model.position)(X)
    rate = over_paths(model.crossing_rate)(X) if smooth else jnp.zeros_like(position)
    return position, rate


@eqx.filter_jit
def advance(
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
def locate(model, solver, cfg, X_prev, X, k_stick, path, dt, z_key, u_key):
    """Locate each stick inside the step (from X_prev to X) in which it happened."""
    step = jnp.maximum(k_stick, 0.0).astype(jnp.uint32)
    z = _rng.normals(z_key, path, step, 1)[0]
    u = _rng.uniforms(u_key, path, step, 1)[0]
    return localise.locate(
        model, solver, X_prev, X, dt, smooth=cfg.smooth, monitor=cfg.monitor, z=z, u=u
    )
