"""Exact-in-law stick detection (the bridge detector, `stickslip._simulate.bridge`).

Checked against things it did not produce: the independent reference histograms at coarse
steps, a fine-step grid-monitored run on a second parameter set, the bridge law computed
independently by numerical integration, and Rice's exact upcrossing count of the bridge.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import chi2_homogeneity, without_zero_pile
from scipy import linalg, special

import stickslip as ss
from stickslip._jax import jax, jnp
from stickslip._simulate import bridge

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
# A second set: another natural frequency, damping, noise and correlation time.
SECOND = dict(omega0=2.0, zeta=0.2, D=0.5, v_b=1.0, x0=1.0, tau=0.3)


def _against_reference(ens, reference):
    """Chi-square homogeneity of the slip-time and slip-distance histograms with the
    reference (p > 1e-3) and both means within 4 combined standard errors."""
    meta = reference["meta"]
    n_ref = meta["mc"]["n_paths"]
    assert ens.fraction_stuck == pytest.approx(1.0, abs=1e-4)
    ours, _ = np.histogram(ens.slip_time[ens.stuck], bins=reference["T_edges"])
    stat, dof, p = chi2_homogeneity(ours, reference["T_counts"])
    assert p > 1e-3, ("slip_time", stat, dof, p)
    # The reference piles its first-step sticks at d = 0 (grid convention; see
    # `without_zero_pile`): compare with that bin merged into its neighbour.
    edges = reference["d_edges"]
    ours, _ = np.histogram(ens.slip_distance[ens.stuck], bins=edges)
    theirs = without_zero_pile(reference["d_counts"], edges)
    stat, dof, p = chi2_homogeneity(without_zero_pile(ours, edges), theirs)
    assert p > 1e-3, ("slip_distance", stat, dof, p)
    for name, key in (("slip_time", "T"), ("slip_distance", "d")):
        mean, se = ens.mean(name)
        se_ref = meta[f"std_{key}"] / math.sqrt(n_ref)
        assert abs(mean - meta[f"mean_{key}"]) < 4 * math.hypot(se, se_ref), (name, mean)


@pytest.mark.parametrize("dt", [0.2, 0.1])
def test_coarse_steps_match_the_reference(Langevin, reference, dt):
    """At dt = 0.2 the old in-step cubic put the mean slip time 14 % high (3.634 against
    3.177); the bridge detector is exact in law at any step."""
    ens = ss.simulate(Langevin(**PUBLIC), 40_000, dt, 30.0, seed=21)
    assert ens.info["detector"] == "bridge"
    _against_reference(ens, reference)
    assert ens.stats["unresolved"] == 0
    assert ens.stats["unlocated"] == 0


@pytest.mark.slow
@pytest.mark.parametrize("dt", [0.2, 0.1])
def test_coarse_steps_match_the_reference_full_size(Langevin, reference, dt):
    ens = ss.simulate(Langevin(**PUBLIC), 200_000, dt, 30.0, seed=22)
    _against_reference(ens, reference)


def _second_set(Langevin, n, seed, fine_dt):
    m = Langevin(**SECOND)
    fine = ss.simulate(m, n, fine_dt, 40.0, seed=seed, monitor="grid")
    coarse = {dt: ss.simulate(m, n, dt, 40.0, seed=seed + 1) for dt in (0.2, 0.1)}
    mean_f, se_f = fine.mean("slip_time")
    for dt, ens in coarse.items():
        assert ens.fraction_stuck == pytest.approx(1.0, abs=1e-3)
        mean, se = ens.mean("slip_time")
        assert abs(mean - mean_f) < 4 * math.hypot(se, se_f), (dt, mean, mean_f)
        ours, edges = np.histogram(ens.slip_time[ens.stuck], bins=60, range=(0.0, 6.0))
        theirs, _ = np.histogram(fine.slip_time[fine.stuck], bins=edges)
        assert chi2_homogeneity(ours, theirs)[2] > 1e-3, dt


def test_second_set_coarse_steps_match_a_fine_grid_run(Langevin):
    """omega0 = 2, tau = 0.3: dt = 0.2 and 0.1 against the classic grid convention at a
    fine step (its bias, about -0.2 % at dt = 0.005 on the public set, is far below the
    sampling error here)."""
    _second_set(Langevin, 10_000, seed=31, fine_dt=0.005)


@pytest.mark.slow
def test_second_set_coarse_steps_match_a_fine_grid_run_full_size(Langevin):
    _second_set(Langevin, 200_000, seed=33, fine_dt=0.002)


def test_tolerance_changes_cost_not_law(Langevin):
    """A loose and a tight tolerance give the same law; the tighter one reports a smaller
    bound on missed crossings and refines more."""
    m = Langevin(**PUBLIC)
    loose = ss.simulate(m, 20_000, 0.2, 30.0, seed=41, crossing_tol=1e-2)
    tight = ss.simulate(m, 20_000, 0.2, 30.0, seed=42, crossing_tol=1e-7)
    assert tight.stats["miss_bound"] < loose.stats["miss_bound"]
    assert tight.stats["refined_nodes"] > loose.stats["refined_nodes"]
    (a, sa), (b, sb) = loose.mean("slip_time"), tight.mean("slip_time")
    assert abs(a - b) < 4 * math.hypot(sa, sb)
    assert tight.info["crossing_tol"] == 1e-7


def test_detector_choice(Langevin):
    base = dict(PUBLIC)
    cases = [
        (base, {}, "bridge"),
        (base | {"D": 0.0}, {}, "cubic"),  # noise-free: the exact flow, located to 1e-8
        (base, {"solver": "euler"}, "cubic"),
        (base | {"tau": None}, {}, "brownian"),
        (base, {"monitor": "grid"}, "grid"),
    ]
    # The choice is made when a run is set up (`HostRun`: no simulation, nothing compiled for
    # the four other detectors, each a program of its own); the first case runs, and says
    # it in the ensemble's `info`.
    from stickslip._rng import seed_key
    from stickslip._simulate.host import HostRun

    for params, kwargs, detector in cases:
        model = Langevin(**params)
        run = HostRun("simulate", model, kwargs.get("solver", "auto"),
                   kwargs.get("monitor", "continuous"), 0.05, 5.0, seed_key(1))  # fmt: skip
        assert run.info(model)["detector"] == detector, (params, kwargs)
    ens = ss.simulate(Langevin(**base), 200, 0.05, 5.0, seed=1)
    assert ens.info["detector"] == "bridge"


def test_paths_that_never_stuck_have_no_stick_state(Langevin):
    ens = ss.simulate(Langevin(**PUBLIC), 2000, 0.2, 1.0, seed=5)
    assert 0 < np.sum(~ens.stuck) < 2000
    assert np.all(np.isnan(ens.stick_state[~ens.stuck]))
    assert np.all(np.isfinite(ens.stick_state[ens.stuck]))


def test_bad_tolerance_is_named(Langevin):
    with pytest.raises(ValueError, match="crossing_tol"):
        ss.simulate(Langevin(**PUBLIC), 10, 0.1, 1.0, crossing_tol=0.0)
    with pytest.raises(ValueError, match="crossing_tol"):
        ss.simulate(Langevin(**PUBLIC), 10, 0.1, 1.0, crossing_tol=1.5)


def test_depth_follows_the_model_time_scale(Langevin):
    for params in (PUBLIC, SECOND, PUBLIC | {"tau": 0.01}):
        A = np.asarray(Langevin(**params).linear_gaussian().A)
        rho = np.max(np.abs(np.linalg.eigvals(A)))
        for h in (0.02, 0.2, 1.0):
            depth = bridge.depth_for(A, h, bridge.LOCATE_SCALE)
            finest = h / 2.0**depth * rho
            assert finest <= bridge.LOCATE_SCALE
            assert depth == 1 or finest > bridge.LOCATE_SCALE / 2


# -- the bridge law, computed independently --------------------------------------------


def _law(A, B, t):
    """Phi(t) and Sigma(t) by Van Loan's block exponential with scipy's expm (an independent
    method; it is well conditioned at these lags)."""
    d = A.shape[0]
    M = np.block([[-A, B @ B.T], [np.zeros((d, d)), A.T]]) * t
    F = linalg.expm(M)
    Phi = F[d:, d:].T
    Sig = Phi @ F[:d, d:]
    return Phi, 0.5 * (Sig + Sig.T)


def _bridge_at(A, B, h, s):
    """Mean coefficients (P, G) and covariance K of X(s) given X(0) and X(h) (b = 0)."""
    Phi_h, Sig_h = _law(A, B, h)
    Phi_s, Sig_s = _law(A, B, s)
    Phi_r, _ = _law(A, B, h - s)
    G = Sig_s @ Phi_r.T @ np.linalg.inv(Sig_h)
    return Phi_s - G @ Phi_h, G, Sig_s - G @ Phi_r @ Sig_s


@pytest.mark.parametrize("host", [True, False], ids=["numpy", "traced"])
@pytest.mark.parametrize("params, h", [(PUBLIC, 0.2), (SECOND, 0.1)])
def test_midpoint_tables_are_the_bridge_law(Langevin, params, h, host):
    """Both builds of the tables: NumPy (what the simulator uses) and traced."""
    lg = Langevin(**params).linear_gaussian()
    A, B = np.asarray(lg.A), np.asarray(lg.B)
    if host:
        T = bridge.bridge_tables(lg.A, lg.b, lg.B, lg.crossing, h, host=True)
    else:
        T = jax.jit(bridge.bridge_tables)(lg.A, lg.b, lg.B, lg.crossing, h)
    for j in (0, 3):
        P, G, K = _bridge_at(A, B, h / 2**j, h / 2 ** (j + 1))
        np.testing.assert_allclose(np.asarray(T.mid_P[..., j]), P, atol=1e-9)
        np.testing.assert_allclose(np.asarray(T.mid_G[..., j]), G, atol=1e-9)
        Lm = np.asarray(T.mid_L[..., j])
        scale = np.sqrt(np.outer(np.diag(K), np.diag(K)))
        np.testing.assert_allclose((Lm @ Lm.T) / scale, K / scale, atol=1e-7)


def _rice_exact(A, B, c, h, Xa, Xb, level, nodes=500):
    """Rice's expected upcrossings of the bridge (ends `Xa`, `Xb` `(d, n)`), with
    E[a^+ | v = L] in closed form, by a fine midpoint rule: an independent evaluation of the
    integral that the tables bound."""
    r = A.T @ c
    total = np.zeros(Xa.shape[1])
    for s in (np.arange(nodes) + 0.5) * h / nodes:
        P, G, K = _bridge_at(A, B, h, s)
        mean = P @ Xa + G @ Xb
        mv, ma = c @ mean, r @ mean
        vv, va, aa = c @ K @ c, c @ K @ r, r @ K @ r
        m = ma + va / vv * (level - mv)
        sd = math.sqrt(aa - va * va / vv)
        e_plus = sd * np.exp(-0.5 * (m / sd) ** 2) / math.sqrt(2 * math.pi)
        e_plus += m * special.ndtr(m / sd)
        dens = np.exp(-0.5 * (level - mv) ** 2 / vv) / math.sqrt(2 * math.pi * vv)
        total += dens * e_plus * h / nodes
    return total


@pytest.mark.parametrize("h", [0.1, pytest.param(0.4, marks=pytest.mark.slow)])
def test_certified_steps_have_small_rice_counts(Langevin, h):
    """On steps drawn from the slip's own law near the level, a step the tables certify
    (bound <= tol) has Rice's exact expected upcrossing count, which bounds its crossing
    probability, within a few tol, and the certified steps' summed exact counts are within
    a factor 2 of their summed bounds (the reported miss bound). The 8-node quadrature is
    not a strict bound: it can miss a boundary layer at an end close to the level
    (measured on 3000 such steps: exact count of a certified step at most 3.1 tol)."""
    lg = Langevin(**PUBLIC).linear_gaussian()
    A, B, c = (np.asarray(x) for x in (lg.A, lg.B, lg.crossing))
    rng = np.random.default_rng(7)
    n = 500
    Xa = np.stack([rng.uniform(-1, 1, n), rng.uniform(0.9, 1.0, n), rng.normal(0, 2, n)])
    Phi, Sig = _law(A, B, h)
    Xb = Phi @ Xa + np.linalg.cholesky(Sig) @ rng.standard_normal((3, n))
    ends_below = Xb[1] < 1.0
    Xa, Xb = Xa[:, ends_below], Xb[:, ends_below]
    T = bridge.bridge_tables(lg.A, lg.b, lg.B, lg.crossing, h, host=True)  # as simulated
    ours = np.asarray(bridge.expected_upcrossings(T, jnp.asarray(Xa), jnp.asarray(Xb), 1.0))
    exact = _rice_exact(A, B, c, h, Xa, Xb, 1.0)
    tol = 1e-5
    certified = ours <= tol
    assert 20 < np.sum(~certified) and 20 < np.sum(certified & (exact > 1e-9))
    assert np.max(exact[certified]) < 4 * tol
    assert np.sum(exact[certified]) < 2 * np.sum(ours[certified])
    # Where the bridge mean reaches the level (a peak the nodes could step over) the bound
    # is infinite: such a step is always refined.
    assert np.all(exact[np.isinf(ours)] > 1e-3)


# -- the compiled refinement against a depth-first one -------------------------------------


# Compiled like the simulator's (eagerly evaluated, the float32 normals can differ in their
# last bits: XLA contracts multiply-adds in compiled code).
_midpoint = jax.jit(
    lambda T, a, b, key, *ids: bridge.midpoint(T, a, b, ss._rng.tree_normals(key, *ids, 3))
)
_bound = jax.jit(bridge.expected_upcrossings)


def _depth_first(T_levels, key, level, depths, tol, Xa, Xb, path, step):
    """The refinement of the module docstring, depth first and one candidate at a time, in
    plain Python: the same draws (keyed by path, step and tree node) and the same bounds,
    none of the compiled version's breadth-first bookkeeping (buffers, compaction, owners,
    hand-backs). Returns `(found, frac, state, miss)` for one candidate."""
    locate, certify = depths
    c = np.asarray(T_levels[0].crossing)[:, 0]
    miss = 0.0

    def draw(j, pos, a, b):
        ids = (np.uint32([path]), np.uint32([step]), np.uint32([2**j + pos]))
        return np.asarray(_midpoint(T_levels[j], a[:, None], b[:, None], key, *ids))[:, 0]

    def bound(j, a, b):
        return float(_bound(T_levels[j], a[:, None], b[:, None], level)[0])

    def search(j, pos, a, b):
        """First crossing inside interval `pos` of level `j` (open: it ends above the level
        or its bound is above tol)."""
        nonlocal miss
        m = draw(j, pos, a, b)
        for r, (x0, x1) in enumerate(((a, m), (m, b))):
            k, p = j + 1, 2 * pos + r
            if c @ x1 >= level:
                onset = c @ x0 >= level
                if k >= locate and (not onset or k == certify):
                    f = 0.5 if onset else (level - c @ x0) / (c @ x1 - c @ x0)
                    return True, (p + f) / 2.0**k, x0 + f * (x1 - x0)
                return search(k, p, x0, x1)  # it holds a crossing: found in there
            q = bound(k, x0, x1)
            if q <= tol:
                miss += q
            elif k == certify:
                miss += min(q, 1.0)
            else:
                hit = search(k, p, x0, x1)
                if hit[0]:
                    return hit
        return False, 1.0, b

    found, frac, state = search(0, 0, Xa, Xb)
    return found, frac, state, miss


@pytest.mark.parametrize("dt", [0.1, 1.6])
def test_compiled_refinement_is_the_depth_first_one(Langevin, dt, monkeypatch):
    """Candidate steps of a real run, refined by the simulator (breadth first, compiled,
    small buffers and batches so that every hand-back is exercised) and by the depth-first
    reference: the same sticks, to rounding. The breadth-first miss bound may be larger: it
    sums the bounds of halves that a crossing found later, at a deeper level, places after
    the stick. The run's own candidates are mostly decided within a level or two, so the
    same candidates are refined again moved just below the level, where their halves stay
    open level after level and outgrow their buffer (`GROW`)."""
    from stickslip._simulate import host

    monkeypatch.setattr(bridge, "CAPACITIES", (256, 512))
    monkeypatch.setattr(bridge, "BATCH", 256)
    model = Langevin(**PUBLIC)
    run = host.HostRun("test", host.to_arrays(model), "auto", "continuous", dt, 30.0,
                      ss._rng.seed_key(5))  # fmt: skip
    got, statuses = [], []
    original, call = bridge.Refiner.first_crossing, bridge.Refiner._call

    def spy(self, Xa, Xb, path, step):
        out = original(self, Xa, Xb, path, step)
        got.append(((Xa, Xb, path, step), out))
        return out

    def spy_call(self, *args, **kwargs):
        out = call(self, *args, **kwargs)
        statuses.append(int(out[-1]))
        return out

    monkeypatch.setattr(bridge.Refiner, "first_crossing", spy)
    monkeypatch.setattr(bridge.Refiner, "_call", spy_call)
    run.first_passages(np.arange(600, dtype=np.uint32), 600)
    (Xa, Xb, path, step), _ = got[0]
    near = Xa.copy(), Xb.copy()
    for X in near:
        X[1] = PUBLIC["v_b"] * (1 - 1e-5)  # v, the crossing variable
    run.refiner().first_crossing(*near, path, step)  # (through the spy: checked below)
    assert {bridge.GROW, bridge.SHRINK, bridge.DONE} <= set(statuses), set(statuses)
    T = run.solver.bridge
    levels = [jax.tree_util.tree_map(lambda x, j=j: np.asarray(x)[..., j : j + 1], T)
              for j in range(bridge.MAX_DEPTH + 1)]  # fmt: skip
    checked = 0
    for (Xa, Xb, path, step), (found, frac, state, miss, _, _) in got:
        for i in range(0, Xa.shape[1], 7):  # a sample of the candidates of every pass
            ref = _depth_first(levels, run.keys["tree"], 1.0, run.depths, run.tol,
                               Xa[:, i], Xb[:, i], path[i], step[i])  # fmt: skip
            assert found[i] == ref[0]
            assert frac[i] == pytest.approx(ref[1], abs=1e-12)
            np.testing.assert_allclose(state[:, i], ref[2], atol=1e-12)
            # Each candidate's miss bound bounds the depth-first one.
            assert miss[i] >= ref[3] * (1 - 1e-9)
            checked += 1
    assert checked > 300 and sum(np.sum(o[0]) for _, o in got) > 100


def test_stepping_past_candidates_finds_the_same_sticks(Langevin, monkeypatch):
    """Small buffers step past candidate steps that end below the level and refine them all
    at the end (`host.SPECULATE_BELOW`): the same sticks, bit for bit, as refining each
    candidate before stepping on (the scheme checked against the depth-first reference
    above), although some paths were stepped past the step that holds their stick."""
    from stickslip import _compile
    from stickslip._simulate import host

    # (each run on the buffers it wants: no other size stands in for its first one, so the
    # stepping calls counted below are each scheme's own)
    monkeypatch.setattr(_compile, "STAND_IN", 0)
    model = Langevin(**PUBLIC)
    runs = []
    # Never; always, by the host between stepping calls; always, inside the stepping loop
    # (up to 2 per path and call, `host.PAST_SLOTS`; the host takes the rest: here ~40 %
    # of the paths fill both slots in some call, ~20 % end a call just past one).
    for below, slots in ((0, 2), (1 << 30, 0), (1 << 30, 2)):
        monkeypatch.setattr(host, "SPECULATE_BELOW", below)
        monkeypatch.setattr(host, "PAST_SLOTS", slots)
        runs.append(ss.simulate(model, 3000, 0.8, 30.0, seed=4, solver="exact", progress=False))
    each, *pasts = runs
    assert "speculated" not in each.stats
    for past in pasts:
        np.testing.assert_array_equal(past.slip_time, each.slip_time)
        np.testing.assert_array_equal(past.slip_distance, each.slip_distance)
        np.testing.assert_array_equal(past.stick_state, each.stick_state)
        # Candidates refined past a path's stick: work that refining each first does not
        # do, and that the miss bound does not count.
        extra = past.stats["candidates"] - each.stats["candidates"]
        assert extra == past.stats["speculated"] > 0.1 * each.stats["candidates"]
        assert past.stats["miss_bound"] == pytest.approx(each.stats["miss_bound"], rel=1e-12)
    # Stepping past inside the loop saves stepping calls.
    calls = [past.stats["buffers"] for past in pasts]
    assert calls[0] > calls[1]
    assert np.isfinite(each.slip_time).mean() > 0.99


def test_stepped_past_candidates_are_settled_in_step_order(Langevin, monkeypatch):
    """`_settle` by hand: a path's stick is in its first candidate (in step order, whatever
    the order recorded) that holds a crossing; a last candidate that ends at the level but
    whose refinement finds none (rounding) places the stick at its end; the miss bound is
    the stepping bound at the stick plus the refinements of the candidates up to it."""
    from stickslip._simulate import host

    run = host.HostRun("test", host.to_arrays(Langevin(**PUBLIC)), "exact", "continuous",
                      0.5, 30.0, ss._rng.seed_key(1))  # fmt: skip
    below, above = np.array([[0.5], [0.9], [0.0]]), np.array([[0.4], [1.0], [0.0]])
    # Path rows 0 and 1. Row 0: steps 2 (crossing found at 0.25), 5; row 1: steps 3, 4
    # (none found; step 4 ends at the level). Recorded in two rounds, out of order.
    rounds = [
        (np.array([0, 1]), np.array([5.0, 4.0]), np.array([0.3, 0.7]), np.array([9, 8]),
         np.hstack([below, below]), np.hstack([above, above])),
        (np.array([1, 0]), np.array([3.0, 2.0]), np.array([0.2, 0.1]), np.array([8, 9]),
         np.hstack([below, below]), np.hstack([below, below])),
    ]  # fmt: skip

    def refine(cand, Xa, Xb, step, path):
        found = step[cand] == 2.0
        frac = np.where(found, 0.25, 1.0)
        return found, frac, Xa[:, cand] + 0.01, np.full(cand.size, 1e-3)

    monkeypatch.setattr(run, "_refine", refine)
    t_stick, state, miss = np.full(2, np.nan), np.zeros((3, 2)), np.zeros(2)
    run._settle(rounds, t_stick, state, miss)
    np.testing.assert_allclose(t_stick, [2.25 * 0.5, 5.0 * 0.5])
    np.testing.assert_allclose(state[:, 0], below[:, 0] + 0.01)
    np.testing.assert_allclose(state[:, 1], above[:, 0])
    np.testing.assert_allclose(miss, [0.1, 0.7])
    # Row 0's step 5 came after its stick: neither its refinement nor its bound counts.
    assert run.refined_miss == pytest.approx(3e-3) and run.stats["speculated"] == 1


def test_refinement_in_two_threads_is_the_one_thread_one(Langevin, monkeypatch):
    """Candidates enough for two threads (the first step of 5000 paths: every slip's onset):
    the same refinements as in one thread, candidate by candidate, whatever the threads'
    order (the one-thread refinement is checked against the depth-first reference above);
    and in one thread in several batches of equal size."""
    from stickslip import _compile
    from stickslip._simulate import host

    # (one chunk on its own buffer, refined in batches of the size wanted: no other size
    # stands in for them)
    monkeypatch.setattr(_compile, "STAND_IN", 0)
    model = Langevin(**PUBLIC)
    run = host.HostRun("test", host.to_arrays(model), "auto", "continuous", 0.8, 30.0,
                      ss._rng.seed_key(7))  # fmt: skip
    got = []
    original = bridge.Refiner.first_crossing

    def spy(self, Xa, Xb, path, step):
        got.append((Xa.copy(), Xb.copy(), path.copy(), step.copy()))
        return original(self, Xa, Xb, path, step)

    monkeypatch.setattr(bridge.Refiner, "first_crossing", spy)
    run.first_passages(np.arange(5000, dtype=np.uint32), 5000)
    cands = got[0]
    assert cands[0].shape[1] >= 2 * bridge.CAPACITIES[1]
    refiner, part = run._refiner, bridge.Refiner._refine_part
    calls = []
    for threads in (2, 1):
        monkeypatch.setattr(bridge, "_threads", lambda threads=threads: threads)
        parts = []

        def spy_part(self, *a, parts=parts):
            parts.append(a[4:6])  # the candidates lo:hi of the part
            return part(self, *a)

        monkeypatch.setattr(bridge.Refiner, "_refine_part", spy_part)
        calls.append((original(refiner, *cands), parts))
    # One thread, in batches of at most 1500 candidates: as few as that allows, of equal size.
    monkeypatch.setattr(bridge.Refiner, "_refine_part", part)
    monkeypatch.setattr(bridge, "BATCH", 1500)
    sizes = []
    call = bridge.Refiner._call

    def spy_call(self, j, *a, sizes=sizes, **kw):
        if j == 0:
            sizes.append(a[-1])  # a batch's first call: its candidates
        return call(self, j, *a, **kw)

    monkeypatch.setattr(bridge.Refiner, "_call", spy_call)
    batched = original(refiner, *cands)
    (two, parts2), (one, parts1) = calls
    assert len(parts2) == 2 and len(parts1) == 1
    n = cands[0].shape[1]
    assert len(sizes) == -(-n // 1500) and sum(sizes) == n and max(sizes) - min(sizes) <= 1
    for other in (two, batched):
        for a, b in zip(other[:3] + other[4:], one[:3] + one[4:], strict=True):
            np.testing.assert_array_equal(a, b)
        assert other[3] == pytest.approx(one[3], rel=1e-12)
    assert np.sum(one[0]) > 100
