"""Force traces with known cycles, made independently of `stickslip.extract`: a slider of
mass m pulled at speed V through a spring k over a surface with a random static threshold
per cycle and Coulomb kinetic friction plus viscous damping, integrated by RK4 on a step
50 times finer than the sampling; then sensor noise, spikes, an offset drift, creep and,
optionally, a mains hum.

Truth is what the simulation did: a slip starts when the spring force reaches the cycle's
threshold (the slider at rest) and ends when the slider's velocity returns to 0; the next
threshold is drawn then, and if the force already exceeds it the slider slips at once (a
zero-length stick)."""

from __future__ import annotations

import dataclasses

import numpy as np

G = 9.81


@dataclasses.dataclass
class Rig:
    mass: float = 0.0307  # kg, as the paper-on-paper experiment
    stiffness: float = 168.0  # N/m
    v_b: float = 42e-6  # m/s
    rate: float = 2000.0  # samples per s
    threshold: float = 0.32 * 0.0307 * G  # mean static threshold (N)
    threshold_sd: float = 0.004  # N
    gap_mean: float = 0.0045  # mean of static less kinetic friction (N)
    gap_shape: float = 3.0  # gamma shape: some small drops, down to a few noise sd
    damping: float = 0.6  # 1/s per unit mass: c/m
    immediate: float = 0.04  # chance that the next threshold is below the force: re-slip
    noise: float = 2.6e-4  # N, white sensor noise (the real trace's ~0.00088 m g)
    spikes: float = 0.005  # fraction of samples that start a spike
    spike_sd: tuple = (5.0, 30.0)  # spike heights, in noise sd (uniform, either sign)
    drift: float = 2e-3  # N, peak offset drift over the record
    creep: float = 3.0  # noise sd: the force falls behind the loading line before a slip
    creep_time: float = 0.05  # s
    hum: float = 0.0  # noise sd: amplitude of a mains hum (the measured trace: ~0.7)
    hum_frequency: float = 50.0  # Hz


def make_trace(seed: int, duration: float = 60.0, rig: Rig | None = None):
    """(t, force, truth) with truth a dict of arrays per slip: release, stick (end of the
    slip), peak (force at release), drop (release less stick force), next_release."""
    rig = rig or Rig()
    rng = np.random.default_rng(seed)
    m, k, V = rig.mass, rig.stiffness, rig.v_b
    h = 1.0 / rig.rate
    dt = h / 50.0
    c = rig.damping
    t_now, force = 0.0, rig.threshold - 0.01  # start inside a stick
    events, paths = [], []  # (release, stick, F0, F1); each slip's fine (time, force)
    while t_now < duration:
        threshold = rig.threshold + rig.threshold_sd * rng.standard_normal()
        if rng.random() < rig.immediate and events:
            threshold = force - 1e-4
        release = t_now + max(0.0, (threshold - force) / (k * V))
        f0 = max(threshold, force)
        kinetic = f0 - rig.gap_mean * rng.gamma(rig.gap_shape) / rig.gap_shape
        # slip: dF/dt = k (V - u), m du/dt = F - kinetic - c m u, from u = 0
        f, u, tau = f0, 0.0, 0.0
        path_t, path_f = [release], [f0]

        def rhs(f, u, kinetic=kinetic):
            return k * (V - u), (f - kinetic) / m - c * u

        while True:
            k1 = rhs(f, u)
            k2 = rhs(f + 0.5 * dt * k1[0], u + 0.5 * dt * k1[1])
            k3 = rhs(f + 0.5 * dt * k2[0], u + 0.5 * dt * k2[1])
            k4 = rhs(f + dt * k3[0], u + dt * k3[1])
            fn = f + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            un = u + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            if tau > 0 and un <= 0:  # the slider stops: interpolate the crossing
                frac = u / (u - un)
                tau += frac * dt
                f += frac * (fn - f)
                break
            f, u, tau = fn, un, tau + dt
            path_t.append(release + tau)
            path_f.append(f)
        path_t.append(release + tau)
        path_f.append(f)
        paths.append((np.array(path_t), np.array(path_f)))
        events.append((release, release + tau, f0, f))
        t_now, force = release + tau, f
    ev = np.array(events)
    t = np.arange(0.0, duration, h)
    clean = _render(t, ev, paths, rig)
    noisy = clean + rig.noise * rng.standard_normal(t.size)
    noisy += rig.drift * np.sin(np.pi * t / duration + rng.uniform(0, np.pi))
    if rig.hum:
        phase = rng.uniform(0.0, 2 * np.pi)
        noisy += rig.hum * rig.noise * np.sin(2 * np.pi * rig.hum_frequency * t + phase)
    starts = np.flatnonzero(rng.random(t.size) < rig.spikes)
    for s in starts:
        width = rng.integers(1, 4)
        noisy[s : s + width] += rig.noise * rng.uniform(*rig.spike_sd) * rng.choice([-1, 1])
    lag = rig.creep * rig.noise  # the force at a release lags its threshold by the creep
    truth = dict(
        release=ev[:, 0], stick=ev[:, 1], peak=ev[:, 2] - lag, drop=ev[:, 2] - lag - ev[:, 3],
        next_release=np.append(ev[1:, 0], np.inf),
    )  # fmt: skip
    return t, noisy, truth


def _render(t, ev, paths, rig):
    """The force on the sampling grid: loading lines in the sticks (falling behind by the
    creep just before a release), the slips interpolated from their fine paths."""
    load = rig.stiffness * rig.v_b
    out = np.empty(t.size)
    prev_stick, prev_force = -np.inf, ev[0, 2] - load * ev[0, 0]
    for (release, stick, _, f1), (path_t, path_f) in zip(ev, paths, strict=True):
        sel = (t >= prev_stick) & (t < release)
        start = max(prev_stick, 0.0) if np.isfinite(prev_stick) else 0.0
        out[sel] = prev_force + load * (t[sel] - start)
        out[sel] -= rig.creep * rig.noise * np.exp((t[sel] - release) / rig.creep_time)
        sel = (t >= release) & (t < stick)
        # the creep's lag fades out over the slip: the force is continuous at both ends
        fade = 1.0 - (t[sel] - release) / (stick - release)
        out[sel] = np.interp(t[sel], path_t, path_f) - rig.creep * rig.noise * fade
        prev_stick, prev_force = stick, f1
    sel = t >= prev_stick
    out[sel] = prev_force + load * (t[sel] - prev_stick)
    return out
