"""The frames of a study's density figures: set by the Monte Carlo histogram, not by an
approximation that diverges, with a detail panel where a narrow peak dwarfs the rest."""

import numpy as np

from stickslip.study import plots


def _gauss(x, mu, s):
    return np.exp(-0.5 * ((x - mu) / s) ** 2) / (s * np.sqrt(2 * np.pi))


X = np.arange(0.05, 15.0, 0.1)  # cell centres, as a study's slip-time grid


def test_spike_and_hump_get_a_detail_panel():
    # a quarter of the mass in an exponential peak at 0 (immediate re-sticks), the rest a hump
    y = 0.25 * np.exp(-X / 0.15) / 0.15 + 0.75 * _gauss(X, 4.0, 1.0)
    spike = plots._spike(y)
    assert spike is not None and spike.start == 0
    away = np.ones(X.size, bool)
    away[spike] = False
    # the detail's frame holds the hump's top and cuts the peak
    lo, hi = plots._frame(y[away], plots._DETAIL_HEADROOM)
    assert lo < 0 < 0.75 * _gauss(4.0, 4.0, 1.0) < hi < y[0]


def test_a_single_hump_or_two_alike_get_one_panel():
    assert plots._spike(_gauss(X, 5.0, 1.0)) is None
    assert plots._spike(_gauss(X, 4.0, 0.8) + 0.8 * _gauss(X, 10.0, 0.8)) is None
    # a narrow peak that carries almost all the mass is the distribution, not a spike
    assert plots._spike(_gauss(X, 3.0, 0.1) + 0.01 * _gauss(X, 9.0, 1.0)) is None
    assert plots._spike(np.zeros(X.size)) is None


def test_leaves_the_range():
    frame = plots._frame(np.array([0.0, 1.0, 2.0]), plots._HEADROOM)
    assert frame == (-0.06 * 2.3, 2.3)
    assert not plots._leaves(np.array([0.0, 2.2, np.nan]), frame)
    assert plots._leaves(np.array([0.0, -15.0]), frame)
    assert plots._leaves(np.array([0.0, 2.5]), frame)
    # only where `keep` says: the peak a detail panel cuts does not count
    assert not plots._leaves(np.array([5.0, 1.0]), frame, keep=np.array([False, True]))


def test_frame_widens_to_near_curves_only():
    bars = _gauss(X, 4.0, 1.0)
    top = bars.max()
    base = plots._frame(bars, plots._HEADROOM)
    # an approximation 30 % high at the top, close elsewhere, stays near: the frame holds it
    near = 1.3 * bars
    lo, hi = plots._frame(bars, plots._HEADROOM, [near])
    assert hi >= near.max() > base[1] and not plots._leaves(near, (lo, hi))
    # a diverging one (negative, or far off over the range) does not move the frame
    for far in (bars - 0.5 * top, bars + 0.8 * top):
        assert plots._frame(bars, plots._HEADROOM, [far]) == base
        assert plots._leaves(far, base)
