"""The buffer loop shared by every ensemble run: one diffrax solve of a buffer of paths with
a crossing solver (the stick/slip hybrid, or the upcrossing recorder) around the slip
solver. `driver` (first passages), `cycles` (time series) and `upcrossings` (free runs)
all run through it."""

from __future__ import annotations

import diffrax

from .._solver import PathwiseBrownian, SlipTerm
from .hybrid import StickSlipHybrid

# The far end of every solve (in steps); events end the solves long before. A power of two:
# diffrax's step times t0 + (t1 - t0) * j / n are then exact integers.
HORIZON = float(2**30)


def solve(
    model, solver, cfg, y0, path, dt, keys, offset, *, t1, saveat, event=None, max_steps=None,
    wrapper=StickSlipHybrid, **fields,
):  # fmt: skip
    """One diffrax solve of the ensemble state `y0` with the crossing solver `wrapper`
    around the slip solver (the stick/slip hybrid by default), from global step `offset`.
    The solve's own time starts at 0 and ends at the static `t1` (or at the event): with
    static end points diffrax checks them at trace time instead of inserting a host
    callback, and code with host callbacks cannot be kept in the persistent cache."""
    step_key, bridge_key = keys
    control = PathwiseBrownian(step_key, path, dt, solver.noise_dim(model), offset=offset)
    hybrid = wrapper(
        inner=solver, dt=dt, bridge_key=bridge_key, path=path, offset=offset, detect=cfg.detect,
        **fields,
    )  # fmt: skip
    return diffrax.diffeqsolve(
        SlipTerm(model, control),
        hybrid,
        t0=0.0,
        t1=t1,
        dt0=1.0,
        y0=y0,
        args=model,
        saveat=saveat,
        stepsize_controller=diffrax.ConstantStepSize(),
        event=event,
        max_steps=max_steps,
        throw=False,
        adjoint=diffrax.ForwardMode(),
    )
