"""Profile-likelihood intervals (`fit(..., intervals="profile")`): the profile found by
designs in the other parameters against a brute-force profile of a known surface, and the
option end to end on a fit."""

from __future__ import annotations

import math
import sys
import warnings

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

import stickslip as ss
from stickslip._inference.profile import CHI2_95, profile_intervals
from stickslip._inference.surface import local_surface

# A banana: a normal in (a, b - K a^2). The profile of b over a is not the quadratic the
# curvature at the maximum gives, and its interval is known by a 1-D search per b.
SA, SB, K = 1.0, 0.3, 0.6


def banana(u):
    a, b = u
    return -0.5 * ((a / SA) ** 2 + ((b - K * a * a) / SB) ** 2)


class Surface:
    """The fit's `Likelihood` interface on a known function: (value, per-cycle terms)."""

    def __call__(self, u, at_seed=None):
        return banana(np.asarray(u, float)), None


def brute_force_interval(q):
    """Where the profile of b, max over a by a bounded 1-D search, meets q / 2 below the
    maximum (0 at (0, 0)): the two roots by bisection on a fine grid."""

    def profile(b):
        return -minimize_scalar(lambda a: -banana((a, b)), bounds=(-5, 5), method="bounded",
                                options=dict(xatol=1e-10)).fun  # fmt: skip

    def root(lo, hi):
        f = lambda b: 2 * (0.0 - profile(b)) - q  # noqa: E731
        sign = np.sign(f(lo))
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if np.sign(f(mid)) == sign else (lo, mid)
        return 0.5 * (lo + hi)

    return root(-3.0, 0.0), root(0.0, 3.0)


def test_the_profile_follows_a_curved_ridge_that_the_quadratic_misses():
    """The profile interval of b (a maximised) against the brute-force profile of the same
    function: within 2 % of its width; the quadratic at the maximum (Wald, same threshold)
    misses the curve's long side by far more."""
    lo, hi = np.array([-4.0, -4.0]), np.array([4.0, 4.0])
    loglik = Surface()
    surface = local_surface(loglik, np.array([0.05, -0.02]), lo, hi, {}, ["a", "b"], step=0.1)
    H = np.asarray(surface.hessian)
    cov = np.linalg.inv(-H)  # the curvature's own: the adjustment is 1, the threshold q
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ci, records, said = profile_intervals(loglik, surface, cov, None, ["a", "b"],
                                              {"a": "linear", "b": "linear"}, lo, hi)  # fmt: skip
    assert said == []
    assert records["b"]["adjustment"] == pytest.approx(1.0)
    want = brute_force_interval(CHI2_95)
    width = want[1] - want[0]
    assert ci["b"][0] == pytest.approx(want[0], abs=0.02 * width)
    assert ci["b"][1] == pytest.approx(want[1], abs=0.02 * width)
    # a: the profile of a over b is the normal's own (b - K a^2 free): +-1.96 SA exactly
    assert ci["a"][0] == pytest.approx(-1.959964 * SA, abs=0.02 * SA)
    assert ci["a"][1] == pytest.approx(1.959964 * SA, abs=0.02 * SA)
    # the Wald interval of b, from the curvature at the maximum, misses the long side
    wald = 1.959964 * math.sqrt(cov[1, 1])
    assert want[1] - wald > 0.3 * width


def test_an_adjusted_threshold_scales_the_interval():
    """A quadratic surface: the profile interval is the Wald one at the adjusted
    threshold, sqrt(c) times the plain width for a variance c times the curvature's."""
    lo, hi = np.array([-10.0, -10.0]), np.array([10.0, 10.0])
    C = np.array([[1.0, 0.6], [0.6, 2.0]])
    P = np.linalg.inv(C)

    class Quadratic:
        def __call__(self, u, at_seed=None):
            u = np.asarray(u, float)
            return -0.5 * u @ P @ u, None

    surface = local_surface(Quadratic(), np.zeros(2), lo, hi, {}, ["x", "y"], step=0.2)
    ci, records, _ = profile_intervals(Quadratic(), surface, 2.25 * C, None, ["x", "y"],
                                       {"x": "linear", "y": "linear"}, lo, hi)  # fmt: skip
    for i, k in enumerate("xy"):
        half = 1.5 * 1.959964 * math.sqrt(C[i, i])
        assert records[k]["adjustment"] == pytest.approx(2.25, rel=1e-6)
        parts = records[k]["variances"]  # the adjustment's parts: no simulation here
        assert parts["sandwich"] == pytest.approx(2.25 * C[i, i], rel=1e-12)
        assert parts["simulation"] == 0.0
        assert parts["curvature"] == pytest.approx(C[i, i], rel=1e-6)
        assert ci[k][0] == pytest.approx(-half, rel=0.03)
        assert ci[k][1] == pytest.approx(half, rel=0.03)


def test_a_fit_with_profile_intervals_agrees_with_wald_where_the_surface_is_quadratic(tmp_path):
    """D and tau from 1500 slip times: the likelihood is near quadratic in log D and log
    tau there, so the profile and Wald intervals agree to a tenth of their width; both in
    `diagnostics.profile`, which a saved fit keeps; a bad `intervals` is refused in one
    line."""
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from test_fit import BASE, slip_times

    data = {"slip_time": slip_times(1500, seed=101)}
    r = ss.fit("langevin", data, free={"D": (0.1, 1.0), "tau": (0.02, 0.5)}, fixed=BASE,
               seed=1, n_sim=20_000, check=False, intervals="profile")  # fmt: skip
    for k in ("D", "tau"):
        lo, hi = np.log(r.ci[k])
        wlo, whi = np.log(r.diagnostics.profile[k]["wald"])
        assert lo < np.log(r.estimate[k]) < hi
        assert abs(lo - wlo) < 0.1 * (whi - wlo) and abs(hi - whi) < 0.1 * (whi - wlo)
    assert "profile-likelihood intervals" in r.method
    r.save(tmp_path / "fit.json")
    back = ss.load_fit(tmp_path / "fit.json")
    for k in r.ci:
        assert back.ci[k] == pytest.approx(r.ci[k])
    assert back.diagnostics.profile["D"]["ends"] == r.diagnostics.profile["D"]["ends"]
    with pytest.raises(ss.ParameterError, match="intervals"):
        ss.fit("langevin", data, {"D": (0.1, 1.0)}, BASE | {"tau": 0.1}, intervals="exact")


# (1e-15: a statistic the polynomial fits to rounding, whose root bracket is a point)
@pytest.mark.parametrize("c, noise", [(1.0, 0.0), (2.25, 1e-15), (1.0, 1.0), (0.7, 2.0),
                                      (1.4, 3.0)])  # fmt: skip
def test_the_threshold_of_a_noisy_statistic_is_its_quantile(c, noise):
    """The threshold of c chi2_1 read with normal noise against 10^6 draws of the two
    (the draws' own 95 % point has sampling sd ~ 0.01 c + 0.003 noise)."""
    from stickslip._inference.profile import noisy_threshold

    rng = np.random.default_rng(11)
    draws = c * rng.chisquare(1, 10**6) + noise * rng.standard_normal(10**6)
    assert noisy_threshold(c, noise) == pytest.approx(np.quantile(draws, 0.95),
                                                      abs=0.05 * c + 0.015 * noise)  # fmt: skip


def test_ends_are_read_from_the_tries_a_design_vouches_for():
    """`read_ends`: a try whose design found no vertex (a lower bound on the profile) is
    not read past the threshold; a side whose read tries all lie inside it ends on the
    root's line through the estimate, beyond the farthest of them, not at the box."""
    from stickslip._inference.profile import read_ends

    q = 4.0  # root 2
    record = dict(estimate=0.0, threshold=q, box=[False, False],
                  psi=[-0.5, 0.5, 0.6], statistic=[4.0, 2.0, 30.0],
                  vertex=[True, True, False])  # fmt: skip
    lo, hi = read_ends(record, -10.0, 10.0)
    assert lo == pytest.approx(-0.5)
    # the root's line through (0.5, sqrt 2): 2 / (sqrt(2) / 0.5) = 0.707, the 30 unread
    assert hi == pytest.approx(0.5 * 2 / math.sqrt(2.0))
    # inside the threshold at 0.5 and 0.7, one of them without a vertex: read, the line's
    # root at 2 / beta with beta the least-squares slope of (1.732, 1.414) at (0.5, 0.7)
    record = dict(estimate=0.0, threshold=q, box=[False, False],
                  psi=[-0.5, 0.5, 0.7], statistic=[4.0, 3.0, 2.0],
                  vertex=[True, True, False])  # fmt: skip
    d, r = np.array([0.5, 0.7]), np.sqrt([3.0, 2.0])
    assert read_ends(record, -10.0, 10.0)[1] == pytest.approx(2 / (d @ r / (d @ d)))


@pytest.mark.slow  # (~20 s)
def test_profile_intervals_on_a_noisy_known_surface_cover_at_their_level():
    """A known quadratic log-likelihood (two parameters, correlated) about a maximum drawn
    from its own normal law, with the simulated likelihood's roughness as independent
    noise of sd 1.5 units at every point (`benchmarks/profile_calibration.py`: the fit's
    local surface, sandwich and simulation covariance, then `profile_intervals`): 300 sets
    cover the truth at 95 % within three sampling sds (0.038). Without the allowance for
    the statistic's own noise the same sets cover 88-90 %."""
    from conftest import benchmark_module

    calibration = benchmark_module("profile_calibration")
    C = calibration.correlation(2)
    rng = np.random.default_rng(1)
    covered = np.zeros(2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(300):
            for i, ((lo, hi), _) in enumerate(calibration.one_set(rng, C, 1.5, 0.0, 1.0, False)):
                covered[i] += lo <= 0.0 <= hi
    tolerance = 3 * math.sqrt(0.95 * 0.05 / 300)
    assert np.all(np.abs(covered / 300 - 0.95) < tolerance), covered / 300
