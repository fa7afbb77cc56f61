"""The contract every registered model must meet (new plugins are checked automatically)."""

import numpy as np
import pytest
from conftest import assert_same_slip

import stickslip as ss
from stickslip._jax import jax, jnp

MODELS = sorted(ss.list_models().items())


@pytest.mark.parametrize("name, cls", MODELS, ids=[n for n, _ in MODELS])
def test_model_contract(name, cls):
    m = cls.example()
    assert isinstance(m, ss.FrictionModel), f"{name}: example() must return an instance"
    d = len(m.state_names)
    y0 = m.onset_state(jax.random.key(0))
    assert y0.shape == (d,) and y0.dtype == jnp.float64
    assert m.drift(y0).shape == (d,)
    assert m.diffusion(y0).shape == (d, m.noise_dim)
    if isinstance(m, ss.CreepingSlider):  # one motion through stick and slip, integrated
        e = ss.simulate(m, 2, 1e-3, 8.0, seed=0)
        assert e.n_paths == 2 and e.fraction_stuck == 1.0
        assert np.all(e.stick_time > 0) and np.all(e.slip_time > 0)
        return
    if isinstance(m, ss.ChainModel):  # per-block events: its own simulator
        run = ss.simulate_chain(m, 2, 0.02, 50.0, seed=0)
        assert run.mean_velocity.shape == (2, run.t.size) and run.n_events.shape == (2,)
        return
    assert float(m.crossing(y0)) == pytest.approx(float(m.stick_level))
    assert isinstance(m.crossing_is_smooth, bool)
    slip = m.slip_phase()  # what the compiled slip-phase code runs on: the same numbers
    if slip is not m:
        assert isinstance(slip, ss.FrictionModel)
        assert_same_slip(m, (y0, y0 + np.random.default_rng(1).normal(size=d)))
    lg = m.linear_gaussian()
    if lg is not None:
        y = y0 + 0.1
        np.testing.assert_allclose(m.drift(y), lg.A @ y + lg.b, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(m.diffusion(y), lg.B, rtol=1e-12, atol=1e-14)
        assert float(m.crossing(y)) == pytest.approx(float(lg.crossing @ y))
    solvers = ["euler", "exact"] if lg is not None else ["euler"]
    for solver in solvers:
        e = ss.simulate(m, 256, 0.01, 20.0, seed=0, solver=solver)
        assert e.n_paths == 256 and e.fraction_stuck > 0
        s = e.stuck
        assert np.all(np.isfinite(e.period[s])) and np.all(e.stick_time[s] >= 0)
