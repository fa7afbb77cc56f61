"""Euler-Maruyama for any slip-phase SDE."""

from __future__ import annotations

import diffrax

from .._jax import jax, jnp
from .base import AbstractSlipSolver, over_paths


class EulerMaruyama(AbstractSlipSolver):
    r"""Euler-Maruyama, $X_{k+1} = X_k + f(X_k)\,h + G(X_k)\,\Delta W_k$, on an ensemble.

    Works for any model; converges to the Itô solution, weak order 1 in the step size.
    Inside a step the interpolant is the cubic Hermite polynomial with the drift as slope at
    both ends: consistent for a differentiable crossing variable, used only for the position
    when noise enters the crossing variable directly.
    """

    def noise_dim(self, model):
        return model.noise_dim

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        control, carried = self.control(terms, t0, t1, solver_state)
        y1 = (y0[0] + terms.vf_prod(t0, y0, args, control), y0[1])
        return y1, None, dict(y0=y0, y1=y1), carried, diffrax.RESULTS.successful

    def dense_nodes(self, model, y0, y1, h):
        values = jnp.stack([y0, y1])
        slopes = jax.vmap(over_paths(model.drift))(values)
        return values, slopes
