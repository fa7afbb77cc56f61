"""Checks of the independent trace generator (benchmarks/independent_slider.py): the slip
against closed forms and solve_ivp, the exact noise update, the thresholds' law, the
sensor; each with fixed seeds and a tolerance from the sampling error or the round-off.
(`python benchmarks/independent_slider.py --check` runs them with their numbers printed.)"""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import pathlib
import sys
import time

import numpy as np
import pytest
from scipy import integrate, optimize, stats

ROOT = pathlib.Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location(
    "independent_slider", ROOT / "benchmarks" / "independent_slider.py"
)
sim = importlib.util.module_from_spec(_spec)
sys.modules.setdefault(_spec.name, sim)  # (dataclasses look the module up)
_spec.loader.exec_module(sim)

QUIET = dict(noise_intensity=0.0, damping=0.0, gap_sd=0.0)
W0 = math.sqrt(sim.Rig().stiffness / sim.Rig().mass)


def _rig(**kw):
    return dataclasses.replace(sim.Rig(), **kw)


class _Given:
    """A normals source for `sim.slip` that hands out a prepared array in order."""

    def __init__(self, arr):
        self.arr, self.pos = arr, 0

    def take(self, n):
        self.pos += n
        return self.arr[self.pos - n : self.pos]

    def unread(self, n):
        self.pos -= n


# ---------------------------------------------------------------- 1. undamped, noise-free
def _closed_form_by_root(rig, g):
    """Slip time and drop from the exact solution of m U' = k (V t - X) - F_k from rest at
    f = g: U(t) = (g/(m w)) sin(w t) + V (1 - cos(w t)); the end is U's first zero after
    the release, bracketed by a scan and found by brentq."""
    m, k, v = rig.mass, rig.stiffness, rig.v_b
    w = math.sqrt(k / m)
    u = lambda t: g / (m * w) * math.sin(w * t) + v * (1 - math.cos(w * t))
    f = lambda t: g * math.cos(w * t) + k * v / w * math.sin(w * t)
    grid = np.linspace(1e-3 / w, 2 * math.pi / w, 4001)
    vals = np.array([u(t) for t in grid])
    i = int(np.argmax(vals <= 0))
    end = optimize.brentq(u, grid[i - 1], grid[i], xtol=1e-16, rtol=4 * np.finfo(float).eps)
    return end, g - f(end)


@pytest.mark.parametrize("g", [4.47e-3, 1e-4, 2e-2])
def test_undamped_slip_matches_closed_form(g):
    rig = _rig(**QUIET)
    t_root, d_root = _closed_form_by_root(rig, g)
    t_atan, d_atan = sim.closed_form_slip(rig, g)
    assert t_root > math.pi / W0  # later than pi / w: the far end moves during the slip
    assert abs(t_atan / t_root - 1) < 1e-12 and abs(d_atan / d_root - 1) < 1e-10
    path = sim.slip(rig, g, 0.0, 1.0, sim.propagator(rig))
    e_t, e_d = path["end"] / t_root - 1, (g - path["f_end"]) / d_root - 1
    print(f"\n[1] G={g:.2e} N: slip {1e3 * t_root:.6f} ms (pi/w {1e3 * math.pi / W0:.6f} ms), "
          f"relative error of slip time {e_t:.1e}, of drop {e_d:.1e}")
    assert abs(e_t) < 1e-8 and abs(e_d) < 1e-8
    assert np.all(path["u"] >= 0)


def test_noise_free_trace_is_regular():
    """The whole trace, noise-free and regular: every cycle has the closed-form slip time,
    drop 2G, stick time 2G/(kV), and the sampled force lies on the closed form."""
    rig = _rig(**QUIET, noise=0.0, spikes=0.0, drift=0.0)
    t, y, tr = sim.make_trace(1, 30.0, rig)
    g, kv, fk = rig.gap_mean, rig.stiffness * rig.v_b, rig.kinetic_friction
    t_slip, drop = sim.closed_form_slip(rig, g)
    assert tr["n_complete"] >= 20
    assert np.allclose(tr["slip_time"], t_slip, rtol=1e-8, atol=0)
    assert np.allclose(tr["force_drop"], drop, rtol=1e-8, atol=0)
    assert np.allclose(tr["stick_time"], 2 * g / kv, rtol=1e-8, atol=0)
    assert np.allclose(tr["threshold"], fk + g, rtol=1e-12) and np.array_equal(y, tr["force"])
    assert np.allclose(tr["release"][0], sim.LEAD, rtol=1e-12)
    # The grid: on the loading line in the sticks, on the closed form in the slips.
    rel, stk = tr["release"], tr["stick"]
    j = np.searchsorted(rel, t, side="right") - 1
    ok = (j >= 0) & (t < stk[j] + tr["stick_time"][j])  # (inside the complete rows)
    w, a = W0, kv / W0
    tau = t[ok] - rel[j[ok]]
    in_slip = tau < t_slip
    exact = np.where(in_slip, g * np.cos(w * tau) + a * np.sin(w * tau),
                     -g + kv * (t[ok] - stk[j[ok]])) + fk
    err = np.abs(y[ok] - exact)
    print(f"\n[1] regular trace: {tr['n_complete']} cycles, max |F - closed form| on the grid "
          f"{err[in_slip].max():.1e} N in slips, {err[~in_slip].max():.1e} N in sticks")
    # interpolation between slip steps: k max|U'| h^2 / 8
    bound = rig.stiffness * (g + a) / rig.mass * tr["dt"] ** 2 / 8
    assert err[in_slip].max() < 1.01 * bound and err[~in_slip].max() < 1e-12


# ---------------------------------------------------------------- 2. damped, noise-free
@pytest.mark.parametrize("zeta", [0.05, 0.3])
def test_damped_slip_matches_solve_ivp(zeta):
    rig = _rig(**{**QUIET, "damping": 2 * zeta * sim.Rig().mass * W0})
    g, m, k, c, v = 4.47e-3, rig.mass, rig.stiffness, rig.damping, rig.v_b

    def rhs(t, z):
        return [k * (v - z[1]), (z[0] - c * z[1]) / m]

    def stop(t, z):
        return z[1]

    stop.terminal, stop.direction = True, -1
    sol = integrate.solve_ivp(rhs, (0, 1.0), [g, 0.0], method="DOP853", rtol=1e-10,
                              atol=[1e-16, 1e-16], events=stop)
    t_ref, d_ref = sol.t_events[0][0], g - sol.y_events[0][0][0]
    path = sim.slip(rig, g, 0.0, 1.0, sim.propagator(rig))
    e_t, e_d = path["end"] / t_ref - 1, (g - path["f_end"]) / d_ref - 1
    print(f"\n[2] zeta={zeta}: slip {1e3 * t_ref:.6f} ms, drop {d_ref:.6e} N; relative "
          f"difference from solve_ivp (DOP853, rtol 1e-10): slip time {e_t:.1e}, drop {e_d:.1e}")
    assert abs(e_t) < 1e-8 and abs(e_d) < 1e-8


# ---------------------------------------------------------------- 3. the noise
def test_propagator_is_exact():
    """The one-step law is exact: Q against a quadrature of exp(As) B B^T exp(A^T s), and
    the two-step law equals the one-step law at 2h (Phi, Gam and Q)."""
    rig = sim.Rig()
    a, b, bw = sim.slip_matrices(rig)
    p1 = sim.propagator(rig)
    h = p1.h
    from scipy.linalg import expm

    q, _ = integrate.quad_vec(lambda s: expm(a * s) @ np.outer(bw, bw) @ expm(a * s).T, 0, h,
                              epsabs=0, epsrel=1e-12)
    scale = np.sqrt(np.outer(np.diag(q), np.diag(q)))
    e_q = np.max(np.abs(p1.cov - q) / scale)
    p2 = sim.propagator(rig, 2 * h)
    e_phi = np.max(np.abs(p1.phi @ p1.phi - p2.phi))
    e_gam = np.max(np.abs((p1.phi @ p1.gam + p1.gam - p2.gam) / p2.gam[:2].__abs__().max()))
    q2 = p1.phi @ p1.cov @ p1.phi.T + p1.cov
    e_q2 = np.max(np.abs(q2 - p2.cov) / np.sqrt(np.outer(np.diag(q2), np.diag(q2))))
    e_chol = np.max(np.abs(p1.chol @ p1.chol.T - p1.cov) / scale)
    print(f"\n[3] exact step: Q vs quadrature {e_q:.1e}, Phi(h)^2 vs Phi(2h) {e_phi:.1e}, "
          f"Gam {e_gam:.1e}, Q semigroup {e_q2:.1e}, chol {e_chol:.1e} (relative)")
    assert max(e_q, e_gam, e_q2, e_chol) < 1e-9 and e_phi < 1e-12
    ou = rig.noise_intensity / rig.noise_time * -math.expm1(-2 * h / rig.noise_time)
    assert abs(p1.cov[2, 2] / ou - 1) < 1e-12
    assert abs(p1.phi[2, 2] - math.exp(-h / rig.noise_time)) < 1e-15


@pytest.mark.slow
def test_ou_variance_and_correlation():
    """20000 independent paths of the exact step, each started at xi = 0: the variance after
    t = tau_c, and after 20 tau_c (stationary) with the correlation at lag tau_c."""
    rig = sim.Rig()
    p = sim.propagator(rig)
    n_paths, lag = 20000, round(rig.noise_time / p.h)
    rng = np.random.default_rng(12)
    z = np.zeros((3, n_paths))
    z[0] = rig.gap_mean
    xs = []
    for _ in range(20 * lag):
        z = p.phi @ z + p.gam[:, None] + p.chol @ rng.standard_normal((3, n_paths))
        xs.append(z[2].copy())
    var0 = rig.noise_intensity / rig.noise_time
    lag_t = lag * p.h
    r1 = np.var(xs[lag - 1]) / (var0 * -math.expm1(-2 * lag_t / rig.noise_time))
    r_inf = np.var(xs[-1]) / var0
    rho = np.corrcoef(xs[-1 - lag], xs[-1])[0, 1]
    rho_exp = math.exp(-lag_t / rig.noise_time)
    se_v, se_r = math.sqrt(2 / n_paths), (1 - rho_exp**2) / math.sqrt(n_paths)
    print(f"\n[3] OU: Var xi(tau_c) / exact {r1:.4f}, Var xi(20 tau_c) / (S/tau_c) {r_inf:.4f} "
          f"(se {se_v:.4f}); lag-tau_c correlation {rho:.4f} vs e^-1 {rho_exp:.4f} "
          f"(se {se_r:.4f})")
    assert abs(r1 - 1) < 4 * se_v and abs(r_inf - 1) < 4 * se_v
    assert abs(rho - rho_exp) < 4 * se_r


def test_slip_loop_follows_the_exact_step():
    """The simulator's slip loop (Python floats) is the exact step on the given normals
    (a heavy slider: a long slip), and starts from xi = 0."""
    rig = _rig(mass=50.0)
    p = sim.propagator(rig)
    normals = np.random.default_rng(5).standard_normal((40000, 3))
    f0 = 0.05  # (10 sd of xi: the slip lasts)
    path = sim.slip(rig, f0, 0.0, 0.5, p, _Given(normals))
    n = len(path["f"]) - 1 if path["end"] is None else len(path["f"]) - 2
    assert n > 20000
    z = np.array([f0, 0.0, 0.0])
    ref = [z]
    for i in range(n):
        z = p.phi @ z + p.gam + p.chol @ normals[i]
        ref.append(z)
    ref = np.array(ref)
    got = np.stack([path["f"][: n + 1], path["u"][: n + 1], path["xi"][: n + 1]], axis=1)
    assert got[0, 2] == 0.0 and got[0, 1] == 0.0
    err = np.max(np.abs(got - ref) / np.abs(ref).max(0))
    assert err < 1e-12


def _coarsen(fine, coarse, nf, ratio):
    """The normals of the coarse step (h = ratio x fine) that drive the same path as the fine
    normals nf: eta_coarse = sum_j Phi_fine^(ratio-1-j) eta_fine_j."""
    eta = (nf @ fine.chol.T).reshape(-1, ratio, 3)
    eta_c = sum(eta[:, j] @ np.linalg.matrix_power(fine.phi, ratio - 1 - j).T
                for j in range(ratio))
    return np.linalg.solve(coarse.chol, eta_c.T).T


@pytest.mark.slow
def test_xi_zero_at_every_release_and_crossings_converge():
    """xi = 0 at each release of a noisy trace; and the crossing found inside a step
    converges: the same path at steps h, h/4 and h/16 (the coarse noise made from the fine
    noise, so that the paths agree at the coarse instants) gives slip ends that converge to
    the finest one, with an error that falls faster than h (the Hermite cubic of U, whose
    dU/dt holds xi, Hoelder-1/2: about h^1.5)."""
    rig = sim.Rig()
    kt, kf, ev = sim.simulate(rig, 20.0, 3, keep_paths=True)
    assert len(ev["paths"]) > 10
    assert all(pa["xi"][0] == 0.0 and pa["u"][0] == 0.0 for pa in ev["paths"])
    assert all(np.all(pa["u"] >= 0) for pa in ev["paths"])
    h = sim.step_size(rig)
    p16, p4, p1 = (sim.propagator(rig, h / r) for r in (16, 4, 1))
    rng = np.random.default_rng(8)
    e1, e4, ends = [], [], []
    for _ in range(24):
        n16 = rng.standard_normal((16 * 2500, 3))
        t16, t4, t1 = (
            sim.slip(rig, rig.gap_mean, 0.0, 1.0, p, _Given(nn))["end"]
            for p, nn in ((p16, n16), (p4, _coarsen(p16, p4, n16, 4)),
                          (p1, _coarsen(p16, p1, n16, 16)))
        )
        e1.append(abs(t1 - t16))
        e4.append(abs(t4 - t16))
        ends.append(t16)
    m1, m4 = np.median(e1), np.median(e4)
    gain = math.exp(np.mean(np.log(np.maximum(e1, 1e-15) / np.maximum(e4, 1e-15))))
    print(f"\n[3] crossing vs the same path at h/16: median |error| {m1:.1e} s at h = {h:.2e} s, "
          f"{m4:.1e} s at h/4 (geometric-mean gain {gain:.1f}); max {max(e1):.1e} s, "
          f"{max(e4):.1e} s (slip times {1e3 * min(ends):.2f}-{1e3 * max(ends):.2f} ms)")
    assert m1 < 1e-2 * h and max(e1) < 0.1 * h and gain > 3


# ---------------------------------------------------------------- 4. thresholds
def test_gaps_follow_the_truncated_normal():
    rig = sim.Rig()
    mu, sd = rig.gap_mean, rig.gap_sd
    rng = np.random.default_rng(4)
    n = 40000
    g = np.array([sim.draw_gap(rng, mu, sd) for _ in range(n)])
    law = stats.truncnorm(-mu / sd, np.inf, loc=mu, scale=sd)
    m_exp, s_exp = law.mean(), law.std()
    kurt = float(law.stats(moments="k"))
    se_m, se_s = s_exp / math.sqrt(n), s_exp * math.sqrt((2 + kurt) / (4 * n))
    print(f"\n[4] gaps: mean {g.mean():.5e} vs {m_exp:.5e} ({(g.mean() - m_exp) / se_m:+.2f} se), "
          f"sd {g.std():.5e} vs {s_exp:.5e} ({(g.std() - s_exp) / se_s:+.2f} se), "
          f"min {g.min():.1e}")
    assert g.min() > 0
    assert abs(g.mean() - m_exp) < 4 * se_m and abs(g.std() - s_exp) < 4 * se_s
    # In a trace: the thresholds are F_k + the drawn gaps (zero-length sticks included),
    # from their own stream (the friction noise does not change them).
    _, _, tr = sim.make_trace(2, 60.0, rig)
    assert np.allclose(tr["threshold"], rig.kinetic_friction + tr["gaps"][: tr["n_complete"]])
    _, _, tr0 = sim.make_trace(2, 60.0, _rig(noise_intensity=0.0))
    n_common = min(len(tr["gaps"]), len(tr0["gaps"]))
    assert np.array_equal(tr["gaps"][:n_common], tr0["gaps"][:n_common])
    assert np.all(tr["peak_force"] >= tr["threshold"])
    zero = tr["stick_time"] == 0
    assert np.all(tr["peak_force"][1:][~zero[:-1]] == tr["threshold"][1:][~zero[:-1]])
    _, _, tr1 = sim.make_trace(2, 30.0, _rig(gap_sd=0.0))
    assert np.all(tr1["gaps"] == rig.gap_mean)


# ---------------------------------------------------------------- 5. the sensor
def _robust_sd(r):
    s = 1.4826 * np.median(np.abs(r))
    for _ in range(20):
        s_new = np.std(r[np.abs(r) < 4.5 * s])
        s_new /= math.sqrt(1 - 2 * 4.5 * stats.norm.pdf(4.5) / (1 - 2 * stats.norm.sf(4.5)))
        if abs(s_new - s) < 1e-12 * s:
            break
        s = s_new
    return s


def test_sensor_noise_spikes_drift():
    rig = sim.Rig()
    t, y, tr = sim.make_trace(6, 120.0, rig)
    r = y - tr["force"] - tr["offset"]
    n = len(r)
    s = _robust_sd(r)
    outl = np.abs(r) > 4.5 * s
    runs = int(np.sum(outl[1:] & ~outl[:-1]) + outl[0])
    se_s, se_runs = s * math.sqrt(1 / (2 * n)), math.sqrt(rig.spikes * n)
    print(f"\n[5] sensor: white sd {s:.4e} vs {rig.noise:.4e} ({(s / rig.noise - 1) * 100:+.2f} %, "
          f"se {100 * se_s / s:.2f} %); spikes {runs / n:.5f} of samples vs {rig.spikes} "
          f"({(runs - rig.spikes * n) / se_runs:+.2f} se); peak drift "
          f"{np.abs(tr['offset']).max():.3e} N")
    assert abs(s - rig.noise) < 4 * se_s + 2e-3 * rig.noise  # (+ residual spike overlap)
    assert abs(runs - rig.spikes * n) < 4 * se_runs
    assert abs(np.abs(tr["offset"]).max() - rig.drift) < 1e-15
    spec = np.abs(np.fft.rfft(tr["offset"] * np.hanning(n)))
    freq = np.fft.rfftfreq(n, 1 / rig.rate)
    assert spec[freq > 1.0].max() < 1e-4 * spec.max()  # slow: at most 2 cycles per record
    # Keyed streams: the hum and the white-noise level change nothing else.
    rig_h = _rig(hum=5e-4)
    _, y_h, tr_h = sim.make_trace(6, 120.0, rig_h)
    hum = y_h - y
    assert np.array_equal(tr_h["force"], tr["force"])
    basis = np.stack([np.sin(2 * np.pi * 50.0 * t), np.cos(2 * np.pi * 50.0 * t)], axis=1)
    coef, *_ = np.linalg.lstsq(basis, hum, rcond=None)
    assert abs(np.hypot(*coef) - 5e-4) < 1e-13 and np.abs(hum - basis @ coef).max() < 1e-13
    _, y_n, tr_n = sim.make_trace(6, 120.0, _rig(noise=2 * rig.noise))
    assert np.allclose(y_n - tr_n["force"] - tr_n["offset"], 2 * r, atol=1e-15)


def test_sensor_hum_line():
    rig = _rig(hum=3e-4)
    t, y, tr = sim.make_trace(7, 20.0, rig)
    n = len(t)
    spec = 2 * np.abs(np.fft.rfft(y - tr["force"])) / n
    freq = np.fft.rfftfreq(n, 1 / rig.rate)
    at = int(np.argmin(np.abs(freq - rig.hum_frequency)))
    floor = np.median(spec[(freq > 10) & (freq < 500)])
    _, y0, tr0 = sim.make_trace(7, 20.0, _rig(hum=0.0))
    spec0 = 2 * np.abs(np.fft.rfft(y0 - tr0["force"])) / n
    se = floor / math.sqrt(math.log(4))  # sd of one component of a bin (median of Rayleigh)
    print(f"\n[5] hum line at {freq[at]:.1f} Hz: amplitude {spec[at]:.3e} vs {rig.hum:.3e}; "
          f"without hum {spec0[at]:.1e} (noise floor {floor:.1e})")
    assert abs(spec[at] - rig.hum) < 4 * se
    assert spec0[at] < 5 * se and spec[at] > 20 * floor
    assert int(np.argmax(np.where(freq > 10, spec, 0))) == at


# ---------------------------------------------------------------- 6. speed
@pytest.mark.slow
def test_speed_of_a_300_s_trace():
    t0 = time.process_time()
    t, y, tr = sim.make_trace(0, 300.0)
    cpu = time.process_time() - t0
    print(f"\n[6] one 300 s trace at 2 kHz: {cpu:.2f} s CPU ({tr['n_complete']} complete cycles, "
          f"{len(t)} samples)")
    assert len(t) == 600000 and tr["n_complete"] > 100
