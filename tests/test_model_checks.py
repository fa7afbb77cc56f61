"""A model is user code: the shapes its methods return are probed once before it is first
simulated (one line naming the method, the shape expected and the one returned), and the
paths whose state leaves the finite numbers are counted apart and said in one warning."""

from __future__ import annotations

import warnings

import jax.numpy as jnp
import numpy as np
import pytest

import stickslip as ss


class Poisoned(ss.FrictionModel):
    """An oscillator with friction noise whose drift is `poison` (nan or inf) where
    x < `below`: a model that is wrong in part of its state space only."""

    below: float = -10.0
    poison: float = float("nan")
    level: float = 1.0
    x0: float = 2.0

    @property
    def state_names(self):
        return ("x", "v")

    @property
    def noise_dim(self):
        return 1

    def drift(self, y):
        f = jnp.stack([y[1], -y[0] - 0.02 * y[1] ** 3])
        return jnp.where(y[0] < self.below, self.poison, f)

    def diffusion(self, y):
        return jnp.array([[0.0], [0.3]])

    @property
    def stick_level(self):
        return self.level

    def onset_state(self, key):
        return jnp.stack([jnp.asarray(self.x0, float), jnp.zeros(())])


def _run(model, n=1000):
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        ens = ss.simulate(model, n, 0.01, 30.0, seed=1)
    said = [str(w.message) for w in said if "finite numbers" in str(w.message)]
    return ens, said


def test_a_drift_that_is_nan_in_part_of_the_state_space_is_said():
    """Such a drift changed the stuck fraction from 0.99 to 0.55 and the mean slip time
    with no word: the paths that went there are counted apart, and where is said."""
    clean, said = _run(Poisoned())
    assert said == [] and clean.stats["nonfinite"] == 0 and not clean.nonfinite.any()
    for poison, kind in ((float("nan"), "nan"), (float("inf"), "inf")):
        ens, said = _run(Poisoned(below=-1.5, poison=poison))
        n_bad = ens.stats["nonfinite"]
        assert 0 < n_bad < ens.n_paths and n_bad == int(ens.nonfinite.sum())
        assert len(said) == 1, said
        assert f"Poisoned.drift returns {kind} at (x=-1.5" in said[0], said[0]
        assert not (ens.stuck & ens.nonfinite).any()
        assert np.all(np.isnan(ens.slip_time[ens.nonfinite]))
        # the paths that never went there are the clean run's, to the bit
        fine = ~ens.nonfinite
        np.testing.assert_array_equal(ens.slip_time[fine], clean.slip_time[fine])
        assert np.all(ens.slip_time[ens.stuck] > 0)  # (an infinite drift gave every one 0)


@pytest.mark.parametrize(
    "params, where",
    [
        (dict(below=10.0), "Poisoned.drift returns nan at (x=2, v=0)"),
        (dict(x0=float("nan")), "onset_state returns (x=nan, v=0)"),
    ],
)
def test_a_model_nan_everywhere_is_said_not_counted(params, where):
    """An all-nan drift or onset state gave 0 stuck paths silently."""
    ens, said = _run(Poisoned(**params), n=64)
    assert ens.stats["nonfinite"] == 64 and ens.fraction_stuck == 0.0
    assert len(said) == 1 and where in said[0], said


class Shaped(ss.FrictionModel):
    """A model whose methods return the shapes they are given (`shapes`)."""

    drift_shape: tuple = (2,)
    diffusion_shape: tuple = (2, 1)
    onset_shape: tuple = (2,)
    noise: int = 1
    level: float = 1.0

    @property
    def state_names(self):
        return ("x", "v")

    @property
    def noise_dim(self):
        return self.noise

    def drift(self, y):
        return jnp.ones(self.drift_shape) * y[0]

    def diffusion(self, y):
        return jnp.zeros(self.diffusion_shape) * y[0]

    @property
    def stick_level(self):
        return self.level

    def onset_state(self, key):
        return jnp.ones(self.onset_shape)


@pytest.mark.parametrize(
    "params, match",
    [
        (
            dict(drift_shape=(3,)),
            r"Shaped.drift returns shape \(3,\) for a state of shape "
            r"\(2,\) \(x, v\): expected shape \(2,\)",
        ),
        (dict(drift_shape=()), r"Shaped.drift returns shape \(\) .* expected shape \(2,\)"),
        (
            dict(diffusion_shape=(2,)),
            r"Shaped.diffusion returns shape \(2,\) .* expected "
            r"shape \(2, 1\)",
        ),
        (dict(diffusion_shape=(2, 3)), r"Shaped.diffusion returns shape \(2, 3\)"),
        (dict(onset_shape=(3,)), r"Shaped.onset_state returns shape \(3,\)"),
        (dict(noise=0), r"Shaped.noise_dim must be >= 1"),
        (dict(level=float("nan")), r"Shaped.stick_level is nan"),
        (dict(level=float("inf")), r"Shaped.stick_level is inf"),
    ],
)
def test_wrong_shapes_name_the_method_and_the_shapes(params, match):
    """They reached the user as JAX's own errors (`jvp called with different primal and
    tangent shapes`, `dot_general requires contracting dimensions`, an `IndexError` at
    noise_dim 0) or as slip times of exactly 0."""
    for simulate in (ss.simulate, ss.simulate_cycles):
        with pytest.raises(ss.ParameterError, match=match) as err:
            simulate(Shaped(**params), 8, 0.01, 1.0)
        assert "\n" not in str(err.value) and "parameter 'model'" in str(err.value)


def test_a_method_that_fails_is_named():
    class Broken(Shaped):
        def diffusion(self, y):
            return jnp.ones((2, 1)) @ jnp.ones((3, 1))

    with pytest.raises(ss.ParameterError, match=r"Broken.diffusion fails on a state of shape"):
        ss.simulate(Broken(), 8, 0.01, 1.0)


def test_every_registered_model_passes_the_probe():
    from stickslip._model_check import check_shapes

    for name in ss.list_models():
        model = ss.get_model(name).example()
        if model is not None and not isinstance(model, ss.plugin.ChainModel):
            check_shapes("simulate", model)


def test_successive_cycles_say_where_a_model_left_the_finite_numbers():
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        series = ss.simulate_cycles(Poisoned(below=-1.5), 8, 0.01, 60.0, seed=1)
    told = [str(w.message) for w in said if "finite numbers" in str(w.message)]
    assert series.stats["nonfinite"] > 0 and len(told) == 1, told
    assert "Poisoned.drift returns nan" in told[0]
