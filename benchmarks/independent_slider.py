"""Independent generator of synthetic measured stick-slip force traces.

Written from the physics alone (numpy and scipy only; nothing from ``stickslip``), to make
test data for the library's fitting.

The rig
-------
A slider of mass m rests on a track and is pulled through a spring of stiffness k whose far
end moves at constant speed V. With X(t) the slider's position and U = dX/dt >= 0 its
velocity, the sensor sees the spring force

    F(t) = k (V t - X(t))            (no constant offset: F is the spring force itself).

It is convenient to work with the force above the kinetic friction, f = F - F_k. Then, in
either phase,

    df/dt = k (V - U).

Stick (U = 0). The force rises along the loading line f(t) = f(t0) + k V (t - t0), in
closed form, until F reaches the static threshold F_s = F_k + G of the current cycle; the
slider then releases with U = 0.

Slip. Newton's law with kinetic friction F_k, a viscous damping c and a random friction
force xi(t),

    m dU/dt = f - c U + xi,
    d xi = -(xi / tau_c) dt + (sqrt(2 S) / tau_c) dW,

i.e. xi is an Ornstein-Uhlenbeck process with correlation time tau_c and intensity S
(N^2 s): stationary covariance <xi(t) xi(s)> = (S / tau_c) exp(-|t - s| / tau_c), whose
integral over the lag is 2 S. The noise is made by sliding: xi(release) = 0 at each
release, and nothing is carried through a stick. The slip ends, and the slider sticks,
when U first returns to 0 after the release.

Because the slip equations are linear with constant coefficients, the state
z = (f, U, xi) obeys the linear SDE

    dz = (A z + b) dt + B dW,
    A = [[0, -k, 0], [1/m, -c/m, 1/m], [0, 0, -1/tau_c]],  b = (k V, 0, 0),
    B = (0, 0, sqrt(2 S) / tau_c).

Over a fixed step h it is advanced *exactly in law* (no truncation error at all):

    z(t + h) = Phi z(t) + Gam + eta,   Phi = exp(A h),   Gam = int_0^h exp(A s) ds b,
    eta ~ N(0, Q),   Q = int_0^h exp(A s) B B^T exp(A^T s) ds

(Phi and Gam from the matrix exponential of the augmented 4x4 matrix [[A, b], [0, 0]] h;
Q by Van Loan's block exponential). Its xi row is the exact OU update: mean-reversion
factor exp(-h / tau_c) and conditional variance (S / tau_c) (1 - exp(-2 h / tau_c)); the
noise is drawn in the order (xi, U, f), the xi increment first with exactly that variance
and the increments of U and f from their Gaussian law conditional on it (a Cholesky
factor of Q in that order). The step is h = min(tau_c, 2 pi sqrt(m / k)) / 50, small
enough that the instants between steps are well resolved: the crossing U = 0 is located
inside the step on the cubic Hermite interpolant of U (U and dU/dt known at both ends),
and f at the crossing on the Hermite interpolant of f (df/dt = k (V - U)).

Noise-free, undamped check (c = 0, S = 0): from f(0) = G, U(0) = 0 the exact solution
with the far end moving during the slip is

    f(t) = G cos(w t) + (k V / w) sin(w t),   U(t) = (G / (m w)) sin(w t) + V (1 - cos(w t)),

w = sqrt(k / m). U returns to 0 at w T = pi + 2 arctan(k V / (w G)) (a little after pi / w),
where f = -G: the drop is exactly 2 G, since f^2 + (df/dt / w)^2 is conserved.

Thresholds. The static threshold that ends a stick is F_s = F_k + G, with G drawn when that
stick begins, independently of everything else, from a normal law of mean gap_mean and sd
gap_sd truncated to G > 0 (redrawn until positive); gap_sd = 0 gives G = gap_mean. If the
force at a stick's start already exceeds the new threshold, the stick has zero length and
the next slip starts at once from the current force.

The trace starts inside a stick, LEAD seconds of loading below the first threshold:
F(0) = F_k + G_0 - k V LEAD. Row j of the truth is slip j and the stick that follows it
(stick_time[j] = release[j+1] - stick[j]); a row is complete when both lie inside the
record. Only complete rows are in the per-cycle arrays; the partial first stick and a
partial last slip or stick are counted in ``n_slips`` / ``n_complete``.

The sensor
----------
The noise-free force is sampled on the grid t_i = i / rate (i = 0 .. round(duration rate) - 1)
-- exactly on the loading line in sticks, by linear interpolation of the fine slip solution
in slips -- and the measured force is

    y_i = F(t_i) + white_i + spike_i + drift(t_i) + hum(t_i),

each effect from its own keyed stream np.random.default_rng([seed, stream]) (streams below),
so that changing one effect leaves the others' draws unchanged:

* white: N(0, noise^2), independent per sample;
* spikes: each sample starts a spike with probability ``spikes``; a spike is 1-3 samples
  wide (uniform), of one height over its width, uniform in 5-30 noise sd, of random sign
  (overlapping spikes add);
* drift: a smooth random offset, four sinusoids of 0.5, 1, 1.5 and 2 cycles per record with
  random phases and N(0, 1/j^2) amplitudes, scaled to a peak |drift(t)| of ``drift``;
* hum: hum sin(2 pi hum_frequency t + phi), phi uniform.

Run ``python benchmarks/independent_slider.py --check`` for the checks, or
``--seed 3 --duration 300 --gap-sd 2.8e-3`` for one trace's summary.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np
from scipy.linalg import expm

# Keyed random streams: np.random.default_rng([seed, STREAM_...]).
STREAM_FRICTION = 1  # xi(t) during slips
STREAM_THRESHOLD = 2  # the gaps G
STREAM_WHITE = 3
STREAM_SPIKES = 4
STREAM_DRIFT = 5
STREAM_HUM = 6

LEAD = 0.1  # s of loading between the start of the record and the first threshold
STEPS_PER_SCALE = 50  # h = min(tau_c, 2 pi sqrt(m/k)) / STEPS_PER_SCALE


@dataclasses.dataclass(frozen=True)
class Rig:
    """The rig and the sensor (SI units); defaults near a real 30 g paper slider, with the
    effective mass from a fit."""

    mass: float = 0.0178  # m, kg
    stiffness: float = 168.0  # k, N/m
    v_b: float = 42e-6  # V, m/s
    kinetic_friction: float = 0.0911  # F_k, N
    gap_mean: float = 4.47e-3  # mean of the untruncated normal law of G, N
    gap_sd: float = 2.8e-3  # its sd, N
    damping: float = 2 * 1e-3 * 0.0178 * (168.0 / 0.0178) ** 0.5  # c = 2 zeta m w0, kg/s
    noise_intensity: float = 2.44e-8  # S, N^2 s
    noise_time: float = 1.03e-3  # tau_c, s
    rate: float = 2000.0  # samples per s
    noise: float = 2.6e-4  # white noise sd, N
    spikes: float = 0.003  # fraction of samples that start a spike
    drift: float = 1e-3  # peak offset drift, N
    hum: float = 0.0  # mains hum amplitude, N
    hum_frequency: float = 50.0  # Hz


def _check_rig(rig: Rig) -> None:
    for name in ("mass", "stiffness", "v_b", "noise_time", "rate"):
        if not getattr(rig, name) > 0:
            raise ValueError(f"Rig.{name} must be > 0, got {getattr(rig, name)!r}")
    for name in ("damping", "noise_intensity", "gap_sd", "noise", "spikes", "drift", "hum"):
        if not getattr(rig, name) >= 0:
            raise ValueError(f"Rig.{name} must be >= 0, got {getattr(rig, name)!r}")
    if rig.gap_sd == 0 and not rig.gap_mean > 0:
        raise ValueError("with gap_sd = 0 the gap is gap_mean, which must be > 0")
    if rig.gap_sd > 0 and rig.gap_mean / rig.gap_sd < -6:
        raise ValueError("gap_mean / gap_sd < -6: the truncated normal is too rarely positive")
    if not rig.spikes <= 1:
        raise ValueError("Rig.spikes is a fraction of samples")


# --------------------------------------------------------------------------- slip propagator
def step_size(rig: Rig) -> float:
    """The fixed slip step h = min(tau_c, 2 pi sqrt(m/k)) / 50."""
    period = 2 * math.pi * math.sqrt(rig.mass / rig.stiffness)
    return min(rig.noise_time, period) / STEPS_PER_SCALE


def slip_matrices(rig: Rig):
    """(A, b, B) of dz = (A z + b) dt + B dW for z = (f, U, xi)."""
    m, k, c, tau = rig.mass, rig.stiffness, rig.damping, rig.noise_time
    a = np.array([[0.0, -k, 0.0], [1 / m, -c / m, 1 / m], [0.0, 0.0, -1 / tau]])
    b = np.array([k * rig.v_b, 0.0, 0.0])
    bw = np.array([0.0, 0.0, math.sqrt(2 * rig.noise_intensity) / tau])
    return a, b, bw


@dataclasses.dataclass(frozen=True)
class Propagator:
    """Exact one-step law z(t+h) = phi z(t) + gam + chol @ n, n ~ N(0, I_3) (the rows of
    chol for (f, U, xi); its columns drawn in the order xi, U, f)."""

    h: float
    phi: np.ndarray
    gam: np.ndarray
    cov: np.ndarray
    chol: np.ndarray  # lower-triangular in the order (xi, U, f), mapped back to (f, U, xi)


def propagator(rig: Rig, h: float | None = None) -> Propagator:
    h = step_size(rig) if h is None else float(h)
    a, b, bw = slip_matrices(rig)
    aug = np.zeros((4, 4))
    aug[:3, :3], aug[:3, 3] = a * h, b * h
    e = expm(aug)
    phi, gam = e[:3, :3], e[:3, 3]
    # Van Loan: expm([[-A, B B^T], [0, A^T]] h) = [[., E12], [0, E22]], Q = E22^T E12.
    vl = np.zeros((6, 6))
    vl[:3, :3], vl[:3, 3:], vl[3:, 3:] = -a * h, np.outer(bw, bw) * h, a.T * h
    ev = expm(vl)
    cov = ev[3:, 3:].T @ ev[:3, 3:]
    cov = 0.5 * (cov + cov.T)
    # The exact OU variance for the xi entry (the same number up to round-off).
    tau, s = rig.noise_time, rig.noise_intensity
    cov[2, 2] = s / tau * -math.expm1(-2 * h / tau)
    chol = np.zeros((3, 3))
    if s > 0:
        order = [2, 1, 0]  # xi first, then U given xi, then f given both
        sub = cov[np.ix_(order, order)]
        d = np.sqrt(np.diag(sub))
        lo = np.linalg.cholesky(sub / np.outer(d, d)) * d[:, None]
        chol[np.ix_(order, order)] = lo
    return Propagator(h, phi, gam, cov, chol)


class _Normals:
    """Standard normals handed out in order from one stream, in chunks (so that the numbers a
    slip gets do not depend on the chunk size)."""

    def __init__(self, rng: np.random.Generator, chunk: int = 1 << 14):
        self.rng, self.chunk = rng, chunk
        self.buf = np.empty((0, 3))
        self.pos = 0

    def take(self, n: int) -> np.ndarray:
        if self.pos + n > len(self.buf):  # keep every answer one slice of the buffer
            fresh = self.rng.standard_normal((max(self.chunk, n), 3))
            self.buf, self.pos = np.concatenate([self.buf[self.pos :], fresh]), 0
        self.pos += n
        return self.buf[self.pos - n : self.pos]

    def unread(self, n: int) -> None:
        """Give back the last n normals taken (unused: the slip ended before them)."""
        self.pos -= n


def _first_root(c0, c1, c2, c3, exclude_zero):
    """Smallest root in (0, 1] of c0 + c1 s + c2 s^2 + c3 s^3 (None when there is none)."""
    coeffs = [c3, c2, c1] if exclude_zero else [c3, c2, c1, c0]
    roots = np.roots(np.trim_zeros(coeffs, "f")) if any(coeffs) else np.array([])
    real = roots[np.abs(roots.imag) <= 1e-9 * np.maximum(1.0, np.abs(roots.real))].real
    real = real[(real > 0) & (real <= 1 + 1e-12)]
    return float(min(real.min(), 1.0)) if len(real) else None


def slip(rig: Rig, f0: float, t0: float, t_end: float, prop: Propagator, normals=None):
    """One slip from rest (U = 0, xi = 0) at force f0 above F_k, at time t0, until U returns
    to 0 or the record ends at t_end.

    Returns a dict: 't', 'f', 'u', 'xi' (the path at t0 + n h, then the end point), 'end'
    (the stick's time, or None when the record ended first), 'f_end' (f there)."""
    m, c, k, v = rig.mass, rig.damping, rig.stiffness, rig.v_b
    h = prop.h
    (p00, p01, p02), (p10, p11, p12), (p20, p21, p22) = prop.phi.tolist()
    g0, g1, g2 = prop.gam.tolist()
    noisy = normals is not None and rig.noise_intensity > 0
    n_max = max(int(math.floor((t_end - t0) / h)), 0)
    fs, us, xs = [f0], [0.0], [0.0]
    f, u, x = f0, 0.0, 0.0
    n, end, f_end = 0, None, None
    block = 2048
    while n < n_max and end is None:
        nb = min(block, n_max - n)
        if noisy:
            eta = (normals.take(nb) @ prop.chol.T).tolist()
        else:
            eta = None
        for i in range(nb):
            if eta is None:
                f1 = p00 * f + p01 * u + p02 * x + g0
                u1 = p10 * f + p11 * u + p12 * x + g1
                x1 = p20 * f + p21 * u + p22 * x + g2
            else:
                e0, e1, e2 = eta[i]
                f1 = p00 * f + p01 * u + p02 * x + g0 + e0
                u1 = p10 * f + p11 * u + p12 * x + g1 + e1
                x1 = p20 * f + p21 * u + p22 * x + g2 + e2
            if u1 <= 0.0:
                # Crossing inside [t_n, t_n + h]: cubic Hermite of U (dU/dt = (f - cU + xi)/m).
                a0, a1 = (f - c * u + x) / m * h, (f1 - c * u1 + x1) / m * h
                c2, c3 = -3 * u - 2 * a0 + 3 * u1 - a1, 2 * u + a0 - 2 * u1 + a1
                s = _first_root(u, a0, c2, c3, n == 0 and u == 0)
                if s is None:  # (round-off) fall back on the chord
                    s = u / (u - u1) if u > u1 else 1.0
                d0, d1 = k * (v - u) * h, k * (v - u1) * h
                f_end = (
                    (2 * s**3 - 3 * s**2 + 1) * f
                    + (s**3 - 2 * s**2 + s) * d0
                    + (-2 * s**3 + 3 * s**2) * f1
                    + (s**3 - s**2) * d1
                )
                end = t0 + (n + s) * h
                fs.append(f_end)
                us.append(0.0)
                xs.append(x1)  # (xi at the step's end: not used after the stick)
                n += 1
                if noisy:
                    normals.unread(nb - i - 1)
                break
            f, u, x = f1, u1, x1
            fs.append(f)
            us.append(u)
            xs.append(x)
            n += 1
    t = t0 + h * np.arange(len(fs), dtype=float)
    if end is not None:
        t[-1] = end
    return {"t": t, "f": np.array(fs), "u": np.array(us), "xi": np.array(xs),
            "end": end, "f_end": f_end}


# --------------------------------------------------------------------------- thresholds
def draw_gap(rng: np.random.Generator, mean: float, sd: float) -> float:
    """G ~ N(mean, sd^2) truncated to G > 0, by redrawing until positive."""
    if sd == 0:
        return float(mean)
    while True:
        g = mean + sd * rng.standard_normal()
        if g > 0:
            return float(g)


# --------------------------------------------------------------------------- the trace
def simulate(rig: Rig, duration: float, seed: int, h: float | None = None, keep_paths=False):
    """The noise-free motion over [0, duration]: knots (t, F) of the force (exact on the
    sticks' loading lines between them) and the events."""
    _check_rig(rig)
    prop = propagator(rig, h)
    kv, fk = rig.stiffness * rig.v_b, rig.kinetic_friction
    rng_g = np.random.default_rng([seed, STREAM_THRESHOLD])
    normals = _Normals(np.random.default_rng([seed, STREAM_FRICTION]))
    gaps = [draw_gap(rng_g, rig.gap_mean, rig.gap_sd)]
    f = gaps[0] - kv * LEAD
    t = 0.0
    knots_t, knots_f = [np.array([0.0])], [np.array([f])]
    release, stick, peak, thresh, f_stick, paths = [], [], [], [], [], []
    while True:
        g = gaps[-1]
        wait = max(g - f, 0.0) / kv  # the stick (zero length if the force is already past)
        if t + wait > duration:
            knots_t.append(np.array([duration]))
            knots_f.append(np.array([f + kv * (duration - t)]))
            break
        t += wait
        f = max(f, g)
        release.append(t)
        peak.append(f)
        thresh.append(g)
        path = slip(rig, f, t, duration, prop, normals)
        if keep_paths:
            paths.append(path)
        knots_t.append(path["t"])
        knots_f.append(path["f"])
        if path["end"] is None:  # the record ends inside this slip
            stick.append(math.nan)
            f_stick.append(math.nan)
            break
        t, f = path["end"], path["f_end"]
        stick.append(t)
        f_stick.append(f)
        gaps.append(draw_gap(rng_g, rig.gap_mean, rig.gap_sd))
    ev = {
        "release": np.array(release),
        "stick": np.array(stick),
        "peak": np.array(peak) + fk,
        "threshold": np.array(thresh) + fk,
        "f_stick": np.array(f_stick) + fk,
        "gaps": np.array(gaps),
        "h": prop.h,
    }
    if keep_paths:
        ev["paths"] = paths
    kt, kf = np.concatenate(knots_t), np.concatenate(knots_f) + fk
    keep = np.concatenate([[True], np.diff(kt) > 0])  # (a zero-length stick repeats a knot)
    return kt[keep], kf[keep], ev


def sensor(t: np.ndarray, seed: int, rig: Rig, duration: float):
    """(white + spikes, drift + hum) on the grid t, each effect from its own keyed stream."""
    n = len(t)
    white = rig.noise * np.random.default_rng([seed, STREAM_WHITE]).standard_normal(n)
    rng = np.random.default_rng([seed, STREAM_SPIKES])
    starts = np.flatnonzero(rng.random(n) < rig.spikes)
    width = rng.integers(1, 4, len(starts))
    height = rng.uniform(5.0, 30.0, len(starts)) * rig.noise
    height *= np.where(rng.random(len(starts)) < 0.5, -1.0, 1.0)
    spikes = np.zeros(n)
    for w in (1, 2, 3):
        for j in range(w):
            sel = starts[width == w] + j
            ok = sel < n
            np.add.at(spikes, sel[ok], height[width == w][ok])
    rng = np.random.default_rng([seed, STREAM_DRIFT])
    amp = rng.standard_normal(4) / np.arange(1, 5)
    phase = rng.uniform(0, 2 * np.pi, 4)
    freq = np.arange(1, 5) * 0.5 / duration
    drift = (amp[:, None] * np.sin(2 * np.pi * freq[:, None] * t[None, :] + phase[:, None])).sum(0)
    peak = np.abs(drift).max() if n else 0.0
    drift = drift * (rig.drift / peak) if peak > 0 else drift * 0.0
    phi = np.random.default_rng([seed, STREAM_HUM]).uniform(0, 2 * np.pi)
    hum = rig.hum * np.sin(2 * np.pi * rig.hum_frequency * t + phi)
    return white + spikes, drift + hum


def make_trace(seed: int, duration: float = 300.0, rig: Rig = Rig()):  # noqa: B008
    """(t in s, measured force in N, truth).

    truth, per complete cycle (row j = slip j and the stick that follows it):
    'release' (s), 'stick' (s, the slip's end), 'slip_time', 'stick_time'
    (release[j+1] - stick[j]), 'peak_force' (F at release, noise-free), 'force_drop'
    (F at release minus F at stick), 'threshold' (F_s of that release); and
    'rig' (the Rig as a dict), 'force' (the noise-free force on the grid), 'offset'
    (drift + hum on the grid), 'gaps' (every G drawn, in order), 'n_slips' (releases in
    the record, complete or not), 'n_complete', 'dt' (the slip step)."""
    kt, kf, ev = simulate(rig, duration, seed)
    n = int(round(duration * rig.rate))
    t = np.arange(n) / rig.rate
    force = np.interp(t, kt, kf)
    noise, offset = sensor(t, seed, rig, duration)
    rel, stk = ev["release"], ev["stick"]
    nc = max(len(rel) - 1, 0)  # row j is complete when release j+1 happened in the record
    nc = min(nc, int(np.sum(np.isfinite(stk))))
    rows = slice(0, nc)
    truth = {
        "release": rel[rows],
        "stick": stk[rows],
        "slip_time": stk[rows] - rel[rows],
        "stick_time": rel[1 : nc + 1] - stk[rows],
        "peak_force": ev["peak"][rows],
        "force_drop": ev["peak"][rows] - ev["f_stick"][rows],
        "threshold": ev["threshold"][rows],
        "rig": dataclasses.asdict(rig),
        "force": force,
        "offset": offset,
        "gaps": ev["gaps"],
        "n_slips": len(rel),
        "n_complete": nc,
        "dt": ev["h"],
    }
    return t, force + noise + offset, truth


# --------------------------------------------------------------------------- checks
def closed_form_slip(rig: Rig, g: float):
    """(slip time, drop) of the undamped noise-free slip from rest at f = g (exact)."""
    w = math.sqrt(rig.stiffness / rig.mass)
    a = rig.stiffness * rig.v_b / w
    return (math.pi + 2 * math.atan2(a, g)) / w, 2 * g


def _main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--check", action="store_true", help="run the checks and print them")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--duration", type=float, default=300.0)
    p.add_argument("--gap-sd", type=float, default=None)
    args = p.parse_args()
    if args.check:
        import pathlib
        import sys

        import pytest

        test = pathlib.Path(__file__).resolve().parents[1] / "tests" / "test_independent_slider.py"
        sys.exit(pytest.main([str(test), "-q", "-s", "-n", "0", "-m", "", "-p",
                              "no:cacheprovider"]))
    rig = Rig() if args.gap_sd is None else dataclasses.replace(Rig(), gap_sd=args.gap_sd)
    t0 = time.process_time()
    t, y, truth = make_trace(args.seed, args.duration, rig)
    cpu = time.process_time() - t0
    print(f"seed {args.seed}, {args.duration:g} s at {rig.rate:g} Hz ({len(t)} samples), "
          f"gap_sd {rig.gap_sd:g} N, slip step {truth['dt']:.3g} s; {cpu:.2f} s CPU")
    print(f"slips in the record {truth['n_slips']}, complete cycles {truth['n_complete']}")
    if truth["n_complete"]:
        drop = truth["force_drop"]
        q = np.quantile(drop, [0.05, 0.25, 0.5, 0.75, 0.95])
        print(f"mean stick time {truth['stick_time'].mean():.4f} s, "
              f"mean slip time {1e3 * truth['slip_time'].mean():.3f} ms")
        print("force drop quantiles 5/25/50/75/95 %: " + ", ".join(f"{x:.3e}" for x in q) + " N")
        print(f"zero-length sticks {int(np.sum(truth['stick_time'] == 0))}")


if __name__ == "__main__":
    _main()
