"""The crossing-statistics estimator, against independent implementations and simulation."""

import math

import numpy as np
import pytest
import scipy.integrate as si
import scipy.linalg as sl
from scipy.special import erfc
from scipy.stats import multivariate_normal, norm

import stickslip as ss
from stickslip._estimate.bvn import positive_part_mean

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
WHITE = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)


@pytest.fixture(scope="module")
def exact(Langevin):
    return ss.CrossingEstimator(Langevin(**PUBLIC))


@pytest.fixture(scope="module")
def upcrossings(Langevin):
    """Free-run upcrossings of 40000 OU paths up to t = 8 (fixed seed)."""
    return ss.simulate(Langevin(**PUBLIC), 40_000, 0.005, 8.0, seed=21, record_upcrossings=16)


# -- independent NumPy/SciPy implementation of the Gaussian moments -------------------------
def _matrices(params):
    w2, z, D = params["omega0"] ** 2, params["zeta"], params["D"]
    if params.get("tau") is None:
        A = np.array([[0.0, 1.0], [-w2, -z]])
        B = np.array([[0.0], [math.sqrt(2 * D)]])
        m0 = np.array([params["x0"], params["v_b"]])
    else:
        tau = params["tau"]
        A = np.array([[0.0, 1.0, 0.0], [-w2, -z, 1.0], [0.0, 0.0, -1.0 / tau]])
        B = np.array([[0.0], [0.0], [math.sqrt(2 * D) / tau]])
        m0 = np.array([params["x0"], params["v_b"], 0.0])
    return A, B, m0


def _cov(A, B, t):
    """Sigma(t) by adaptive quadrature of the defining integral (no matrix-exponential tricks)."""
    f = lambda s: sl.expm(A * s) @ B @ B.T @ sl.expm(A * s).T
    return si.quad_vec(f, 0, t, epsabs=1e-16, epsrel=1e-13, limit=4000)[0]


def test_n1_equals_the_reference(exact, reference):
    """Exact Rice n1 against the reference data's (independent implementation) to 1e-6."""
    n1 = exact.n1(reference["t"])
    assert np.max(np.abs(n1 - reference["n1"]) / reference["n1"]) < 1e-6


@pytest.mark.parametrize("t1, t2", [(0.5, 3.0), (1.0, 1.5), (2.0, 2.02), (3.0, 6.5)])
def test_n2_equals_an_independent_implementation(exact, t1, t2):
    """n2 from the direct covariance of (v1, v2, a1, a2) and 2-D quadrature of
    E[a1+ a2+ | v1 = v2 = v_b], against the estimator's closed form, to 1e-6."""
    A, B, m0 = _matrices(PUBLIC)
    g = np.eye(3)[1]
    h = A.T @ g
    P1 = _cov(A, B, t1)
    m1 = sl.expm(A * t1) @ m0
    Phi = sl.expm(A * (t2 - t1))
    m2, P2, C21 = Phi @ m1, Phi @ P1 @ Phi.T + _cov(A, B, t2 - t1), Phi @ P1
    U = np.stack([g, h])
    mean = np.concatenate([U @ m1, U @ m2])[[0, 2, 1, 3]]  # v1 v2 a1 a2
    C = np.block([[U @ P1 @ U.T, U @ C21.T @ U.T], [U @ C21 @ U.T, U @ P2 @ U.T]])
    C = C[np.ix_([0, 2, 1, 3], [0, 2, 1, 3])]
    So = C[:2, :2]
    density = multivariate_normal(mean[:2], So).pdf([1.0, 1.0])
    K = C[2:, :2] @ np.linalg.inv(So)
    mu = mean[2:] + K @ (np.array([1.0, 1.0]) - mean[:2])
    V = C[2:, 2:] - K @ C[:2, 2:]
    mvn = multivariate_normal(mu, V)
    top = mu + 12 * np.sqrt(np.diag(V))
    integral = si.dblquad(
        lambda y, x: x * y * mvn.pdf([x, y]), 0, top[0], 0, top[1], epsabs=1e-14, epsrel=1e-10
    )[0]
    expected = density * integral
    ours = exact.n2(np.array([t1]), np.array([t2]))[0, 0]
    assert abs(ours - expected) / expected < 1e-6
    assert exact.n2(np.array([t2]), np.array([t1]))[0, 0] == pytest.approx(ours, rel=1e-14)


def test_n2_near_and_on_the_diagonal(exact, Langevin):
    lags = np.array([1e-3, 1e-4, 1e-5, 1e-6])
    vals = np.array([exact.n2(np.array([3.0]), np.array([3.0 + s]))[0, 0] for s in lags])
    assert np.all(np.isfinite(vals)) and np.all(vals > 0)
    # a finite limit approached like sqrt(lag): successive differences over decades of lag
    # shrink by a factor near sqrt(10) = 3.16 (3.66 and 3.33 at larger lags)
    ratios = np.diff(vals)[:-1] / np.diff(vals)[1:]
    assert np.all((ratios > 2.9) & (ratios < 3.5))
    diag = exact.n2(np.array([3.0]), np.array([3.0]))[0, 0]
    assert diag == pytest.approx(vals[-1], rel=2e-2)
    closure = ss.CrossingEstimator(Langevin(**WHITE))
    assert np.isinf(closure.n2(np.array([3.0]), np.array([3.0]))[0, 0])


def test_closure_n1_equals_eq13_integrated_numerically(Langevin):
    """White noise: the paper's closure n1(t) = int dx P10(x, v_b, t) I_a(x, v_b) (eqs. 11-13,
    with I_a = E[a+]), integrated over x by quadrature, against the estimator, to 1e-6."""
    est = ss.CrossingEstimator(Langevin(**WHITE))
    assert not est.exact and est.closure_variance == pytest.approx(2 * 0.4)
    A, B, m0 = _matrices(WHITE)
    sigma = math.sqrt(2 * 0.4)
    for t in (0.3, 2.0, 6.0, 15.0):
        m = sl.expm(A * t) @ m0
        P = _cov(A, B, t)
        P10 = multivariate_normal(m, P)

        def integrand(x, P10=P10):
            mu_a = -(WHITE["omega0"] ** 2) * x - WHITE["zeta"] * WHITE["v_b"]
            Ia = sigma * norm.pdf(mu_a / sigma) + mu_a * norm.cdf(mu_a / sigma)
            return P10.pdf([x, WHITE["v_b"]]) * Ia

        sd = math.sqrt(P[0, 0])
        expected = si.quad(
            integrand, m[0] - 12 * sd, m[0] + 12 * sd, epsabs=1e-14, epsrel=1e-11, limit=500
        )[0]
        assert est.n1(t) == pytest.approx(expected, rel=1e-6)


def _n1_with(Ia, model):
    """n1(t) of the exact OU model with E[a+ | v = v_b] replaced by `Ia(mu, s)`."""
    lg = model.linear_gaussian()
    g, h = np.asarray(lg.crossing), np.asarray(lg.A).T @ np.asarray(lg.crossing)
    A, B, m0 = (np.asarray(a) for a in (lg.A, lg.B, lg.m0))

    def n1(t):
        m, P = sl.expm(A * t) @ m0, _cov(A, B, t)
        svv, sva, saa = g @ P @ g, g @ P @ h, h @ P @ h
        pv = norm.pdf(1.0, g @ m, math.sqrt(svv))
        mu = h @ m + sva / svv * (1.0 - g @ m)
        return pv * Ia(mu, math.sqrt(saa - sva**2 / svv))

    return n1


@pytest.mark.slow
def test_eq12_as_printed_is_E_minus_and_simulation_picks_E_plus(upcrossings, Langevin):
    """Eq. (12) as printed, sqrt(s^2/2pi) exp(-mu^2/2s^2) - (mu/2) erfc(mu/(sqrt2 s)), equals
    E[a^-]; the upcrossing density needs E[a^+]. Simulated upcrossings decide: n1 with E[a^+]
    agrees with them within sampling error, n1 with the printed formula does not."""
    printed = lambda mu, s: (
        s / math.sqrt(2 * math.pi) * math.exp(-(mu**2) / (2 * s * s))
        - mu / 2 * erfc(mu / (math.sqrt(2) * s))
    )
    e_minus = lambda mu, s: float(positive_part_mean(-mu, s))
    e_plus = lambda mu, s: float(positive_part_mean(mu, s))
    for mu, s in [(-1.0, 0.5), (0.3, 2.0), (2.0, 0.7)]:
        assert printed(mu, s) == pytest.approx(e_minus(mu, s), rel=1e-12)
    model = Langevin(**PUBLIC)
    u = upcrossings.upcrossings
    # from t = 0.5: n1 peaks sharply near t = 0.02, finer than the bin averages below resolve
    edges = np.arange(0.5, 8.0001, 0.5)
    counts = np.histogram(u.times[~u.immediate].ravel(), bins=edges)[0]
    emp = counts / u.n_paths / 0.5
    se = np.sqrt(counts) / u.n_paths / 0.5

    # bin averages of each candidate n1 (Simpson on 9 points per bin)
    def binned(fn):
        out = []
        for a, b in zip(edges[:-1], edges[1:], strict=True):
            ts = np.linspace(a + 1e-9, b, 9)
            out.append(si.simpson([fn(t) for t in ts], x=ts) / (b - a))
        return np.array(out)

    z_plus = (binned(_n1_with(e_plus, model)) - emp) / se
    z_printed = (binned(_n1_with(printed, model)) - emp) / se
    assert np.mean(z_plus**2) < 2.0  # chi-square per bin near 1
    assert np.max(np.abs(z_printed)) > 20


@pytest.mark.slow
def test_empirical_n1_agrees_with_exact(upcrossings, exact, Langevin):
    emp = ss.CrossingEstimator(Langevin(**PUBLIC), ensemble=upcrossings, dt=0.1)
    assert not emp.exact
    t = np.arange(0.1, 7.91, 0.1)
    counts = emp.n1(t) * upcrossings.n_paths * 0.1
    se = np.sqrt(np.maximum(counts, 1)) / upcrossings.n_paths / 0.1
    # the exact n1 averaged over the same cells
    fine = np.linspace(0.05, 7.95, 7901)
    cell = np.add.reduceat(exact.n1(fine)[:-1], np.arange(0, 7900, 100)) * 0.001 / 0.1
    z = (emp.n1(t) - cell[: t.size]) / se
    assert np.mean(z**2) < 1.6 and np.max(np.abs(z)) < 4.5


def test_stationary_rate_is_rice(exact, Langevin):
    """Large-t n1 = Rice's (1/2pi) sqrt(lambda2/lambda0) exp(-v_b^2/2 lambda0) with the
    stationary variances of v and a (Lyapunov equation solved by SciPy)."""
    A, B, _ = _matrices(PUBLIC)
    P = sl.solve_continuous_lyapunov(A, -B @ B.T)
    g = np.eye(3)[1]
    l0, l2 = g @ P @ g, (A.T @ g) @ P @ (A.T @ g)
    rice = math.sqrt(l2 / l0) / (2 * math.pi) * math.exp(-1.0 / (2 * l0))
    assert exact.stationary_rate == pytest.approx(rice, rel=1e-9)
    assert exact.n1(300.0) == pytest.approx(rice, rel=1e-6)


def test_the_papers_rice_frequency(Langevin):
    """The paper's n0 = (omega0/2pi) exp(-v_b zeta/2D) is Rice's formula for the stationary
    velocity of the white-noise model (lambda0 = D/zeta) with lambda2 = omega0^2 lambda0, the
    acceleration without its noise, and with v_b where v_b^2 belongs: it agrees only at
    v_b = 1. The closure's own large-t rate differs from it."""

    def paper(p):
        return p["omega0"] / (2 * math.pi) * math.exp(-p["v_b"] * p["zeta"] / (2 * p["D"]))

    def rice(p):
        l0 = p["D"] / p["zeta"]
        return p["omega0"] / (2 * math.pi) * math.exp(-(p["v_b"] ** 2) / (2 * l0))

    assert paper(WHITE) == pytest.approx(rice(WHITE), rel=1e-12)
    other = WHITE | {"v_b": 1.3}
    assert abs(paper(other) / rice(other) - 1) > 0.02
    est = ss.CrossingEstimator(Langevin(**WHITE))
    l0 = WHITE["D"] / WHITE["zeta"]
    s_a = math.sqrt(WHITE["omega0"] ** 2 * l0 + 2 * WHITE["D"])  # omega^4 var(x) + closure
    mu_a = -WHITE["zeta"] * WHITE["v_b"]
    closure = norm.pdf(1.0, 0, math.sqrt(l0)) * (
        s_a * norm.pdf(mu_a / s_a) + mu_a * norm.cdf(mu_a / s_a)
    )
    assert est.stationary_rate == pytest.approx(closure, rel=1e-9)
    assert abs(est.stationary_rate / paper(WHITE) - 1) > 0.02


def _binned(est, method, order, edges, **kw):
    fine = np.linspace(edges[0], edges[-1], (edges.size - 1) * 100 + 1)
    F = est.first_passage(fine, method, order, **kw)
    return np.array(
        [
            np.trapezoid(F[i * 100 : (i + 1) * 100 + 1], fine[i * 100 : (i + 1) * 100 + 1])
            for i in range(edges.size - 1)
        ]
    ) / np.diff(edges)


def test_second_order_decoupling_against_the_reference_histogram(exact, reference):
    """L1 distance to the reference Monte Carlo histogram over t in [0, 7], bins of 0.1 (bin
    averages of the density): F_g^(2) within 0.10; the approximations rank as expected."""
    hist = reference["T_counts"] / reference["T_counts"].sum() / 0.1
    edges = reference["T_edges"][:71]
    L1 = {}
    for method, order in [
        ("truncation", 1),
        ("decoupling", 1),
        ("truncation", 2),
        ("decoupling", 2),
    ]:
        L1[(method, order)] = np.sum(np.abs(_binned(exact, method, order, edges) - hist[:70])) * 0.1
    assert L1[("decoupling", 2)] <= 0.10
    assert (
        L1[("decoupling", 2)]
        < L1[("decoupling", 1)]
        < L1[("truncation", 2)]
        < L1[("truncation", 1)]
    )


def test_orderings_that_must_hold(exact):
    t = np.linspace(0, 6, 601)
    n1 = exact.n1(t)
    assert np.all(exact.first_passage(t, "decoupling", 1) <= n1 + 1e-15)
    assert np.all(exact.first_passage(t, "truncation", 2) <= n1 + 1e-15)  # K >= 0
    np.testing.assert_allclose(exact.first_passage(t, "truncation", 1), n1, rtol=1e-12)


def _n1_integral(est, a, b, tau):
    """int_a^b n1 by scipy's adaptive quadrature (an integration independent of the
    estimator's grids), with the onset transient, as short as tau, marked."""
    from scipy import integrate

    f = lambda s: float(est.n1(np.array([s]))[0])
    marks = [p for p in (tau, 5 * tau, 20 * tau) if a < p < b]
    return integrate.quad(f, a, b, points=marks or None, limit=500, epsabs=1e-10)[0]


def test_normalisation(exact):
    t = np.linspace(0, 30, 3001)
    # int_0^T F_g^(1) = 1 - exp(-int_0^T n1), an identity of the approximation; the
    # estimator integrates n1 to a controlled error (adaptive quadrature here)
    I1 = _n1_integral(exact, 0.0, 0.5, 0.1) + _n1_integral(exact, 0.5, 30.0, 0.1)
    assert exact.diagnostics(30.0)["mass"] == pytest.approx(1 - math.exp(-I1), abs=1e-7)
    Fg2 = exact.first_passage(t, "decoupling", 2)
    assert np.trapezoid(Fg2, t) == pytest.approx(1.0, abs=3e-3)
    Fhat = exact.first_passage(t, "truncation", 1, normalized=True)
    assert np.trapezoid(Fhat, t) == pytest.approx(1.0, abs=0.02)  # cut within one grid step
    assert exact.diagnostics(30.0, "truncation", 1, normalized=True)["t_n"] < 30


@pytest.mark.parametrize("tau", [0.01, pytest.param(0.003, marks=pytest.mark.slow)])  # (7 s: slow)
def test_first_order_mass_follows_a_short_correlation_time(Langevin, tau):
    """The onset transient is as short as tau: on a grid of dt = 0.01 the
    trapezoid rule gave int_0^0.5 n1 = 1.22 for 1.82 at tau = 0.01 and the mass of F_g^(1)
    on [0.5, 10] 0.291 for 0.160. Now within 2e-3 of adaptive quadrature."""
    est = ss.CrossingEstimator(Langevin(**(PUBLIC | {"tau": tau})))
    I_half = _n1_integral(est, 0.0, 0.5, tau)
    I_ten = I_half + _n1_integral(est, 0.5, 10.0, tau)
    expected = math.exp(-I_half) - math.exp(-I_ten)
    t = np.linspace(0.5, 10.0, 9501)
    F = est.first_passage(t, "decoupling", 1)
    assert np.trapezoid(F, t) == pytest.approx(expected, abs=2e-3)
    assert est.diagnostics(0.5)["mass"] == pytest.approx(-math.expm1(-I_half), abs=1e-6)


def test_densities_that_cannot_be_right_say_so(Langevin):
    """A truncation carries more than the slipping paths; a grid that misses part of the
    support; a second order whose grid does not resolve the onset (tau = 0.01 on a grid of
    0.01, coarser than the default there, 0.002)."""
    est = ss.CrossingEstimator(Langevin(**(PUBLIC | {"tau": 0.01})), dt=0.01)
    d = np.arange(-3.0, 9.0, 0.05) + 0.025
    with pytest.warns(ss.ApproximationWarning, match=r"carries 9.\d+, more than the 1 "):
        est.slip_distance_density(d, "truncation", 1)
    with pytest.warns(ss.ApproximationWarning, match=r"cells \[0.5, 1\] hold"):
        est.slip_distance_density(np.arange(0.5, 1.0, 0.1) + 0.05, "decoupling", 1)
    with pytest.warns(ss.ApproximationWarning, match="does not resolve n1's onset transient"):
        est.first_passage(np.linspace(0, 5, 51), "decoupling", 2)


def test_negative_truncation_is_reported_not_clipped(exact):
    with pytest.warns(
        ss.ApproximationWarning, match=r"truncation order 2: density negative on t in \["
    ):
        F = exact.first_passage(np.linspace(0, 20, 201), "truncation", 2)
    assert F.min() < 0
    d = exact.diagnostics(20.0, "truncation", 2)
    assert d["min_density"] < 0


def test_densities_carry_the_mass_of_F(Langevin):
    """The period and slip-distance densities carry what the slip-time density does over
    the horizon: exactly at first order (the boxes carry each grid cell's exact mass), and
    to the second order's own grid error."""
    est = ss.CrossingEstimator(Langevin(**PUBLIC), horizon=30.0)
    d = np.arange(-3.0, 9.0, 0.05) + 0.025
    T = np.arange(0.0, 60.0, 0.1) + 0.05
    for order, tol in ((1, 1e-4), (2, 2e-3)):
        mass = est.diagnostics(30.0, "decoupling", order)["mass"]
        assert est.period_density(T, "decoupling", order).sum() * 0.1 == pytest.approx(
            mass, abs=tol
        )
        assert est.slip_distance_density(d, "decoupling", order).sum() * 0.05 == pytest.approx(
            mass, abs=tol
        )


@pytest.mark.slow
def test_position_densities_against_simulated_upcrossings(upcrossings, Langevin):
    """First-order truncation counts every upcrossing: its slip-distance 'density' is the
    histogram of x0 - x over all upcrossings before the horizon, which the simulation gives
    directly. Exact and empirical estimators agree within sampling error."""
    model = Langevin(**PUBLIC)
    exact = ss.CrossingEstimator(model, horizon=6.0)
    emp = ss.CrossingEstimator(model, ensemble=upcrossings, horizon=6.0, dt=0.01)
    d = np.arange(-1.0, 4.0, 0.1) + 0.05
    a = exact.slip_distance_density(d, "truncation", 1)
    b = emp.slip_distance_density(d, "truncation", 1)
    se = np.sqrt(np.maximum(b * 0.1 * upcrossings.n_paths, 1)) / upcrossings.n_paths / 0.1
    z = (a - b) / se
    assert np.mean(z**2) < 2.0


@pytest.mark.slow
def test_stationary_onset_is_a_mixture_with_an_atom(Langevin):
    """eta0 = 'stationary': p0 = P(a(0) >= 0) re-sticks at once; the rest is a quadrature over
    a(0) < 0 that converges (32 against 64 nodes) and matches simulated upcrossings."""
    model = Langevin(**PUBLIC, eta0="stationary")
    est = ss.CrossingEstimator(model)
    p0 = norm.sf((1.0 + 0.1) / math.sqrt(0.4 / 0.1))
    assert est.immediate_probability == pytest.approx(p0, rel=1e-12)
    fine = ss.CrossingEstimator(model, quadrature_nodes=64)
    t = np.linspace(0.02, 8, 200)
    np.testing.assert_allclose(est.n1(t), fine.n1(t), rtol=1e-6)
    assert est.n_components == 32
    # Every slipping path sticks: F_g^(1) carries 1 - p0. Onsets with a(0) just below 0
    # re-stick within ~1e-4, so its values, exact wherever asked, need a grid that fine
    # near 0 to integrate to that mass (the estimator's own integral is error-controlled).
    assert est.diagnostics(60.0)["mass"] == pytest.approx(1 - p0, abs=1e-4)
    t = np.concatenate([np.linspace(0, 0.2, 20001), np.linspace(0.2, 60, 6000)[1:]])
    F = est.first_passage(t, "decoupling", 1)
    assert np.trapezoid(F, t) == pytest.approx(1 - p0, abs=1e-3)
    sim = ss.simulate(model, 30_000, 0.005, 6.0, seed=5, record_upcrossings=8)
    emp = ss.CrossingEstimator(model, ensemble=sim, dt=0.25)
    assert emp.immediate_probability == pytest.approx(p0, abs=4 * math.sqrt(p0 * (1 - p0) / 30_000))
    tc = np.arange(0.25, 5.8, 0.25)
    cell = np.array([np.mean(est.n1(np.linspace(c - 0.125, c + 0.125, 51))) for c in tc])
    counts = emp.n1(tc) * 30_000 * 0.25
    z = (emp.n1(tc) - cell) / (np.sqrt(np.maximum(counts, 1)) / 30_000 / 0.25)
    assert np.mean(z**2) < 2.0


def test_bad_arguments(exact, Langevin):
    with pytest.raises(ss.ParameterError, match="'method' must be one of"):
        exact.first_passage([1.0], "decouple")
    with pytest.raises(ss.ParameterError, match="'order' must be 1 or 2"):
        exact.first_passage([1.0], "decoupling", 3)
    with pytest.raises(ss.ParameterError, match="'normalized' applies to method='truncation' only"):
        exact.first_passage([1.0], "decoupling", 1, normalized=True)
    with pytest.raises(ss.ParameterError, match="'t' must be finite and >= 0"):
        exact.first_passage([-1.0])
    with pytest.raises(ss.ParameterError, match="evenly spaced"):
        exact.slip_distance_density(np.array([0.0, 0.1, 0.3]))
    with pytest.raises(ss.ParameterError, match="'closure_variance' applies only"):
        ss.CrossingEstimator(Langevin(**PUBLIC), closure_variance=1.0)
    with pytest.raises(ss.ParameterError, match="'ensemble' must carry upcrossings"):
        ss.CrossingEstimator(
            Langevin(**PUBLIC), ensemble=ss.simulate(Langevin(**PUBLIC), 10, 0.01, 1.0)
        )
    with pytest.raises(ss.ParameterError, match="'dt' must be > 0"):
        ss.CrossingEstimator(Langevin(**PUBLIC), dt=0.0)


def test_joint_density_integrates_to_n1(exact, Langevin):
    x = np.linspace(-20, 20, 8001)  # the position law is about 2 wide at t = 10
    for t in (0.5, 3.0, 10.0):
        joint = exact.n1_joint(x, np.array([t]))[:, 0]
        assert np.trapezoid(joint, x) == pytest.approx(exact.n1(t), rel=1e-6)
    small = ss.simulate(Langevin(**PUBLIC), 2000, 0.005, 8.0, seed=21, record_upcrossings=16)
    emp = ss.CrossingEstimator(Langevin(**PUBLIC), ensemble=small, dt=0.5)
    cells_x = np.arange(-12.0, 12.0, 0.25) + 0.125  # covers every recorded position
    cells_t = np.arange(0.5, 7.0, 0.5)  # the grid times: n1 there is the cell average
    joint = emp.n1_joint(cells_x, cells_t)
    np.testing.assert_allclose(joint.sum(axis=0) * 0.25, emp.n1(cells_t), rtol=1e-9)


def test_fewer_upcrossings_per_path_run_the_same_program(Langevin, rent_held):
    """K = 12 after K = 16 (each K compiled a program of its own): one program with 16 rows
    serves both, nothing is traced or compiled, and the first 12 upcrossings of every path
    are those of the K = 16 record (the K = 12 run stops once every path has 12, so it
    counts no more than the other)."""
    args = (Langevin(**PUBLIC), 2000, 0.005, 8.0)
    sixteen = ss.simulate(*args, seed=21, record_upcrossings=16).upcrossings
    counts = {k: ss.cache_info()[k] for k in ("traces", "compiles")}
    twelve = ss.simulate(*args, seed=21, record_upcrossings=12).upcrossings
    assert {k: ss.cache_info()[k] for k in counts} == counts
    assert twelve.times.shape == (2000, 12) and np.isfinite(twelve.times).sum() > 2000
    np.testing.assert_array_equal(twelve.times, sixteen.times[:, :12])
    np.testing.assert_array_equal(twelve.positions, sixteen.positions[:, :12])
    assert np.all(twelve.count <= sixteen.count)
    ended = twelve.count < 12  # paths that reached t_max before their 12th: counted alike
    np.testing.assert_array_equal(twelve.count[ended], sixteen.count[ended])


@pytest.mark.slow
def test_white_noise_closure_second_order(Langevin):
    """The closure's n2 diverges like tau^-1/2 on the diagonal (integrable): the second-order
    decoupling stays finite, with a positive escape rate and most of its mass by t = 40."""
    est = ss.CrossingEstimator(Langevin(**WHITE))
    diag = est.diagnostics(40.0, "decoupling", 2)
    assert diag["escape_rate_min"] > 0 and diag["min_density"] >= 0
    assert 0.9 < diag["mass"] <= 1.0


# -- the fast evaluation paths against direct ones --------------------------------------------
@pytest.mark.parametrize(
    "params",
    [PUBLIC, pytest.param(WHITE, marks=pytest.mark.slow)],  # (the closure: 15 s more, slow)
    ids=["ou", "white-closure"],
)
def test_grid_K2_equals_the_lag_rule_evaluated_directly(Langevin, params):
    """K2(t) = int n2(t, s) ds on the grid, where the moments and propagators of the pairs
    are composed from shared tables, against the same quadrature (`lag_rule`) with every
    moment and propagator computed directly: equal to rounding."""
    from stickslip._estimate import kernels, sources

    est = ss.CrossingEstimator(Langevin(**params))
    src, h = est._source, est.dt
    K = src.second_order(src.grid(13.0, h), 1301)[0]
    for k in (1, 7, 150, 777, 1300):
        tau, w = sources.lag_rule(np.arange(1301)[k] * h)
        # in blocks of one length for every k (one compiled evaluation, the length of
        # test_n2_equals_an_independent_implementation's): the last node repeated, weight 0
        B = 64
        tau, w = (np.pad(a, (0, -a.size % B), mode=m) for a, m in ((tau, "edge"), (w, "constant")))
        ms, Ps = src.moments(np.maximum(k * h - tau, 0.0))
        prop = kernels.lag_propagators(src.cr, tau)
        pairs = [np.asarray(a) for a in (ms[0], Ps[0], *prop, tau)]
        direct = 0.0
        for i in range(0, tau.size, B):
            n2 = kernels.n2_pairs(src.cr, *(a[i : i + B] for a in pairs))
            direct += w[i : i + B] @ np.asarray(n2)
        assert K[k] == pytest.approx(direct, rel=1e-11), k


def test_shared_panels_are_those_of_the_graded_rule():
    """`_panels` splits the graded Gauss-Legendre rule of many lengths into shared and own
    panels: node for node the rule of `_graded`, including lengths at powers of two."""
    from stickslip._estimate import sources

    for first in (1e-6, 1e-3):
        lengths = np.concatenate(
            [np.arange(1, 3001) * 0.013, first * 2.0 ** np.arange(25), [first / 3, first]]
        )
        (x_sh, w_sh), used, (x_last, w_last) = sources._panels(lengths, first)
        for i, length in enumerate(lengths):
            x, w = sources._gauss(sources._graded(length, first))
            np.testing.assert_array_equal(np.r_[x_sh[: used[i]], x_last[i]], x)
            np.testing.assert_array_equal(np.r_[w_sh[: used[i]], w_last[i]], w)


def test_branch_of_follows_genz_rule():
    """The formula chosen per correlation, against Genz's rule written out: 6 nodes for
    |r| < 0.3, 12 for |r| < 0.75, 20 for |r| < 0.925, else the expansion (NaN: the last)."""
    from stickslip._estimate.bvn import BRANCHES, branch_of

    edges = np.array([0.3, 0.75, 0.925])
    r = np.concatenate([
        np.linspace(-1.2, 1.2, 2401), edges, -edges, np.nextafter(edges, 0),
        np.nextafter(-edges, 0), [1.0, -1.0, 0.0, -0.0, np.inf, -np.inf, np.nan],
    ])  # fmt: skip
    a = np.abs(r)
    rule = np.where(
        a < 0.3, "mid6", np.where(a < 0.75, "mid12", np.where(a < 0.925, "mid20", "high"))
    )
    assert [BRANCHES[i] for i in branch_of(r)] == list(rule)


@pytest.mark.slow  # compiles every branch (~8 s CPU)
def test_bivariate_normal_branches_equal_the_full_formula():
    """E[a1+ a2+] with only the branch of the bivariate normal each correlation needs
    (Genz's 6-, 12-, 20-node rules, the expansion near |r| = 1) against both evaluated and
    selected, to 1e-14 (Genz's rule is accurate to about 1e-15)."""
    from stickslip._estimate.bvn import BRANCHES, branch_of, positive_product_mean

    rng = np.random.default_rng(4)
    n = 4000
    m1, m2 = rng.normal(0, 2, n), rng.normal(0, 2, n)
    s1, s2 = rng.uniform(0.1, 3, n), rng.uniform(0.1, 3, n)
    rho = np.concatenate([rng.uniform(-1, 1, n - 6), [0.3, -0.75, 0.925, -0.925, 0.999999, 0]])
    full = np.asarray(positive_product_mean(m1, m2, s1, s2, rho))
    branch = branch_of(rho)
    for b, name in enumerate(BRANCHES):
        sel = branch == b
        assert sel.any()
        part = np.asarray(positive_product_mean(m1[sel], m2[sel], s1[sel], s2[sel], rho[sel], name))
        np.testing.assert_allclose(part, full[sel], rtol=1e-13, atol=1e-14)


def test_cumulative_without_sorting_equals_the_sorted_sum():
    """Cell masses of boxes and points deposited without sorting (binary search in the
    edges; pairs for narrow boxes, slopes for wide ones) against the sorted breakpoints,
    with boxes of every width, points, and ends on the edges."""
    from stickslip._estimate.estimator import _cumulative, _cumulative_sorted

    rng = np.random.default_rng(5)
    edges = np.linspace(-1.0, 6.0, 71)
    n = 20_000
    lo = np.concatenate([rng.normal(2, 2, n), np.repeat(edges[::5], 2)])
    boxes = rng.exponential(0.2, n) * (rng.uniform(size=n) > 0.2)  # a fifth are points
    width = np.concatenate([boxes, np.tile([0, 0.3], 15)])
    hi, mass = lo + width, rng.normal(1, 1, lo.size)
    for at in (edges, np.sort(rng.uniform(-2, 7, 500))):
        np.testing.assert_allclose(
            _cumulative(at, lo, hi, mass, pairwise=2), _cumulative_sorted(at, lo, hi, mass),
            rtol=0, atol=1e-9,
        )  # fmt: skip
    wide = width > 0.05  # slopes and intercepts only: boxes wider than the spacing
    np.testing.assert_allclose(
        _cumulative(edges, lo[wide], hi[wide], mass[wide], pairwise=0),
        _cumulative_sorted(edges, lo[wide], hi[wide], mass[wide]),
        rtol=0, atol=1e-9,
    )  # fmt: skip


def test_position_densities_do_not_depend_on_what_was_asked_before(Langevin):
    """The period density uses the grid times up to its last cell only; asked first, or
    after the slip distance (which fills the whole horizon), it is the same."""
    m = Langevin(**PUBLIC)
    T = np.arange(0.1, 12.0, 0.2)
    d = np.arange(-1.0, 4.0, 0.1) + 0.05
    for args in (("decoupling", 2), ("truncation", 1, True)):
        a = ss.CrossingEstimator(m, horizon=16.0)
        first = a.period_density(T, *args)
        b = ss.CrossingEstimator(m, horizon=16.0)
        b.slip_distance_density(d, *args)
        np.testing.assert_allclose(b.period_density(T, *args), first, rtol=1e-12, atol=1e-14)


def _kernel_compilations(run):
    """Names of the estimator's kernels that `run()` compiles (JAX's compile log)."""
    import logging

    import jax

    from stickslip._estimate import kernels

    names = {n for n in dir(kernels) if not n.startswith("__")}
    seen = []

    class Grab(logging.Handler):
        def emit(self, record):
            msg = record.getMessage()
            if msg.startswith("Compiling jit("):
                name = msg[len("Compiling jit(") :].split(")", 1)[0]
                if name in names:
                    seen.append(name)

    logger, handler = logging.getLogger("jax"), Grab()
    logger.addHandler(handler)
    try:
        with jax.log_compiles(True):
            run()
    finally:
        logger.removeHandler(handler)
    return seen


def test_a_new_step_or_time_grid_compiles_no_kernel(Langevin):
    """The step enters the kernels as a traced value and point requests are evaluated in
    blocks of one length (n1) or padded to a few (n1_joint, n2: powers of two): after one
    estimator has run, another step and time grids of other lengths compile none of the
    estimator's kernels (each new step compiled four, ~1 s each; each new length two or
    three). The numbers are those of the unpadded evaluation."""
    model = Langevin(**PUBLIC)
    first = ss.CrossingEstimator(model, dt=0.01)
    first.first_passage(np.linspace(0.0, 6.0, 601))
    first.n1(np.linspace(0.05, 6.0, 300))
    first.n2(np.array([1.0, 2.0]), np.array([1.5, 2.5]))
    second = ss.CrossingEstimator(model, dt=0.0125)
    t = np.linspace(0.05, 5.0, 77)
    got = {}

    def run():
        got["F"] = second.first_passage(np.linspace(0.0, 5.0, 401))
        got["n1"] = second.n1(t)
        got["n2"] = second.n2(np.array([1.0, 2.0, 3.0]), np.array([1.25, 2.5, 4.0]))

    assert _kernel_compilations(run) == []
    # n1 in blocks against the kernels called on the times as they are; n2 of a grid
    # against the same pair asked alone (padded to another content)
    from stickslip._estimate import kernels

    src = second._source
    ms, Ps = kernels.moments_at(src.cr, src.m0s, src.P0s, t)
    direct = src.w @ np.asarray(kernels.n1_from(src.cr, ms, Ps))
    np.testing.assert_allclose(got["n1"], direct, rtol=1e-12)
    assert got["n2"][1, 1] == pytest.approx(second.n2(2.0, 2.5)[0, 0], rel=1e-12)
