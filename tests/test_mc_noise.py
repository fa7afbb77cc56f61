"""The simulation's noise in a fit's estimate: the delete-a-block jackknife over the cycles
simulated at the design points (`intervals._jackknife`), checked against the spread of the
vertex itself over many independent draws of the noise (a Monte Carlo of the statistic,
not of the code's formula)."""

import dataclasses

import numpy as np

from stickslip._inference import intervals
from stickslip._inference.surface import _Surface, polynomial_vertex, quadratic_design


def _surface(design, centre, steps):
    return _Surface(centre=centre, steps=steps, nominal=design, design=design, values=[],
                    scores=[], shift=None, hessian=np.eye(centre.size), clipped=[])  # fmt: skip


def test_jackknife_of_the_vertex_matches_its_spread_over_draws():
    """A quadratic surface in two parameters (a ridge: correlated curvature) whose value at
    each design point is the mean of B blocks' contributions, each block with its own
    random tilt shared by every point (common random numbers) and its own point noise.
    Over 600 draws the mean jackknife variance of the vertex matches the vertex's own
    variance within three times the sampling error of that variance (sd sqrt(2/600) = 6 %)
    and 5 % more for the jackknife's own upward bias on a nonlinear statistic (measured
    here: 12-14 %, a slightly conservative interval)."""
    rng = np.random.default_rng(11)
    B = 10
    centre, steps = np.zeros(2), np.array([0.3, 0.2])
    design = quadratic_design(centre, steps)
    du = design - centre
    A = np.array([[40.0, -30.0], [-30.0, 30.0]])  # the information: a ridge
    truth = -0.5 * np.einsum("ji,ik,jk->j", du - [0.05, -0.03], A, du - [0.05, -0.03])
    vertices, jack = [], []
    for _ in range(600):
        tilt = rng.normal(0.0, 0.3, (B, 2))  # a block's smooth part: shared by the points
        point = rng.normal(0.0, 0.3, (B, len(design)))  # and its rough part
        contrib = tilt @ du.T + point  # (B, points)
        full = truth + contrib.mean(axis=0)
        x, _ = polynomial_vertex(du, full, steps)
        loo = np.stack([truth + np.delete(contrib, b, axis=0).mean(axis=0) for b in range(B)], 1)
        C = intervals._jackknife(_surface(design, centre, steps), loo)
        if x is None or C is None:
            continue
        vertices.append(x)
        jack.append(np.diag(C))
    assert len(vertices) > 550
    spread = np.var(np.array(vertices), axis=0, ddof=1)
    ratio = np.mean(jack, axis=0) / spread
    assert np.all(np.abs(ratio - 1) < 3 * np.sqrt(2 / len(vertices)) + 0.05), ratio


def test_without_a_vertex_in_most_replicates_there_is_no_jackknife():
    """A flat surface (noise alone): most replicates have no maximum near the centre, and
    the jackknife says so (`None`) rather than give a covariance."""
    rng = np.random.default_rng(12)
    centre, steps = np.zeros(2), np.array([0.3, 0.3])
    design = quadratic_design(centre, steps)
    loo = rng.normal(0.0, 1.0, (len(design), 10))
    assert intervals._jackknife(_surface(design, centre, steps), loo) is None


def test_block_values_are_the_likelihood_without_each_block():
    """`jackknife_values` bins each block once and subtracts it, and convolves by FFT; the
    same numbers (to rounding: 1e-12 of the value) as the log-likelihood scored on the
    simulated cycles with that block cut out (zero sticks, infinite slips and all)."""
    from stickslip._inference.data import to_fit_scale
    from stickslip._inference.likelihood import bandwidth_of, jackknife_values, scored_samples

    rng = np.random.default_rng(3)
    data = {k: rng.lognormal(0, 0.5, 200) for k in ("slip_time", "stick_time", "slip_distance")}
    data["stick_time"][:30] = 0
    sim = {k: rng.lognormal(0.1, 0.6, 5003) for k in data}
    sim["stick_time"][:900] = 0
    sim["slip_time"][5:9] = np.inf
    h = {k: bandwidth_of(to_fit_scale(k, data[k]), 5003) for k in data}
    got = jackknife_values(data, sim, h, None)
    for b in range(got.size):
        cut = {k: np.concatenate([a[: b * a.size // got.size], a[(b + 1) * a.size // got.size :]])
               for k, a in sim.items()}  # fmt: skip
        terms = scored_samples(data, cut, h, None)
        want = sum(np.sum(v) for v in terms.values())
        assert abs(got[b] - want) <= 1e-12 * abs(want)


def _cubic_surface(design, centre, A, g, k):
    du = design - centre
    return g @ du.T - 0.5 * np.einsum("ji,ik,jk->j", du, A, du) + (du**3) @ k


def test_the_plain_bread_is_the_quadratics_curvature_whatever_the_cubic_terms():
    """On the design's symmetric points a cubic term is odd and the curvature even, so the
    plain quadratic's least-squares Hessian is the surface's own quadratic part exactly
    (closed form: -A), where the fit's polynomial at its vertex adds 6 k x; and the bread
    takes the mean of the two seeds' values (noise of opposite sign cancels)."""
    from stickslip._inference.surface import quadratic_hessian

    centre, steps = np.zeros(3), np.array([0.3, 0.2, 0.25])
    design = quadratic_design(centre, steps)
    A = np.array([[40.0, -12.0, 3.0], [-12.0, 25.0, -4.0], [3.0, -4.0, 10.0]])
    f = _cubic_surface(design, centre, A, np.array([2.0, -1.0, 1.5]), np.array([5.0, -8.0, 3.0]))
    assert np.allclose(quadratic_hessian(design - centre, f), -A, atol=1e-9)
    x, H_vertex = polynomial_vertex(design - centre, f, steps)
    assert x is not None and not np.allclose(H_vertex, -A, atol=1e-3)
    e = np.random.default_rng(5).normal(0.0, 1.0, len(design))
    surface = dataclasses.replace(_surface(design, centre, steps), values=list(f + e),
                                  hessian=H_vertex)  # fmt: skip
    plain = intervals.with_plain_bread(surface, f - e)
    assert np.allclose(plain.hessian, -A, atol=1e-9)
    assert plain.shift is surface.shift and plain.values == surface.values


def test_no_plain_bread_where_the_quadratic_is_not_concave():
    """A saddle through both seeds' values (or a polynomial that is not concave), or
    values that do not determine the quadratic, leave the surface as it was: its own check
    then gives no interval."""
    centre, steps = np.zeros(2), np.array([0.3, 0.3])
    design = quadratic_design(centre, steps)
    saddle = _cubic_surface(design, centre, np.diag([10.0, -5.0]), np.zeros(2), np.zeros(2))
    surface = dataclasses.replace(_surface(design, centre, steps), values=list(saddle),
                                  hessian=-np.eye(2))  # fmt: skip
    assert intervals.with_plain_bread(surface, saddle) is surface
    cap = _cubic_surface(design, centre, np.diag([10.0, 5.0]), np.zeros(2), np.zeros(2))
    upward = dataclasses.replace(surface, values=list(cap), hessian=np.eye(2))
    assert intervals.with_plain_bread(upward, cap) is upward
    # a correlated maximum whose pair's diagonal points were lost (a refused model): the
    # cross term is not determined (least squares would read it as 0); no bread from it
    lost = _cubic_surface(design, centre, np.array([[10.0, 3.0], [3.0, 5.0]]), np.zeros(2),
                          np.zeros(2))  # fmt: skip
    lost[np.all(np.abs(design - centre) > 0, axis=1)] = -np.inf
    kept = dataclasses.replace(surface, values=list(lost), hessian=-np.eye(2))
    assert intervals.with_plain_bread(kept, lost) is kept


def test_the_larger_covariance_bounds_both_and_is_the_least_on_common_axes():
    """The larger of two covariances is at least each in every direction (both differences
    positive semidefinite); where they share their axes it is the larger variance on each
    (closed form: diagonal matrices give the elementwise maximum); and where one already
    bounds the other it is that one."""
    rng = np.random.default_rng(11)
    for _ in range(50):
        m, n = rng.normal(size=(2, 3, 3))
        a, b = m @ m.T, n @ n.T
        c = intervals.larger_covariance(a, b)
        assert np.allclose(c, c.T, atol=1e-12)
        for other in (a, b):
            assert np.min(np.linalg.eigvalsh(c - other)) > -1e-10
    a, b = np.diag([1.0, 4.0, 0.5]), np.diag([2.0, 1.0, 0.5])
    assert np.allclose(intervals.larger_covariance(a, b), np.diag([2.0, 4.0, 0.5]))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    rotate = lambda d: q @ d @ q.T  # noqa: E731  (the same axes, turned)
    assert np.allclose(intervals.larger_covariance(rotate(a), rotate(b)),
                       rotate(np.diag([2.0, 4.0, 0.5])))  # fmt: skip
    small = 0.5 * a
    assert np.allclose(intervals.larger_covariance(small, a), a)
    assert np.allclose(intervals.larger_covariance(a, small), a)


def test_the_plain_bread_is_steadier_along_a_weak_direction():
    """A weak direction whose maximum lies a step from the design's centre, each point's
    value noisy (the simulation's roughness): over 400 draws the curvature along it varies
    less from the plain quadratic through the design than from the polynomial at its
    vertex, whose noisy cubic term moves it there (measured: 5.6 times the variance); the
    F ratio of the two variances past 1.5, beyond its 0.1 % point (about 1.4 at these
    degrees of freedom). The plain curvature is unbiased (within 3 standard errors)."""
    from stickslip._inference.surface import quadratic_hessian

    rng = np.random.default_rng(13)
    centre, steps = np.zeros(2), np.array([0.3, 0.3])
    design = quadratic_design(centre, steps)
    du = design - centre
    A = np.diag([200.0, 8.0])
    truth = -0.5 * np.einsum("ji,ik,jk->j", du - [0.0, 0.3], A, du - [0.0, 0.3])
    plain, cubic = [], []
    for _ in range(400):
        values = truth + rng.normal(0.0, 0.3, len(design))
        x, H = polynomial_vertex(du, values, steps)
        if x is None:
            continue
        cubic.append(H[1, 1])
        plain.append(quadratic_hessian(du, values)[1, 1])
    assert len(cubic) > 300
    assert np.var(cubic) / np.var(plain) > 1.5, (np.std(cubic), np.std(plain))
    assert abs(np.mean(plain) + A[1, 1]) < 3 * np.std(plain) / np.sqrt(len(plain))
