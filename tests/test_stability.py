"""Where each method fails: points pinned on either side of every failure boundary.

The points come from the stability map (benchmarks/stability_map.py: omega0 = 1, zeta = 0.1,
x0 = 1). Statistical checks fix their seed and take their tolerance from the sampling error:
Z = 4 standard errors.
"""

import math

import equinox as eqx
import numpy as np
import pytest
from scipy import optimize

import stickslip as ss
from stickslip.stability import (
    MULTIPERIODIC_P_MISS,
    NEGATIVE_DENSITY,
    NEGATIVE_ESCAPE_RATE,
    NEVER_NORMALISES,
    NO_CONVERGENCE,
)

Z = 4.0
BASE = dict(omega0=1.0, zeta=0.1, x0=1.0)


def closed_form_critical_speed(omega0, zeta, x0):
    r"""Damped oscillator from (x0, v_b): v(t) = R e^{-gamma t} cos(omega_d t + phi), with
    tan phi = (omega0^2 x0 + gamma v_b) / (omega_d v_b). Its first maximum after onset is at
    omega_d t + phi + psi = 2 pi (tan psi = gamma / omega_d), where v = R e^{-gamma t} cos psi;
    it equals v_b when cos phi = cos psi exp(-(gamma / omega_d)(2 pi - phi - psi))."""
    g = zeta / 2
    wd = math.sqrt(omega0**2 - g**2)
    psi = math.atan(g / wd)

    def f(phi):
        return math.cos(phi) - math.cos(psi) * math.exp(-(g / wd) * (2 * math.pi - phi - psi))

    phi_c = optimize.brentq(f, psi, math.pi / 2, xtol=1e-15)
    return omega0**2 * x0 / (wd * math.tan(phi_c) - g)


@pytest.fixture(scope="module")
def report():
    """Reports by (tau, v_b, D, methods), computed once."""
    cache = {}
    Langevin = ss.get_model("langevin")

    def get(tau, v_b, D, methods=("Fn1_norm", "Fn2", "Fn2_norm", "Fg2")):
        key = (tau, v_b, D, methods)
        if key not in cache:
            model = Langevin(**BASE, D=D, v_b=v_b, tau=tau)
            cache[key] = ss.stability_report(model, methods=methods, seed=0)
        return cache[key]

    return get


# -- the critical speed ----------------------------------------------------------------------
@pytest.mark.parametrize(
    "omega0, zeta, x0", [(1.0, 0.1, 1.0), (2.0, 0.5, 0.5), (1.0, 1.5, 1.0), (0.5, 0.02, 3.0)]
)
def test_critical_speed_matches_the_closed_form(Langevin, omega0, zeta, x0):
    expected = closed_form_critical_speed(omega0, zeta, x0)
    for tau in (None, 0.1):  # the noise-free path does not depend on the noise model
        m = Langevin(omega0=omega0, zeta=zeta, D=0.4, v_b=1.0, x0=x0, tau=tau)
        assert ss.critical_speed(m) == pytest.approx(expected, rel=1e-8)


def test_critical_speed_grows_as_damping_vanishes(Langevin):
    speeds = [ss.critical_speed(Langevin(**{**BASE, "zeta": z}, D=0.1, v_b=1.0)) for z in
              (0.1, 0.01, 0.001)]  # fmt: skip
    assert speeds[0] == pytest.approx(1.2335475732, rel=1e-8)
    assert speeds[1] > 3 * speeds[0] and speeds[2] > 3 * speeds[1]
    # the small-damping law v_c ~ omega0 x0 sqrt(omega_d / (4 pi gamma))
    assert speeds[2] == pytest.approx(math.sqrt(1 / (4 * math.pi * 0.0005)), rel=0.02)
    # critical or over-damping: the velocity never comes back up, at any speed
    for zeta in (2.0, 3.0):
        m = Langevin(**{**BASE, "zeta": zeta}, D=0.1, v_b=1e-3)
        assert math.isinf(ss.deterministic_slip(m)) and ss.critical_speed(m) == 0.0


def test_deterministic_slip_either_side_of_the_critical_speed(Langevin):
    m = Langevin(**BASE, D=0.0, v_b=1.0)
    v_c = ss.critical_speed(m)
    below, above = (eqx.tree_at(lambda m: m.v_b, m, f * v_c) for f in (0.99, 1.01))
    t_below = ss.deterministic_slip(below)
    assert 0 < t_below < 2 * math.pi and math.isinf(ss.deterministic_slip(above))
    # The simulator without noise agrees: it sticks at that time below, slides above.
    e = ss.simulate(below, 1, 0.05, 200.0, seed=0)
    assert e.slip_time[0] == pytest.approx(t_below, abs=1e-9)
    assert np.isnan(ss.simulate(above, 1, 0.05, 200.0, seed=0).slip_time[0])
    assert ss.deterministic_slip(m) == pytest.approx(4.994056555307, abs=1e-10)


# -- truncations and decoupling --------------------------------------------------------------
def test_second_order_truncation_goes_negative_on_the_reference_set(report):
    r = report(0.1, 1.0, 0.4)
    assert NEGATIVE_DENSITY in r.failures["Fn2"]
    assert r.diagnostics["Fn2"]["min_density"] < -0.05 * r.diagnostics["Fn2"]["peak"]
    # ... and so never normalises, while second-order decoupling passes every check there
    assert NEVER_NORMALISES in r.failures["Fn2_norm"]
    assert r.ok("Fg2") and r.ok("mc_exact")
    assert r.ok("Fn1_norm") and r.diagnostics["Fn1_norm"]["t_n"] is not None


def test_second_order_truncation_stays_positive_with_little_noise_near_sliding(report):
    r = report(0.1, 1.1, 1e-4)
    assert r.regime == "stick-slip"
    assert r.ok("Fn2")  # measured: min / peak = -1e-18, rounding
    assert r.diagnostics["Fn2"]["min_density"] > -1e-9 * r.diagnostics["Fn2"]["peak"]


def test_negative_escape_rate_at_low_speed_and_low_noise(report):
    r = report(0.1, 0.25, 1e-4)
    assert NEGATIVE_ESCAPE_RATE in r.failures["Fg2"]
    assert r.diagnostics["Fg2"]["escape_rate_min"] < -1.0  # measured: -24
    # ... where the second-order truncation normalises (cut at t_n)
    assert r.ok("Fn2_norm") and r.diagnostics["Fn2_norm"]["t_n"] is not None
    # on the reference set the escape rate stays positive
    assert report(0.1, 1.0, 0.4).diagnostics["Fg2"]["escape_rate_min"] > 0


def test_normalised_first_order_truncation_never_normalises_when_sliding(report):
    r = report(0.1, 1.5, 1e-3)
    assert r.regime == "sliding"
    assert NEVER_NORMALISES in r.failures["Fn1_norm"]
    assert r.diagnostics["Fn1_norm"]["mass"] < 0.9
    assert r.ok("Fg2")


# -- white noise: the closure and the Monte Carlo without a dt limit -------------------------
def test_white_noise_report_marks_closure_and_monte_carlo(report):
    r = report(None, 1.0, 0.4, ("Fg1",))
    assert not r.exact and "closure, not exact" in r.failures["Fg1"]
    assert r.failures["mc_exact"] == (NO_CONVERGENCE,) == r.failures["mc_euler"]
    assert math.isnan(r.p_miss)
    with pytest.raises(ss.ParameterError, match="'key'"):
        r.ok("Fn1")  # not checked in this report
    assert report(0.1, 1.0, 0.4).failures["mc_euler"] == ()


def _mean_slip_times(model, monitor="grid"):
    out = []
    for dt in (0.01, 0.0025):
        e = ss.simulate(model, 4000, dt, 60.0, seed=1, solver="exact", monitor=monitor)
        out.append(e.mean("slip_time"))
    (a, sa), (b, sb) = out
    return a, b, math.hypot(sa, sb)


def test_white_noise_monte_carlo_does_not_converge_in_dt(Langevin):
    a, b, se = _mean_slip_times(Langevin(**BASE, D=0.4, v_b=1.0))
    assert abs(b - a) > Z * se  # measured: 12 standard errors, the mean halves
    assert b < 0.7 * a


def test_ou_noise_monte_carlo_converges_in_dt(Langevin):
    a, b, se = _mean_slip_times(Langevin(**BASE, D=0.4, v_b=1.0, tau=0.1))
    assert abs(b - a) < Z * se


def test_noise_free_white_model_converges_in_dt(Langevin):
    m = Langevin(**BASE, D=0.0, v_b=1.0)
    t_det = ss.deterministic_slip(m)
    a, b, _ = _mean_slip_times(m)
    # grid monitoring: linear interpolation between grid points, error |v''| dt^2 / 8 |v'|
    assert abs(a - t_det) < 1e-4 and abs(b - t_det) < 1e-5
    a, b, _ = _mean_slip_times(m, monitor="continuous")
    assert abs(a - t_det) < 1e-9 and abs(b - t_det) < 1e-9
    r = ss.stability_report(m, methods=("Fg1",))
    assert r.p_miss == 0.0 and "no density" in r.failures["Fg1"][0]


# -- the multiperiodic regime ----------------------------------------------------------------
def test_multiperiodic_near_the_critical_speed(report, Langevin):
    v_c = ss.critical_speed(Langevin(**BASE, D=0.0, v_b=1.0))
    near = report(0.1, 0.95 * v_c, 1e-3, ())
    assert near.regime == "multiperiodic"
    assert near.p_miss - Z * near.p_miss_se > MULTIPERIODIC_P_MISS
    slow = report(0.1, 0.5, 1e-3, ())
    assert slow.regime == "stick-slip"
    assert slow.p_miss + Z * max(slow.p_miss_se, 1 / 4000) < MULTIPERIODIC_P_MISS


# -- bad input -------------------------------------------------------------------------------
def test_bad_input():
    block = ss.get_model("friction-block").example()
    for fn in (ss.deterministic_slip, ss.critical_speed, ss.stability_report):
        with pytest.raises(ss.ParameterError, match="'model'.*no linear-Gaussian"):
            fn(block)
    m = ss.get_model("langevin")(**BASE, D=0.1, v_b=1.0)
    with pytest.raises(ss.ParameterError, match="'parameter'"):
        ss.critical_speed(m, parameter="speed")
    with pytest.raises(ss.ParameterError, match="'methods'"):
        ss.stability_report(m, methods=("Fn3",))
    with pytest.raises(ss.ParameterError, match="'t_max'"):
        ss.stability_report(m, t_max=-1.0)
