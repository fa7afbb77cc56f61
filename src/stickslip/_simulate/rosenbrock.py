r"""A creeping slider's noisy motion in steps that end at its noise grid's nodes: a
linearly implicit (Rosenbrock) method, L-stable, of order 2 (ROS2: Verwer, Spee, Blom and
Hundsdorfer, SIAM J. Sci. Comput. 20, 1456, 1999).

Why. With friction noise the forcing is a piecewise-linear function of time, with a kink
at every node of the grid (`node`, `_xi`). An adaptive solver that does not know where the
kinks are shrinks its steps at each one (diffrax's Kvaerno3 at 1e-6: 163 000 implicit steps
a cycle of the paper-like slider, 0.23 cycles a second). The creep's stiffness (its
velocity relaxes in $M v / (N a)$, far below the grid's step) calls for an L-stable method,
not for small steps. So the steps here never cross a node: each is at most the grid's
interval, ends at the next node, and is shortened only where its local error (step
doubling) passes the tolerance, as at a slip's end, where the slider decelerates and the
linearised step would overshoot. The noise is the same function of time as an adaptive
solver's would be: the same paths, to the methods' errors.

A step is ROS2 with $\gamma = 1 + 1/\sqrt2$: with $W = I - \gamma h J$ ($J$ the Jacobian of
the vector field at the step's start),

$$W k_1 = F(t_n, y_n) + \gamma h F_t, \quad W k_2 = F(t_n + h, y_n + h k_1) - 2 k_1 -
\gamma h F_t, \quad y_{n+1} = y_n + \tfrac32 h k_1 + \tfrac12 h k_2,$$

$F_t$ the forcing's rate of change (the noise is linear over a step): the non-autonomous
form. Without the $F_t$ terms the method is of order 2 on non-stiff motion only: on a
linear motion with a mode of rate 1e4 under a forcing ramped differently every step, the
error halved as the step halved (order 1) where with them it falls four times
(`tests/test_rosenbrock.py`).
No Newton iteration: one Jacobian and two small linear solves a step, by Gaussian
elimination written out (a batched LAPACK call costs about a microsecond a system).

Events (the force's peaks and troughs, where `sign * crossing` rises through zero) are
found between steps; the step that holds one is integrated again in `_REFINE` substeps and
the event placed by bisection on the linear interpolant of the substep that holds it.
"""

from __future__ import annotations

import functools
import math

import equinox as eqx

from .._jax import jax, jnp

GAMMA = 1.0 + 1.0 / math.sqrt(2.0)
_REFINE = 16  # substeps over the step that holds an event
_BISECT = 48  # halvings of the event's substep (2^-48 of it)
_UNROLLED = 8  # Gaussian elimination written out up to this dimension


def _solve(W, b):
    """`W x = b` for one small system: elimination without pivoting, written out.
    `W = I - gamma h J` of a damped motion has positive leading minors (the spring's
    coupling adds `(gamma h)^2 k / M` to the slider's); where a pivot vanishes the step
    is not finite, fails its error test and shrinks, and W tends to I."""
    d = b.shape[0]
    if d > _UNROLLED:
        return jnp.linalg.solve(W, b)
    A = [[W[i, j] for j in range(d)] for i in range(d)]
    x = [b[i] for i in range(d)]
    for k in range(d):
        for i in range(k + 1, d):
            f = A[i][k] / A[k][k]
            for j in range(k + 1, d):
                A[i][j] = A[i][j] - f * A[k][j]
            x[i] = x[i] - f * x[k]
    for k in reversed(range(d)):
        s = x[k]
        for j in range(k + 1, d):
            s = s - A[k][j] * x[j]
        x[k] = s / A[k][k]
    return jnp.stack(x)


def _field(model):
    def F(y, xi):
        return model.drift(y) + model.diffusion(y) @ xi

    return F


def ros2(model, y, h, xi0, xi1):
    """One ROS2 step of length `h` from `y`, the white noise `xi0` at the step's start and
    `xi1` at its end (linear between)."""
    F = _field(model)
    J = jax.jacfwd(F)(y, xi0)
    W = jnp.eye(y.shape[0]) - GAMMA * h * J
    Ft = GAMMA * model.diffusion(y) @ (xi1 - xi0)  # gamma h dF/dt: the noise's ramp
    k1 = _solve(W, F(y, xi0) + Ft)
    k2 = _solve(W, F(y + h * k1, xi1) - 2.0 * k1 - Ft)
    return y + h * (1.5 * k1 + 0.5 * k2)


def node(key, j, m):
    """The grid's `m` standard normals at node `j` of the path's `key`."""
    high, low = (j >> 31).astype(jnp.uint32), j.astype(jnp.uint32)
    k = jax.random.fold_in(jax.random.fold_in(key, high), low)
    return jax.random.normal(k, (m,), dtype=jnp.float64)


def _xi(z0, z1, frac, h):
    return ((1.0 - frac) * z0 + frac * z1) / jnp.sqrt(h)


def doubled(model, y, h, xi0, xi1):
    """Two ROS2 steps of `h / 2` (the noise linear from `xi0` to `xi1`), their middle
    state, and the local error's estimate: their difference from one step of `h` over 3
    (Richardson: the method is of order 2). The first-order solution embedded in ROS2
    (`y + h k1`) will not do as the estimate here: it misses the noise's ramp over the
    step, and the steps shrank to a seventh of the grid's to follow it."""
    xm = 0.5 * (xi0 + xi1)
    ym = ros2(model, y, 0.5 * h, xi0, xm)
    y1 = ros2(model, ym, 0.5 * h, xm, xi1)
    return y1, ym, (y1 - ros2(model, y, h, xi0, xi1)) / 3.0


def _start(key, t0, y0, h, m):
    """The integration's carried state at `(t0, y0)`: the grid's interval `j` that holds
    `t0` and the normals at its two nodes, the next step's length (the grid's)."""
    j0 = jnp.floor(t0 / h).astype(jnp.int64)
    z0, z1 = node(key, j0, m), node(key, j0 + 1, m)
    return dict(t=t0, y=y0, j=j0, z0=z0, z1=z1, dt=h, steps=jnp.asarray(0, jnp.int64))


def _step(model, key, h, t_end, rtol, atol, s):
    """One step from the carried state `s`, no further than the grid's next node or
    `t_end`, tried as two half steps against one (`doubled`), and taken as their
    Richardson extrapolation (local extrapolation: of order 3; its stability function,
    (4 R(z/2)^2 - R(z)) / 3, stays within the unit disc over the left half plane and
    vanishes at infinity, as ROS2's own). Returns the carried state
    after it (unchanged where the step failed its tolerance, then with a shorter step to
    try) and `(ok, failed, half)`: whether it was taken, whether no step short enough is
    left, and its two halves as `(start time, state, noise)` at the start, middle and end."""
    j, t, y = s["j"], s["t"], s["y"]
    t_node = jnp.minimum((j + 1) * h, t_end)
    dt = jnp.minimum(s["dt"], t_node - t)
    to_node = dt >= t_node - t
    t1 = jnp.where(to_node, t_node, t + dt)
    xi0 = _xi(s["z0"], s["z1"], t / h - j, h)
    xi1 = _xi(s["z0"], s["z1"], t1 / h - j, h)
    y1, ym, est = doubled(model, y, t1 - t, xi0, xi1)
    scale = atol + rtol * jnp.maximum(jnp.abs(y), jnp.abs(y1))
    err = jnp.sqrt(jnp.mean((est / scale) ** 2))
    err = jnp.where(jnp.isfinite(err) & jnp.all(jnp.isfinite(y1)), err, jnp.inf)
    ok = err <= 1.0
    grow = jnp.clip(0.9 * jnp.maximum(err, 1e-10) ** (-1.0 / 3.0), 0.2, 5.0)
    nxt = ok & (t1 >= (j + 1) * h)  # on to the grid's next interval: a new node
    failed = ~ok & (dt < 1e-12 * jnp.maximum(h, jnp.abs(t)))  # no step left that passes
    grown = jnp.where(to_node, jnp.maximum(s["dt"], dt * grow), dt * grow)
    m = model.noise_dim
    out = dict(
        t=jnp.where(ok, t1, t), y=jnp.where(ok, y1 + est, y), j=jnp.where(nxt, j + 1, j),
        z0=jnp.where(nxt, s["z1"], s["z0"]), z1=jnp.where(nxt, node(key, j + 2, m), s["z1"]),
        dt=jnp.minimum(h, jnp.where(ok, grown, dt * jnp.minimum(grow, 0.5))),
        steps=s["steps"] + 1,
    )  # fmt: skip
    # (the end as taken, extrapolated: the next step starts there, so that a crossing
    # between two steps falls in one half or the other)
    half = ((t, y, xi0), (0.5 * (t + t1), ym, 0.5 * (xi0 + xi1)), (t1, y1 + est, xi1))
    return out, ok, failed, half


# What a window keeps of each event: the half step that holds it (start and end times,
# states and noises) and its direction (+1: the slider outruns the drive, a force peak).
BRACKET = ("ta", "ya", "xa", "tb", "yb", "xb", "up")


_CARRIED = ("t", "y", "j", "z0", "z1", "dt", "steps")


@eqx.filter_jit
def window(model, y0, t0, limit, key, h, t_stop, rtol, atol, max_steps, max_events):
    """Integrate each path from `(t0, y0)` to `t_stop`, keeping every crossing of the
    drive's speed (`crossing` changing sign between two half steps) as the half step that
    holds it (`locate` places it), up to `max_events`; a path stops early once it has
    `limit` of them or its buffer is nearly full, or after `max_steps`. The motion runs on
    through its events (the path does not depend on where they are, or on the windows).
    Returns each path's end time and state, its events' brackets (`BRACKET`, each of
    `max_events` rows), their count, whether a step failed, and the steps taken. The path
    axis is every array's last (`_compile.call`'s convention).

    The paths step together (each step vmapped over them); the buffers are written only
    at a step where some path has an event (a few hundred of some 10^5 steps): written at
    every step, under `vmap`, they took half the time."""
    d, m = y0.shape[0], model.noise_dim
    P, E = y0.shape[-1], max_events
    lanes = jnp.arange(P)
    over = functools.partial(jax.vmap, in_axes=-1, out_axes=-1)
    crossing = over(model.crossing)
    step = over(lambda s, key: _step(model, key, h, t_stop, rtol, atol, s))
    buf = dict(
        ta=jnp.zeros((E, P)), ya=jnp.zeros((E, d, P)), xa=jnp.zeros((E, m, P)),
        tb=jnp.zeros((E, P)), yb=jnp.zeros((E, d, P)), xb=jnp.zeros((E, m, P)),
        up=jnp.zeros((E, P), bool),
    )  # fmt: skip
    start = over(lambda k, t, y: _start(k, t, y, h, m))(key, t0, y0)
    state = dict(start, n=jnp.zeros(P, jnp.int64), failed=jnp.zeros(P, bool), buf=buf)

    def active(s):
        room = (s["n"] < limit) & (s["n"] + 2 <= E)
        return (s["t"] < t_stop) & room & (s["steps"] < max_steps) & ~s["failed"]

    def write(bn, half, c, events):
        b, n = bn
        for i, ev in enumerate(events):
            (a, z), at = half[i : i + 2], jnp.where(ev, n, E)  # (E: past the end, dropped)
            row = dict(ta=a[0], ya=a[1].T, xa=a[2].T, tb=z[0], yb=z[1].T, xb=z[2].T,
                       up=c[i + 1] > 0.0)  # fmt: skip
            b = {k: (b[k].at[at, lanes] if b[k].ndim == 2 else b[k].at[at, :, lanes]).set(
                row[k], mode="drop") for k in b}  # fmt: skip
            n = n + ev
        return b, n

    def body(s):
        go = active(s)
        out, ok, failed, half = step({k: s[k] for k in _CARRIED}, key)
        out = {k: jnp.where(go, out[k], s[k]) for k in _CARRIED}
        taken = go & ok
        c = [crossing(x[1]) for x in half]  # at the step's start, middle and end
        events = [taken & ((c[i] <= 0.0) != (c[i + 1] <= 0.0)) for i in (0, 1)]
        b, n = jax.lax.cond(jnp.any(events[0] | events[1]),
                            lambda bn: write(bn, half, c, events), lambda bn: bn,
                            (s["buf"], s["n"]))  # fmt: skip
        return dict(out, n=n, failed=s["failed"] | (go & failed), buf=b)

    s = jax.lax.while_loop(lambda s: jnp.any(active(s)), body, state)
    return s["t"], s["y"], s["buf"], s["n"], s["failed"], s["steps"]


@eqx.filter_jit
def locate(model, ta, ya, xa, tb, yb, xb, up):
    """Each event's time and state from its bracket (`window`'s): the half step again in
    `_REFINE` substeps (the noise linear over it), then bisection on the linear
    interpolant of the first substep where `crossing` changes sign the bracket's way (of
    the whole half step, where the substeps miss it). The state found lies on the far
    side: the next crossing is the other way. The event axis is every array's last."""

    def one(ta, ya, xa, tb, yb, xb, up):
        H = tb - ta
        sign = jnp.where(up, 1.0, -1.0)

        def sub(y, k):
            fa, fb = k / _REFINE, (k + 1.0) / _REFINE
            y1 = ros2(model, y, H / _REFINE, xa + fa * (xb - xa), xa + fb * (xb - xa))
            return y1, y1

        _, ys = jax.lax.scan(sub, ya, jnp.arange(_REFINE, dtype=jnp.float64))
        ys = jnp.concatenate([ya[None], ys])
        c = sign * jax.vmap(model.crossing)(ys)
        turns = (c[:-1] <= 0.0) & (c[1:] > 0.0)
        found = jnp.any(turns)
        k = jnp.argmax(turns)
        lo_y, hi_y = jnp.where(found, ys[k], ya), jnp.where(found, ys[k + 1], yb)
        lo_t = jnp.where(found, ta + H * k / _REFINE, ta)
        hi_t = jnp.where(found, ta + H * (k + 1.0) / _REFINE, tb)

        def halve(_, ab):
            a, b = ab
            mid = 0.5 * (a + b)
            over = sign * model.crossing(lo_y + mid * (hi_y - lo_y)) > 0.0
            return jnp.where(over, a, mid), jnp.where(over, mid, b)

        _, f = jax.lax.fori_loop(0, _BISECT, halve, (jnp.asarray(0.0), jnp.asarray(1.0)))
        return lo_t + f * (hi_t - lo_t), lo_y + f * (hi_y - lo_y)

    return jax.vmap(one, in_axes=-1, out_axes=-1)(ta, ya, xa, tb, yb, xb, up)


@eqx.filter_jit
def dense(model, y0, key, h, ts, rtol, atol, max_steps):
    """Each path's states at the times `ts` (from `ts[0]`), the steps also ending at
    each of them; `nan` after a stretch between two that took more than `max_steps`
    or failed. The path axis is every array's last."""
    m = model.noise_dim

    def one(y0, key):
        def sample(carried, t_end):
            def cond(s):
                return (s["t"] < t_end) & (s["steps"] < max_steps) & ~s["failed"]

            def body(s):
                out, _, failed, _ = _step(model, key, h, t_end, rtol, atol,
                                          {k: s[k] for k in carried})  # fmt: skip
                return dict(out, failed=failed)

            s = jax.lax.while_loop(cond, body, dict(carried, failed=jnp.asarray(False)))
            y = jnp.where(s["t"] >= t_end, s["y"], jnp.nan)
            return dict({k: s[k] for k in carried}, y=y, steps=jnp.asarray(0, jnp.int64)), y

        _, ys = jax.lax.scan(sample, _start(key, ts[0], y0, h, m), ts[1:])
        return jnp.concatenate([y0[None], ys])

    return jax.vmap(one, in_axes=-1, out_axes=-1)(y0, key)
