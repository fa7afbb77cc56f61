"""Locating a stick inside a step: cubic pieces and the Brownian-bridge hitting time."""

import numpy as np
from scipy import stats

from stickslip._jax import jnp
from stickslip._simulate import localise


def _hermite_np(p0, p1, m0, m1, u):
    h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
    h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
    return p0 * h00 + m0 * h10 + p1 * h01 + m1 * h11


def test_hermite_matches_the_basis():
    rng = np.random.default_rng(0)
    p0, p1, m0, m1 = rng.normal(size=(4, 100))
    u = rng.uniform(size=100)
    np.testing.assert_allclose(
        localise.hermite(p0, p1, m0, m1, u), _hermite_np(p0, p1, m0, m1, u), atol=1e-14
    )


def test_first_upcrossing_against_a_dense_grid():
    rng = np.random.default_rng(1)
    n = 4000
    p0 = rng.uniform(-1.5, 0.0, n)  # starts at or below the level 0
    p0[:100] = 0.0  # exactly at the level (the slip onset)
    p1, m0, m1 = rng.uniform(-1.5, 1.5, n), rng.normal(0, 3, n), rng.normal(0, 3, n)
    m0[:100] = -np.abs(m0[:100])  # falling at onset
    found, lo, hi = localise.first_upcrossing(*map(jnp.asarray, (p0, p1, m0, m1)), 0.0)
    root = np.asarray(localise.bisect(*map(jnp.asarray, (p0, p1, m0, m1)), 0.0, lo, hi))
    u = np.linspace(0, 1, 4001)
    H = _hermite_np(p0[:, None], p1[:, None], m0[:, None], m1[:, None], u[None])
    below = H < 0
    # the first grid point at or above the level after having been below it
    crossed = (~below[:, 1:]) & np.logical_or.accumulate(below[:, :-1], axis=1)
    brute_found = crossed.any(axis=1)
    brute_root = u[1:][np.argmax(crossed, axis=1)]
    # Compare where the grid resolves the crossing unambiguously (no grazes at grid scale).
    margin = np.min(np.abs(H[:, 1:]), axis=1) > 1e-5
    found = np.asarray(found)
    assert np.array_equal(found[margin], brute_found[margin])
    ok = margin & brute_found
    assert np.max(np.abs(root[ok] - brute_root[ok])) <= u[1]
    val = _hermite_np(p0, p1, m0, m1, root)
    assert np.max(np.abs(val[found])) < 1e-12


def test_interior_reaches_against_a_dense_grid():
    rng = np.random.default_rng(2)
    n = 4000
    p0, p1 = rng.uniform(-1, 0, n), rng.uniform(-1, 0, n)
    m0, m1 = rng.normal(0, 3, n), rng.normal(0, 3, n)
    reach = np.asarray(localise.interior_reaches(*map(jnp.asarray, (p0, p1, m0, m1)), 0.0))
    u = np.linspace(0, 1, 4001)[1:-1]
    H = _hermite_np(p0[:, None], p1[:, None], m0[:, None], m1[:, None], u[None])
    top = H.max(axis=1)
    clear = np.abs(top) > 1e-5
    assert np.array_equal(reach[clear], (top >= 0)[clear])


def test_bridge_hitting_time_is_exact():
    """Independent construction: Brownian motion from L - alpha hits L at a Levy time tau;
    after it, W(h) = L + sigma sqrt(h - tau) N. Keeping the draws that end near L - beta gives
    the hitting time of the bridge, to compare with the inverse-Gaussian sampler."""
    rng = np.random.default_rng(3)
    alpha, beta, var, h = 0.3, 0.2, 2.0, 0.5
    n = 4_000_000
    tau = alpha**2 / (var * rng.standard_normal(n) ** 2)
    hit = tau < h
    tau = tau[hit]
    end = np.sqrt(var * (h - tau)) * rng.standard_normal(tau.size)  # W(h) - L
    keep = np.abs(end + beta) < 0.01
    reference = tau[keep] / h
    assert reference.size > 5000
    m = 100_000
    z = jnp.asarray(rng.standard_normal(m))
    u = jnp.asarray(rng.uniform(size=m))
    ours = np.asarray(localise.bridge_crossing_fraction(alpha, beta, var, h, z, u))
    assert stats.ks_2samp(ours, reference).pvalue > 1e-3
    # The in-step test's probability: P(hit | W(0), W(h)) = exp(-2 alpha beta / (var h)).
    n_end = np.sum(np.abs(rng.standard_normal(n) * np.sqrt(var * h) - alpha + beta) < 0.01)
    p_formula = np.exp(-2 * alpha * beta / (var * h))
    p_mc = keep.sum() / n_end
    se = np.sqrt(p_formula * (1 - p_formula) / n_end) + keep.sum() ** 0.5 / n_end
    assert abs(p_mc - p_formula) < 4 * se


def test_bridge_hitting_time_edge_cases():
    z, u = jnp.asarray([0.3, -1.0]), jnp.asarray([0.2, 0.9])
    at_level = localise.bridge_crossing_fraction(0.0, 0.5, 1.0, 0.1, z, u)
    assert np.all(np.asarray(at_level) == 0.0)  # starting on the level: crossing at once
    ends_on = localise.bridge_crossing_fraction(0.5, 0.0, 1.0, 0.1, z, u)
    assert np.all((np.asarray(ends_on) > 0) & (np.asarray(ends_on) <= 1))
    ends_above = localise.bridge_crossing_fraction(0.5, -0.5, 1.0, 0.1, z, u)
    assert np.all((np.asarray(ends_above) > 0) & (np.asarray(ends_above) < 1))
