"""White friction noise in dv (the paper's eq. 8 as printed) makes the stick immediate.

A path started at v = v_b re-crosses v_b at once: Brownian motion started on a level hits it
again at arbitrarily small times. Grid monitoring hides this only in part, and less and
less as dt shrinks; the Brownian-bridge test shows it at any dt. This is a property of the
model, not of the simulator: the Ornstein-Uhlenbeck version (tau > 0) is well posed.
"""

import math

import numpy as np
import pytest
from scipy.stats import norm

import stickslip as ss

WHITE = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)
N = 4000


def test_grid_euler_resticks_more_as_dt_shrinks(Langevin):
    m = Langevin(**WHITE)
    fractions = []
    for dt in (0.02, 0.005, 0.00125):
        e = ss.simulate(m, N, dt, 10.0, seed=1, solver="euler", monitor="grid")
        early = np.mean(e.slip_time < 0.1)
        fractions.append(early)
        # The first grid step already sticks with P(v_1 >= v_b) = Phi(a0 sqrt(dt / 2D)).
        p1 = norm.cdf(-1.1 * math.sqrt(dt / (2 * 0.4)))
        assert abs(e.fraction_immediate - p1) < 4 * math.sqrt(p1 * (1 - p1) / N)
    se = math.sqrt(0.25 / N)
    assert fractions[0] > 0.5
    assert fractions[1] - fractions[0] > 4 * se and fractions[2] - fractions[1] > 4 * se


@pytest.mark.parametrize("solver", ["euler", "exact"])
@pytest.mark.parametrize("dt", [0.02, 0.002])
def test_bridge_test_shows_the_degeneracy_at_any_dt(Langevin, solver, dt):
    e = ss.simulate(Langevin(**WHITE), 500, dt, 10.0, seed=2, solver=solver)
    assert e.fraction_immediate == 1.0
    assert np.all(e.slip_time == 0) and np.all(e.slip_distance == 0)


def test_ornstein_uhlenbeck_noise_is_well_posed(Langevin):
    """With tau > 0 the early-stick fraction converges as dt shrinks (no degeneracy)."""
    m = Langevin(**WHITE, tau=0.1)
    a = np.mean(ss.simulate(m, N, 0.01, 10.0, seed=3).slip_time < 0.1)
    b = np.mean(ss.simulate(m, N, 0.0025, 10.0, seed=3).slip_time < 0.1)
    assert abs(a - b) < 4 * math.sqrt(0.25 * 2 / N)
    assert a < 0.4
