"""The device scheduler: the first passages of a chunk of paths in one compiled program.

The host scheduler (`host.HostRun._chunk`) runs a chunk as a sequence of short compiled calls
with NumPy compaction, sorting and batch cutting in between: cheap on a CPU, where a call's
results are zero-copy views, but on an accelerator every call and every read of a result is
a wait (docs/performance.md, "On a GPU"). Here the whole chunk is one program:

1. *Stepping*: a `while_loop` steps every path still slipping by one step of the run's slip
   solver (the same noise, keyed by path and step) with the bridge detector's screen
   (`bridge.expected_upcrossings`, cheap form). A candidate step (one that ends at or above
   the level, or whose bound exceeds the tolerance) is appended to a fixed-capacity queue
   (both end states, path, step, the stepping miss bound before it) by a cumulative sum and
   a scatter. A path steps on past a candidate that ends below the level, and stops at one
   that ends at or above it (it holds a crossing) or at the horizon.
2. *Compaction*: the stepping buffers form a ladder of sizes (each an eighth of the one
   before, as `buffers.smaller_buffer` below `FINE_BUFFER`); once the paths left fit the
   next one, they are gathered into it.
3. *Refinement*: when the queue cannot take another step's candidates, or no path is left,
   the whole queue is refined by the bridge detector's level pass (`bridge.refine_levels`)
   on a ladder of interval buffers (the open intervals are moved to a smaller buffer when
   they fit, with their owners renumbered; a larger one when a level would overflow).
4. *Resolution*: each path's stick is in its earliest candidate (in step order) that holds a
   crossing: an integer scatter-min over the candidates' steps. A path whose stick is found
   stops stepping. Results go into per-path arrays; one copy to the host at the end.

The level pass is the host scheduler's own, `lax.cond`s included (on a GPU each is a wait
for the device, as is every iteration's loop condition: a few hundred a chunk, against the
host scheduler's calls and copies by the thousand).

Refinement draws are keyed by (path, step, tree node), so the sticks are those of the host
scheduler, which refines each candidate before stepping on (or steps past it and refines it
later, `_settle`): the same decisions, the located times equal up to rounding. Only the
bridge detector (exact solver, continuous monitoring, noise reaching the crossing variable)
runs here.
"""

from __future__ import annotations

import equinox as eqx
import numpy as np

from .. import _compile, _rng
from .._jax import jax, jnp
from .._solver import PathwiseBrownian, SlipTerm
from .._solver.base import over_paths
from . import bridge
from .hybrid import onset_states

_NONE = np.iinfo(np.int32).max  # "no stick found" (a step index no run reaches)
MIN_STEPPING = 128  # smallest stepping buffer of the ladder (`buffers.MIN_BUFFER`)
FINE = 8192  # from here up the refinement has a ladder of buffers (`buffers.FINE_BUFFER`)
MIN_INTERVALS = 256  # smallest interval buffer of the refinement ladder (`bridge.CAPACITIES`)
MAX_SIZES = 4  # buffers of a ladder (the smallest of a large chunk costs little on a device)
LADDER = 8  # ratio of consecutive buffer sizes (as `buffers.smaller_buffer` below FINE_BUFFER)
# Refinement status of one span of the queue (besides `bridge.GO` and `bridge.DONE`): a level
# would overflow the largest interval buffer; the span is then refined in halves.
_FAIL = 4
_STATS = ("candidates", "refined_nodes", "unresolved", "path_steps", "refined_miss", "speculated")


def stepping_sizes(n: int) -> tuple[int, ...]:
    """The stepping buffers of a chunk whose first buffer holds `n` paths (at most
    `MAX_SIZES`: each is a copy of the step in the program, ~1 s to compile on 2 cores)."""
    sizes = [n]
    while len(sizes) < MAX_SIZES and sizes[-1] // LADDER >= MIN_STEPPING:
        sizes.append(sizes[-1] // LADDER)
    return tuple(sizes)


def interval_sizes(n: int) -> tuple[int, ...]:
    """The interval buffers of the refinement of a queue of `n` candidates: twice the queue
    (a level at most doubles the open intervals), the queue, then an eighth each, down to
    `MIN_INTERVALS` (at most `MAX_SIZES`: each is a copy of the level pass in the program,
    ~3 s to compile on 2 cores; the few intervals of the last levels run on the smallest).
    Below `FINE` candidates, one buffer: a pass costs little whatever its size there."""
    sizes = [max(2 * n, MIN_INTERVALS)]
    if n < FINE:
        return tuple(sizes)
    sizes.append(n)
    while len(sizes) < MAX_SIZES and sizes[-1] // LADDER >= MIN_INTERVALS:
        sizes.append(sizes[-1] // LADDER)
    return tuple(sizes)


def _onset(model, smooth, key, path):
    """The onset states of the paths' first cycle, their positions and the crossing
    variable's rate there (as `steps.onset`: the same draws)."""
    return onset_states(model, smooth, _rng.path_keys(key, path, jnp.uint32(0)))


def _step(model, solver, dt, step_key, X, k, p):
    """One step of the run's slip solver for the paths `p` from their global steps `k`: the
    solver's own step on its noise (`PathwiseBrownian`, as the host's stepping loop)."""
    control = PathwiseBrownian(step_key, p, dt, solver.noise_dim(model), offset=k)
    term = SlipTerm(model, control)
    dw = term.contr(0.0, 1.0)[1]
    (X1, _), *_ = solver.step(term, 0.0, 1.0, (X, None), model, dw, False)
    return X1


def _refine_span(rows_t, depths, tol, key, layout, caps, level, queue, lo, n):
    """Refine the queue's candidates `lo .. lo + n - 1` (`bridge.refine_levels` on the
    interval buffers `caps`, largest first: the levels run on the smallest buffer that holds
    `bridge.HEADROOM` times their open intervals, on a larger one where a level would
    overflow it). Returns `(ok, found, frac, state, miss, unres, splits)`, per
    candidate `(caps[0],)` by its place in the span; `ok` false where a level would have
    overflowed the largest buffer (nothing is kept then)."""
    qa, qb, qpath, qstep = queue["a"], queue["b"], queue["path"], queue["step"]
    d, Q = qa.shape
    C0 = caps[0]
    slots = jnp.arange(C0, dtype=jnp.int32)
    sel = slots < n
    src = jnp.minimum(lo + slots, Q - 1)
    buf = (
        jnp.where(sel, qa[:, src], 0.0), jnp.where(sel, qb[:, src], 0.0), slots,
        jnp.zeros(C0, jnp.int32), jnp.where(sel, qpath[src], 0).astype(jnp.uint32),
        jnp.where(sel, qstep[src], 0).astype(jnp.uint32),
    )  # fmt: skip
    res = (
        jnp.zeros(C0, bool), jnp.ones(C0), jnp.zeros((d, C0)), jnp.zeros(C0),
        jnp.zeros(C0, bool),
    )  # fmt: skip
    caps_arr = jnp.asarray(caps, jnp.int32)

    def branch(i):
        Ci = caps[i]
        shrink = int(caps[i + 1] / bridge.HEADROOM) if i + 1 < len(caps) else 0
        local_slots = jnp.arange(Ci, dtype=jnp.int32)

        def run(carry):
            j, keyed, count, _, _, buf, res, splits = carry
            a, b, owner, pos, k0, k1 = (x[..., :Ci] for x in buf)
            valid = local_slots < count
            # Owners (candidates) numbered from 0 in this buffer: their intervals are
            # contiguous and in order; `who` maps them back.
            starts = valid & jnp.concatenate([jnp.ones(1, bool), owner[1:] != owner[:-1]])
            local = jnp.cumsum(starts, dtype=jnp.int32) - 1
            who = jnp.zeros(Ci, jnp.int32).at[jnp.where(starts, local, Ci)].set(owner, mode="drop")
            n_owners = jnp.sum(starts, dtype=jnp.int32)
            out = bridge.refine_levels(
                rows_t, j, depths, level, tol, key, jnp.int32(shrink), keyed, a, b,
                jnp.where(valid, local, 0), pos, k0, k1, count, layout,
            )  # fmt: skip
            j, a, b, owner, pos, k0, k1, count = out[:8]
            found, frac, state, miss, unres, split, status = out[8:]
            back = jnp.where(local_slots < n_owners, who, C0)
            f0, fr0, st0, m0, u0 = res
            res = (
                f0.at[back].set(f0[back.clip(0, C0 - 1)] | found, mode="drop"),
                fr0.at[back].set(jnp.where(found, frac, fr0[back.clip(0, C0 - 1)]), mode="drop"),
                st0.at[:, back].set(
                    jnp.where(found, state, st0[:, back.clip(0, C0 - 1)]), mode="drop"
                ),
                m0.at[back].add(miss, mode="drop"),
                u0.at[back].set(u0[back.clip(0, C0 - 1)] | unres, mode="drop"),
            )
            owner = who[owner]
            buf = tuple(
                x.at[..., :Ci].set(y) for x, y in zip(buf, (a, b, owner, pos, k0, k1), strict=True)
            )
            # The next buffer: the smallest that holds `HEADROOM` times the open intervals,
            # or twice them after a level overflowed (`GROW`: it was left undone).
            want = jnp.where(status == bridge.GROW, 2 * count, jnp.ceil(bridge.HEADROOM * count))
            fits = jnp.sum(caps_arr >= want, dtype=jnp.int32)
            state_ = jnp.where(
                status == bridge.DONE, bridge.DONE, jnp.where(fits > 0, bridge.GO, _FAIL)
            ).astype(jnp.int32)
            return (j, jnp.int32(1), count, jnp.maximum(fits - 1, 0), state_, buf, res,
                    splits + split)  # fmt: skip

        return run

    branches = [branch(i) for i in range(len(caps))]
    first = jnp.sum(caps_arr >= jnp.ceil(bridge.HEADROOM * n), dtype=jnp.int32) - 1
    init = (jnp.int32(0), jnp.int32(0), n, jnp.maximum(first, 0), jnp.int32(bridge.GO), buf,
            res, jnp.zeros((), jnp.int32))  # fmt: skip
    out = jax.lax.while_loop(
        lambda c: c[4] == bridge.GO, lambda c: jax.lax.switch(c[3], branches, c), init
    )
    return (out[4] == bridge.DONE,) + out[6] + (out[7],)


@eqx.filter_jit
def _program(
    model, solver, smooth, layout, sizes, caps, rows_t, depths, tol, horizon, dt, step_key,
    tree_key, onset_key, path, count,
):  # fmt: skip
    """First passages of one chunk (the module docs): `path` `(N,)` the chunk's path counters
    (the first `count` real), `sizes` the stepping buffers, `caps` the interval buffers.
    Returns one flat array: rows `(2d + 3, N)` (onset states, stick states, stick times
    (`nan` where none), miss bounds, onset positions), then the counts `_STATS`."""
    N = path.shape[0]
    d = solver.noise_dim(model)
    Q = N  # the queue: a stepping round adds at most one candidate a path
    level = model.stick_level
    cross = over_paths(model.crossing)
    X0, x_start, rate = _onset(model, smooth, onset_key, path)
    rows = jnp.arange(N, dtype=jnp.int32)
    valid = rows < count
    # A crossing variable already rising at onset ends the slip at once (T_sl = 0).
    immediate = valid & (rate >= 0.0) if smooth else jnp.zeros(N, bool)

    # Every stepping buffer starts with the first paths of the chunk; the chunk's paths
    # start in the smallest that holds them (a chunk smaller than the program's buffer, the
    # last of a run, runs on the program of the run's other chunks).
    start = (X0, jnp.zeros(N, jnp.int32), jnp.zeros(N), rows, path, valid & ~immediate)
    bufs = tuple(tuple(x[..., :S] for x in start) for S in sizes)
    first_stage = jnp.sum(jnp.asarray(sizes) >= count, dtype=jnp.int32) - 1
    queue = dict(
        a=jnp.zeros((d, Q)), b=jnp.zeros((d, Q)), path=jnp.zeros(Q, jnp.uint32),
        step=jnp.zeros(Q, jnp.int32), miss=jnp.zeros(Q), row=jnp.zeros(Q, jnp.int32),
        n=jnp.zeros((), jnp.int32),
    )  # fmt: skip
    # Per path: the step of its stick's candidate, the fraction of the step, the state there,
    # the stepping miss bound (before that candidate; at the horizon for a path that expired).
    found = dict(step=jnp.full(N, _NONE, jnp.int32), frac=jnp.ones(N), state=X0, miss=jnp.zeros(N))
    stats = jnp.zeros(len(_STATS))
    bump = {name: jnp.eye(len(_STATS))[i] for i, name in enumerate(_STATS)}

    def stepper(s):
        S = sizes[s]
        below = sizes[s + 1] if s + 1 < len(sizes) else 0  # compact once this few are left

        def run(carry):
            stage, _, bufs, queue, found, stats = carry
            X, k, miss, row, p, alive = bufs[s]
            alive = alive & (found["step"][row] == _NONE)  # (a stick found: done)

            def more(c):
                n_alive = jnp.sum(c[5], dtype=jnp.int32)
                return (n_alive > below) & (c[6]["n"] + n_alive <= Q)

            def one_step(c):
                X, k, miss, row, p, alive, queue, found, stats = c
                X1 = _step(model, solver, dt, step_key, X, k.astype(jnp.float64), p)
                at_end = cross(X1) >= level
                bound = bridge.expected_upcrossings(solver.bridge, X, X1, level, cheap=True)
                hit = at_end | (bound > tol)
                cand = alive & hit
                expired = alive & ~hit & (k + 1 >= horizon)
                step_in = cand.astype(jnp.int32)
                at = jnp.where(cand, queue["n"] + jnp.cumsum(step_in, dtype=jnp.int32) - step_in, Q)
                queue = dict(
                    a=queue["a"].at[:, at].set(X, mode="drop"),
                    b=queue["b"].at[:, at].set(X1, mode="drop"),
                    path=queue["path"].at[at].set(p, mode="drop"),
                    step=queue["step"].at[at].set(k, mode="drop"),
                    miss=queue["miss"].at[at].set(miss, mode="drop"),
                    row=queue["row"].at[at].set(row, mode="drop"),
                    n=queue["n"] + jnp.sum(step_in, dtype=jnp.int32),
                )
                miss = miss + jnp.where(alive & ~hit, bound, 0.0)
                found = dict(found, miss=found["miss"].at[jnp.where(expired, row, N)].set(
                    miss, mode="drop"))  # fmt: skip
                # Step on past a candidate that ends below the level (refined later).
                X = jnp.where(alive[None], X1, X)
                alive = alive & ((~hit & ~expired) | (cand & ~at_end))
                return (X, k + 1, miss, row, p, alive, queue, found, stats + S * bump["path_steps"])

            c = jax.lax.while_loop(more, one_step, (X, k, miss, row, p, alive, queue, found, stats))
            X, k, miss, row, p, alive, queue, found, stats = c
            n_alive = jnp.sum(alive, dtype=jnp.int32)
            bufs = bufs[:s] + ((X, k, miss, row, p, alive),) + bufs[s + 1 :]
            if below:

                def compact(bufs):
                    S2 = sizes[s + 1]
                    take = alive.astype(jnp.int32)
                    before = jnp.cumsum(take, dtype=jnp.int32) - take
                    src = (
                        jnp.zeros(S2, jnp.int32)
                        .at[jnp.where(alive, before, S2)]
                        .set(jnp.arange(S, dtype=jnp.int32), mode="drop")
                    )
                    new = (X[:, src], k[src], miss[src], row[src], p[src],
                           jnp.arange(S2) < n_alive)  # fmt: skip
                    return bufs[: s + 1] + (new,) + bufs[s + 2 :]

                last = n_alive <= below
                bufs = jax.lax.cond(last, compact, lambda b: b, bufs)
                stage = jnp.where(last, s + 1, stage)
            return stage, n_alive, bufs, queue, found, stats

        return run

    def refine(carry):
        stage, n_alive, bufs, queue, found, stats = carry
        qn = queue["n"]
        span0 = jnp.int32(Q)

        def more(c):
            return c[0] < qn

        def one_span(c):
            lo, span, out = c
            n = jnp.minimum(span, qn - lo)
            ok, f, fr, st, m, u, splits = _refine_span(
                rows_t, depths, tol, tree_key, layout, caps, level, queue, lo, n
            )
            # A single candidate whose open intervals outgrow the largest buffer (never met:
            # it would need 2 * MIN_INTERVALS undecided halves at one level) is left
            # unrefined and counted as unresolved, rather than looping.
            given_up = ~ok & (n <= 1)
            done = ok | given_up
            at = jnp.where(done & (jnp.arange(caps[0]) < n), lo + jnp.arange(caps[0]), Q)
            f0, fr0, st0, m0, u0, s0 = out
            out = (
                f0.at[at].set(f & ok, mode="drop"), fr0.at[at].set(fr, mode="drop"),
                st0.at[:, at].set(st, mode="drop"),
                m0.at[at].set(jnp.where(ok, m, 0.0), mode="drop"),
                u0.at[at].set(u | given_up, mode="drop"), s0 + jnp.where(ok, splits, 0),
            )  # fmt: skip
            return jnp.where(done, lo + n, lo), jnp.where(done, span, jnp.maximum(n // 2, 1)), out

        out = (
            jnp.zeros(Q, bool), jnp.ones(Q), jnp.zeros((d, Q)), jnp.zeros(Q), jnp.zeros(Q, bool),
            jnp.zeros((), jnp.int32),
        )  # fmt: skip
        _, _, out = jax.lax.while_loop(more, one_span, (jnp.int32(0), span0, out))
        hit_in, frac, state, rmiss, unres, splits = out
        # Resolution: a path's stick is in its earliest candidate that holds a crossing. Its
        # last candidate ends at or above the level; should the refinement find no crossing
        # there (an end within rounding of the level), the stick is the step's end.
        entry = jnp.arange(Q) < qn
        qrow, qstep = queue["row"], queue["step"]
        ended = ~hit_in & (cross(queue["b"]) >= level)
        hit = entry & (hit_in | ended)
        best = (
            found["step"]
            .at[jnp.where(entry, qrow, N)]
            .min(jnp.where(hit, qstep, _NONE), mode="drop")
        )
        at = jnp.where(hit & (qstep == best[qrow]), qrow, N)
        found = dict(
            step=best,
            frac=found["frac"].at[at].set(jnp.where(hit_in, frac, 1.0), mode="drop"),
            state=found["state"]
            .at[:, at]
            .set(jnp.where(hit_in[None], state, queue["b"]), mode="drop"),
            miss=found["miss"].at[at].set(queue["miss"], mode="drop"),
        )
        # A candidate was needed if no earlier one of its path holds the stick (its bounds
        # count in the miss bound; the others were stepped past in vain).
        needed = entry & (qstep <= best[qrow])
        stats = (
            stats + qn * bump["candidates"] + splits * bump["refined_nodes"]
            + jnp.sum(entry & unres) * bump["unresolved"]
            + jnp.sum(jnp.where(needed, rmiss, 0.0)) * bump["refined_miss"]
            + jnp.sum(entry & ~needed) * bump["speculated"]
        )  # fmt: skip
        return stage, n_alive, bufs, dict(queue, n=jnp.zeros((), jnp.int32)), found, stats

    steppers = [stepper(s) for s in range(len(sizes))]

    def round_(carry):
        carry = jax.lax.switch(carry[0], steppers, carry)
        n_alive, qn = carry[1], carry[3]["n"]
        due = (qn > 0) & ((n_alive == 0) | (qn + n_alive > Q))
        return jax.lax.cond(due, refine, lambda c: c, carry)

    def unfinished(carry):
        return (carry[1] > 0) | (carry[3]["n"] > 0)

    n0 = jnp.sum(start[5], dtype=jnp.int32)
    carry = (first_stage, n0, bufs, queue, found, stats)
    _, _, _, _, found, stats = jax.lax.while_loop(unfinished, round_, carry)
    stuck = found["step"] != _NONE
    t_stick = jnp.where(stuck, (found["step"].astype(jnp.float64) + found["frac"]) * dt, jnp.nan)
    t_stick = jnp.where(immediate, 0.0, t_stick)
    table = jnp.concatenate(
        [X0, found["state"], t_stick[None], found["miss"][None], x_start[None]], axis=0
    )
    return jnp.concatenate([table.ravel(), stats])


def first_passages(run, N, paths):
    """`host.HostRun._chunk` on the device scheduler: onset states, stick states, stick times,
    whether located, miss bounds and onset positions of the paths `paths` (one chunk, at most
    `N` paths: the buffer of the run's program), from one compiled call and one copy to the
    host."""
    count = paths.size
    path = np.zeros(N, dtype=np.uint32)
    path[:count] = paths
    d = len(run.model.state_names)
    program = run.device_program(N)
    rows_t, _ = bridge.packed(run.solver.bridge)
    keys = run.keys
    flat = program(
        rows_t, np.asarray(run.depths, np.int32), np.asarray(run.tol), np.int32(run.n_steps),
        run.dt_arr, keys["step"], keys["tree"], keys["onset"], path, np.int32(count), paths=0,
    )  # fmt: skip
    flat = np.asarray(flat)  # (the one copy to the host)
    run.count_call(1)
    if run.bar is not None:
        run.bar.update(count)
    table = flat[: (2 * d + 3) * N].reshape(2 * d + 3, N)[:, :count]
    counts = dict(zip(_STATS, flat[(2 * d + 3) * N :].tolist(), strict=True))
    run.refined_miss += counts.pop("refined_miss")
    for name, value in counts.items():
        run.stats[name] = run.stats.get(name, 0) + int(round(value))
    X0, stick_state = table[:d], table[d : 2 * d].copy()
    t_stick, miss, x_start = table[2 * d].copy(), table[2 * d + 1].copy(), table[2 * d + 2]
    return X0, stick_state, t_stick, np.ones(count, dtype=bool), miss, x_start


def program_for(run, N: int) -> _compile.Fixed:
    """The compiled program of a chunk buffer of `N` paths for the run `run` (its model and
    solver fixed; one executable for all runs of a model structure and buffer size)."""
    _, layout = bridge.packed(run.solver.bridge)
    return _compile.Fixed(
        _program, run.model, run.solver, bool(run.cfg.smooth), layout, stepping_sizes(N),
        interval_sizes(N), timer=run.timer,
    )  # fmt: skip
