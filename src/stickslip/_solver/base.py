"""Building blocks shared by the slip-phase solvers: the ensemble SDE term, the per-path
Brownian control and the abstract solver.

Ensemble arrays are component-major: a state is `(d, n_paths)`, so that each component is a
contiguous row and per-path arithmetic vectorises (measured 2x faster than `(n_paths, d)`
on the target CPU, where strided columns defeat XLA's vectoriser).
"""

from __future__ import annotations

import abc
from typing import ClassVar

import diffrax
import equinox as eqx

from .. import _rng
from .._jax import jax, jnp, materialised


def over_paths(fn):
    """Vectorise a one-path function over the last (path) axis of every argument/output."""
    return jax.vmap(fn, in_axes=-1, out_axes=-1)


def steps(t0, t1):
    """Whole steps between two times of the solve. diffrax makes step times as
    `t0 + (t1 - t0) * j / n`, which after a restart can be off an integer by rounding; the
    physical step length must not depend on where a buffer was restarted."""
    return jnp.round(t1 - t0)


def global_step(t, offset):
    """The global step index (uint32) of the step starting at solve time `t`."""
    return (jnp.round(t) + offset).astype(jnp.uint32)


def contract(G, w):
    """`sum_m G[:, m] * w[m]` path by path, for `G` `(d, m, n)` and `w` `(m, n)`, with a fixed
    summation order (results must not depend on how many paths are in the batch)."""
    acc = G[:, 0] * w[0]
    for j in range(1, G.shape[1]):
        acc = acc + G[:, j] * w[j]
    return acc


class PathwiseBrownian(diffrax.AbstractBrownianPath):
    """Brownian increments for an ensemble, drawn path by path from counters.

    Time is counted in steps from `offset`: the step starting at solve time `t0` is global
    step `offset + t0`, and lasts `dt` in physical time. The increment of path `path[i]` over
    a step depends only on the key, the path's global index and the global step index: the
    ensemble can be split, re-packed or re-run in any grouping and each path sees the same
    noise.

    **Arguments:** `key` (uint32[2]), `path` (uint32[n]), `dt` (physical step length), `dim`
    (noise columns per path), `offset` (global index of the solve's first step).

    **Returns** (from `evaluate(t0, t1)`): increments of shape `(dim, n)`.
    """

    key: jax.Array
    path: jax.Array
    dt: jax.Array
    dim: int = eqx.field(static=True)
    offset: jax.Array = 0.0
    levy_area: ClassVar = diffrax.BrownianIncrement

    @property
    def t0(self):
        return -jnp.inf

    @property
    def t1(self):
        return jnp.inf

    def evaluate(self, t0, t1=None, left=True, use_levy=False):
        del left
        if t1 is None or use_levy:
            raise NotImplementedError("PathwiseBrownian gives increments over grid steps only")
        k = global_step(t0, self.offset)
        z = _rng.normals(self.key, self.path, k, self.dim)
        return jnp.sqrt(self.dt * steps(t0, t1)) * z


class SlipTerm(diffrax.AbstractTerm):
    r"""The slip-phase SDE of an ensemble, $dX = f(X)\,dt + G(X)\,dW$, as one diffrax term.

    The state of the solve is `(X, rest)`: the slip states `X`, shape `(d, n_paths)`, and
    whatever the stick/slip logic carries besides (modes, the state before the step), which
    is not part of the SDE. `vf` gives the drift `(d, n)` and diffusion `(d, m, n)` of every
    path, `contr` gives `(dt, dW)`, and `prod` combines them into the increment of `X`.
    """

    model: eqx.Module
    control: PathwiseBrownian

    def vf(self, t, y, args):
        X = y[0]
        return over_paths(self.model.drift)(X), over_paths(self.model.diffusion)(X)

    def contr(self, t0, t1, **kwargs):
        # Times are in steps (see PathwiseBrownian); the control is in physical time.
        return self.control.dt * steps(t0, t1), self.control.evaluate(t0, t1)

    def prod(self, vf, control):
        (f, g), (dt, dw) = vf, control
        return f * dt + contract(g, dw)


class AbstractSlipSolver(diffrax.AbstractItoSolver):
    """A diffrax solver for the slip phase of an ensemble of paths.

    The state is `(X, rest)` as in `SlipTerm`; a slip solver advances `X` and returns `rest`
    unchanged. Steps are of one unit of the solve's time (one grid step).

    A step's noise must be materialised once: drawn inside the step and left to XLA, it was
    re-derived inside every fused consumer (measured 1.7x slower). On a CPU each step draws
    it in a branch of its own (`control`); elsewhere (a branch in the loop would wait for the
    host every step) it is drawn a step ahead and carried in the solver state, which costs a
    second copy of the draw's code before the loop (on a CPU the stepping loop had 28
    kernels and 576 kB of LLVM IR with it at 128 paths, against 22 and 460 kB, and compiled
    at seven buffer sizes in 14.7-16.1 s against 11.6-12.2 s). The draws are the same
    either way (keyed by path and step).

    Besides diffrax's `step`, a slip solver says how much noise it draws per path and step
    (`noise_dim`) and gives its own interpolant inside a step (`dense_nodes`), which the
    simulator uses to locate each path's stick inside the step where it happened.
    """

    term_structure: ClassVar = diffrax.AbstractTerm
    interpolation_cls: ClassVar = diffrax.LocalLinearInterpolation

    def order(self, terms):
        return 1

    def strong_order(self, terms):
        return 0.5

    def func(self, terms, t0, y0, args):
        return terms.vf(t0, y0, args)

    def init(self, terms, t0, t1, y0, args):
        return None if jax.default_backend() == "cpu" else self.step_control(terms, t0, t1)

    def control(self, terms, t0, t1, solver_state):
        """The control of the step from `t0` to `t1` and the solver state to carry: drawn
        here in a branch of its own where the state is `None` (a CPU), else the carried one,
        with the next step's drawn ahead (`step_control` over a step of the same length).
        A solver's `step` takes its control from here (the state `init` gives is this)."""
        if solver_state is not None:
            return solver_state, self.step_control(terms, t1, t1 + (t1 - t0))
        return materialised(lambda: self.step_control(terms, t0, t1), jnp.isfinite(t0)), None

    def step_control(self, terms, t0, t1):
        """What `step` takes of the control over one step (by default all of it)."""
        return terms.contr(t0, t1)

    @abc.abstractmethod
    def noise_dim(self, model) -> int:
        """Standard normals drawn per path and step."""

    @abc.abstractmethod
    def dense_nodes(self, model, y0, y1, h):
        """The solver's interpolant inside one step from `y0` to `y1` (each `(d, n)`) of
        length `h`: values and time derivatives at `M + 1` equispaced nodes, two arrays of
        shape `(M + 1, d, n)`, to be joined by cubic Hermite pieces."""
