"""`random-threshold-held`: a stick already past the next threshold releases from where it
is (the force cannot jump), where `random-threshold` (the paper's sharp reset) starts that
slip from the threshold drawn.

- The chain's rule, cycle by cycle: every slip starts at or above the last stick's
  position, exactly there after a zero-length stick; the reset model breaks it.
- Against a generator that shares no code with the library
  (`benchmarks/independent_slider.py`: its own exact-in-law integrator, OU friction noise,
  its own truncated normal, the force held at a release): the same laws of slip time,
  force drop and stick time, the same share of zero-length sticks, and the same drops
  after them (slow).
"""

import numpy as np
import pytest
from conftest import benchmark_module
from scipy import stats

import stickslip as ss


def _chain(name, n_paths=4, t_max=1000.0, seed=3, **kw):
    """Successive cycles of a slider where a slip often ends early (noise) before a low
    next threshold."""
    params = dict(omega0=1.0, zeta=0.05, D=1.0, v_b=0.5, tau=0.1, threshold="normal",
                  threshold_params={"mean": 1.0, "sd": 0.6})  # fmt: skip
    model = ss.get_model(name)(**{**params, **kw})
    return ss.simulate_cycles(model, n_paths, 0.01, t_max, seed=seed, record=False).cycles


def _next_onsets(c):
    """(stick position, stick time, next slip's onset position) of consecutive cycles."""
    same = c["path"][1:] == c["path"][:-1]
    onset = c["stick_position"] + c["slip_distance"]
    return c["stick_position"][:-1][same], c["stick_time"][:-1][same], onset[1:][same]


def test_a_held_release_starts_where_the_stick_is():
    stick, wait, onset = _next_onsets(_chain("random-threshold-held"))
    held = wait == 0
    assert held.sum() >= 100 and (~held).sum() > 400
    assert np.all(onset >= stick - 1e-12)
    np.testing.assert_allclose(onset[held], stick[held], rtol=0, atol=1e-12)
    # a stick of positive length ends at the threshold drawn, above the stick position
    assert np.all(onset[~held] > stick[~held])


def test_the_sharp_reset_starts_below_the_stick():
    """The same slider under the paper's reset: after a zero-length stick the slip starts
    at the threshold drawn, below the force the spring holds (the test above can fail)."""
    stick, wait, onset = _next_onsets(_chain("random-threshold"))
    held = wait == 0
    assert held.sum() >= 100 and np.all(onset[held] < stick[held])


def test_the_held_model_is_the_reset_one_without_overshoot():
    """A narrow threshold law and little noise: no stick reaches the next threshold, and the
    two models' cycles agree in law (KS on the periods)."""
    kw = dict(D=0.01, threshold_params={"mean": 1.0, "sd": 0.05})
    a, b = _chain("random-threshold-held", **kw), _chain("random-threshold", **kw)
    assert np.all(a["stick_time"] > 0) and np.all(b["stick_time"] > 0)
    assert stats.ks_2samp(a["period"], b["period"]).pvalue > 1e-3


def _generator():
    return benchmark_module("independent_slider")


def _generated(gen, rig, seeds, duration):
    """Per complete cycle in SI: slip time, force drop, stick time, and whether the next
    release was held (its stick of zero length); the drops of the slips after one."""
    slip, drop, wait, after = [], [], [], []
    for seed in seeds:
        _, _, ev = gen.simulate(rig, duration, seed)
        release, stick, peak, f_stick = ev["release"], ev["stick"], ev["peak"], ev["f_stick"]
        n = np.flatnonzero(np.isfinite(stick))[:-1]  # a complete cycle: the next release seen
        n = n[n + 1 < release.size]
        slip.append(stick[n] - release[n])
        drop.append(peak[n] - f_stick[n])
        w = release[n + 1] - stick[n]
        wait.append(w)
        nxt = n[w == 0] + 1
        nxt = nxt[np.isfinite(f_stick[nxt])]
        after.append(peak[nxt] - f_stick[nxt])
    return [np.concatenate(v) for v in (slip, drop, wait, after)]


def _modelled(name, slider, n_paths, t_max, seed):
    dim = slider.dimensionless()
    model = ss.get_model(name)(**dim)
    c = ss.simulate_cycles(model, n_paths, 0.02, t_max, seed=seed, record=False).cycles
    sc = slider.scales
    to_n = slider.stiffness * sc.length  # a model length as a force
    same = c["path"][1:] == c["path"][:-1]
    wait = c["stick_time"] * sc.time
    after = (c["slip_distance"][1:] * to_n)[same & (c["stick_time"][:-1] == 0)]
    return c["slip_time"] * sc.time, c["slip_distance"] * to_n, wait, after


@pytest.mark.slow
def test_the_held_model_matches_an_independent_generator():
    truth_slider = benchmark_module("fit_independent").truth_slider
    gen = _generator()
    rig = gen.Rig(gap_sd=2.8e-3)
    slider = truth_slider(rig)
    slip, drop, wait, after = _generated(gen, rig, range(900, 910), 300.0)
    held_share = np.mean(wait == 0)
    assert slip.size > 1500 and np.sum(wait == 0) > 40
    for name in ("random-threshold-held", "random-threshold"):
        m_slip, m_drop, m_wait, m_after = _modelled(name, slider, 16, 40_000.0, 5)
        p = {
            "slip time": stats.ks_2samp(slip, m_slip).pvalue,
            "drop": stats.ks_2samp(drop, m_drop).pvalue,
            "stick time": stats.ks_2samp(wait, m_wait).pvalue,
            "drop after a zero stick": stats.ks_2samp(after, m_after).pvalue,
        }
        # the share of zero-length sticks: a two-sample binomial z
        q = np.mean(m_wait == 0)
        se = np.sqrt(held_share * (1 - held_share) / wait.size + q * (1 - q) / m_wait.size)
        p["zero sticks"] = 2 * stats.norm.sf(abs(held_share - q) / se)
        print(name, {k: f"{v:.3g}" for k, v in p.items()}, f"held {held_share:.3f} {q:.3f}")
        if name == "random-threshold-held":
            assert min(p.values()) > 1e-3, p
        else:  # the reset starts those slips lower: their drops are smaller
            assert p["drop after a zero stick"] < 1e-3, p


@pytest.mark.slow
def test_the_generator_slips_carry_the_truths_noise_intensity():
    """KS tests cannot see a noise intensity a few per cent off; the drop's spread at a
    given release force can: the independent generator's matches the held model's at the
    truth's intensity, and not at 0.85 or 1.15 times it (the statistic resolves that)."""
    truth_slider = benchmark_module("fit_independent").truth_slider
    residual_spread = benchmark_module("generator_physics").residual_spread
    gen = _generator()
    rig = gen.Rig(gap_sd=2.8e-3)
    gap, drop = [], []
    for seed in range(910, 930):
        _, _, ev = gen.simulate(rig, 1000.0, seed)
        n = np.isfinite(ev["stick"])
        gap.append(ev["peak"][n] - rig.kinetic_friction)
        drop.append(ev["peak"][n] - ev["f_stick"][n])
    g_sd, g_se = residual_spread(np.concatenate(gap), np.concatenate(drop))
    slider = truth_slider(rig)
    dim = slider.dimensionless()
    to_n = rig.stiffness * slider.scales.length
    z = {}
    for factor in (0.85, 1.0, 1.15):
        model = ss.get_model("random-threshold-held")(**{**dim, "D": dim["D"] * factor})
        c = ss.simulate_cycles(model, 50, 0.02, 40_000.0, seed=6, record=False).cycles
        m_drop = c["slip_distance"] * to_n
        m_sd, m_se = residual_spread(c["stick_position"] * to_n + m_drop, m_drop)
        z[factor] = (g_sd - m_sd) / np.hypot(g_se, m_se)
    print({k: f"{v:+.2f}" for k, v in z.items()})
    assert abs(z[1.0]) < 4, z
    assert z[0.85] > 4 and z[1.15] < -4, z
