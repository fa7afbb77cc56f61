"""`FitResult.predict`: a fitted slider at another spring and speed. Checked against closed
forms (the noise-free undamped slip: half a period of the effective mass on the new
spring, a drop of twice the threshold's excess), the identity (the fit's own slider
predicted back), a measured run (the shipped public runs), and the errors."""

from __future__ import annotations

import dataclasses
import math
import pathlib
import warnings

import numpy as np
import pytest
from scipy.io import loadmat

import stickslip as ss
from stickslip._inference.result import FitResult
from stickslip.units import Slider

RIG = Slider(mass=0.03, stiffness=168.0, v_b=42e-6, static_friction=0.0964,
             kinetic_friction=0.0911, damping=1e-4, noise=1e-13, noise_time=1e-3)  # fmt: skip
DATA = pathlib.Path(__file__).resolve().parents[1] / "examples" / "data" / "slider_paper_on_paper"


def fitted(model, slider=RIG) -> FitResult:
    """A fit's result holding `model` (in `slider`'s units) as its estimate."""
    free = {"omega0": model.omega0, "D": model.D}
    return FitResult(estimate=free, ci={k: (v, v) for k, v in free.items()}, log_likelihood=0.0,
                     method="", diagnostics={"units": slider, "n_sim": 1000, "seed": 1},
                     data={}, model=model)  # fmt: skip


def test_the_fits_own_slider_comes_back():
    """The model of the rig itself, predicted at the rig's stiffness and speed, is the rig:
    the same mass, damping, noise, noise time and static friction (to rounding)."""
    back = fitted(RIG.model()).predict(stiffness=RIG.stiffness, v_b=RIG.v_b, n_sim=200)
    for field in ("mass", "stiffness", "v_b", "damping", "noise", "noise_time",
                  "static_friction", "kinetic_friction"):  # fmt: skip
        assert math.isclose(getattr(back.slider, field), getattr(RIG, field), rel_tol=1e-12)
    assert back.regime == "stick-slip" and back.p_values is None


@pytest.mark.parametrize("stiffness", [168.0, 672.0, 2254.0])
def test_an_effective_mass_moves_to_another_spring(stiffness):
    """A fitted natural frequency 1.3 sqrt(k/m) is an effective mass m / 1.69; on another
    spring, nearly without noise, the predicted slips and drops are the closed-form
    noise-free cycle (`Slider.deterministic`) of a slider built by hand with that mass on
    the new spring, the rig's friction and damping, within 0.5 % (slips near half a
    period, pi sqrt(m_eff / k'), drops near twice the threshold's excess)."""
    model = ss.get_model("langevin")(**{**RIG.dimensionless(), "omega0": 1.3})
    pred = fitted(model).predict(stiffness=stiffness, v_b=RIG.v_b, n_sim=1000)
    mass = RIG.mass / 1.3**2
    assert math.isclose(pred.slider.mass, mass, rel_tol=1e-12)
    # the damping coefficient zeta stays: c scales with the effective mass, m_eff omega_eff
    by_hand = Slider(mass=mass, stiffness=stiffness, v_b=RIG.v_b,
                     static_friction=RIG.static_friction, kinetic_friction=RIG.kinetic_friction,
                     damping=RIG.damping * mass / RIG.mass * 1.3)  # fmt: skip
    cycle = by_hand.deterministic()
    for k in ("slip_time", "force_drop"):
        assert abs(np.median(pred.cycles[k]) / float(cycle[k][0]) - 1) < 0.005, k
    assert abs(float(cycle["slip_time"][0]) / (math.pi * math.sqrt(mass / stiffness)) - 1) < 0.05


def _run(name, stiffness, v_b):
    raw = loadmat(DATA / name)
    force = raw["Fnorm"].ravel() * 0.0307 * 9.81
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ss.extract_cycles(raw["t"].ravel(), force=force, stiffness=stiffness, v_b=v_b)


def test_a_measured_run_is_predicted_through_its_measurement():
    """At the run's stiffness and loading speed, through its measurement: cycles in SI of
    the right size (slips of a few tens of ms, drops of mN), a p-value per observable in
    [0, 1]; a fit of the k = 168 N/m run predicts the k = 1002 N/m run's sticks, slips and
    drops about half as long and large as measured, and the KS test says so."""
    run168 = _run("k168Nm_v42.mat", 168.0, 42e-6)
    rig = Slider.from_cycles(run168, 0.0307, stiffness=168.0, zeta=1e-3)
    dim = rig.dimensionless()
    model = ss.get_model("random-threshold")(
        omega0=1.32, zeta=dim["zeta"], D=0.21, v_b=dim["v_b"], tau=0.1, threshold="normal",
        threshold_params={"mean": 0.9, "sd": 0.53},
    )  # fmt: skip
    fit = fitted(model, rig)
    own = fit.predict(run168, n_sim=1000)
    assert own.regime == "stick-slip"
    assert 0.01 < np.median(own.cycles["slip_time"]) < 0.06
    assert all(0.0 <= p <= 1.0 for p in own.p_values.values())
    other = fit.predict(_run("k1002Nm_v42.mat", 1002.0, 42e-6), n_sim=1000)
    for k, (model_median, data_median) in other.medians().items():
        assert model_median < 0.8 * data_median, k
        assert other.p_values[k] < 1e-6, k
    assert "k = 1002" in other.summary()


def test_what_cannot_be_predicted_is_one_line():
    bare = dataclasses.replace(fitted(RIG.model()), diagnostics={"n_sim": 1000, "seed": 1})
    with pytest.raises(ss.ParameterError, match="scales=Slider"):
        bare.predict(stiffness=168.0, v_b=42e-6)
    with pytest.raises(ss.ParameterError, match="'v_b'"):
        fitted(RIG.model()).predict(stiffness=168.0)
    with pytest.raises(ss.ParameterError, match="'stiffness'"):
        fitted(RIG.model()).predict(stiffness=-1.0, v_b=42e-6)
    with pytest.raises(ss.ParameterError, match="'run'"):
        fitted(RIG.model()).predict({"slip_time": np.ones(3)})


def test_a_saved_fit_predicts_as_the_one_saved(tmp_path):
    fit = fitted(ss.get_model("langevin")(**{**RIG.dimensionless(), "omega0": 1.2}))
    fit.save(tmp_path / "fit.json")
    back = ss.load_fit(tmp_path / "fit.json")
    assert back.diagnostics["units"] == RIG
    a = fit.predict(stiffness=400.0, v_b=60e-6, n_sim=300, seed=5)
    b = back.predict(stiffness=400.0, v_b=60e-6, n_sim=300, seed=5)
    for k in a.cycles:
        np.testing.assert_array_equal(a.cycles[k], b.cycles[k])
