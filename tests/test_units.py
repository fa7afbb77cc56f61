"""`stickslip.units.Slider`: an experiment in SI units, its dimensionless model and results.

References are independent of the module: the real slider's parameters worked out by hand,
the undamped noise-free slip in closed form, and the lab-frame equation of motion of the
slider (position X over the track, not the model's variables) integrated by SciPy.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

import stickslip as ss
from stickslip.units import Slider

# The rig of shared/data/slider_paper_on_paper (README): m = 30.7 g, k = 168 N/m,
# V = 42 um/s, peak force 0.32 m g, force drop 0.035 m g; undamped, the drop is
# 2 (F_s - F_k), so F_k = F_s - drop / 2.
M, K, V, G = 0.0307, 168.0, 42e-6, 9.81
F_S = 0.32 * M * G
DROP = 0.035 * M * G
F_K = F_S - DROP / 2


def lab_frame_slip(m, k, V, F_s, F_k, c):
    """The noise-free slip in the lab frame: m X'' = k (F_s/k + V t - X) - F_k - c X',
    from rest at X = 0 (the spring at the threshold), until the slider stops (X' = 0).
    Returns (slip time, force drop, slider travel)."""

    def rhs(t, y):
        X, U = y
        return [U, (k * (F_s / k + V * t - X) - F_k - c * U) / m]

    def stops(t, y):
        return y[1]

    stops.terminal, stops.direction = True, -1
    T0 = 2 * math.pi * math.sqrt(m / k)
    sol = integrate.solve_ivp(
        rhs, (0.0, 5 * T0), [0.0, 0.0], method="DOP853", events=stops,
        rtol=1e-13, atol=1e-16 * max(F_s / k, 1e-300),
    )  # fmt: skip
    t_sl = float(sol.t_events[0][0])
    X = float(sol.y_events[0][0][0])
    e = F_s / k + V * t_sl - X  # spring extension at the stick
    return t_sl, F_s - k * e, X


def test_real_slider_dimensionless_by_hand():
    c = 1e-3  # kg/s
    s = Slider(M, K, V, F_S, F_K, damping=c, noise=2e-12, noise_time=1e-3)
    # by hand: omega0 = sqrt(168 / 0.0307) = 73.9751 rad/s; F_s = 0.32 * 0.0307 * 9.81 =
    # 0.0963734 N; F_s - F_k = 0.0052704 N; x0 = (0.0052704 - 1e-3 * 42e-6) / 168 =
    # 3.13713e-5 m (the c V term shifts it by 2.5e-10 m); v_b = V / (omega0 x0) =
    # 42e-6 / 2.32069e-3 = 0.018098; zeta = c / (m omega0) = 1e-3 / 2.27104 = 4.40328e-4
    omega0 = 73.9751
    x0 = (0.5 * 0.035 * 0.0307 * 9.81 - 1e-3 * 42e-6) / 168.0
    assert x0 == pytest.approx(3.13713e-5, rel=1e-5)
    p = s.dimensionless()
    assert s.scales.omega0 == pytest.approx(omega0, rel=1e-6)
    assert s.scales.time == pytest.approx(0.0135181, rel=1e-5)
    assert s.scales.length == pytest.approx(x0, rel=1e-12)
    assert s.scales.force == pytest.approx(168.0 * x0, rel=1e-12)
    assert p["omega0"] == 1.0 and p["x0"] == 1.0
    assert p["v_b"] == pytest.approx(42e-6 / (omega0 * x0), rel=1e-6)
    assert p["v_b"] == pytest.approx(0.018098, rel=1e-4)
    assert p["zeta"] == pytest.approx(1e-3 / (0.0307 * omega0), rel=1e-6)  # = c / sqrt(k m)
    assert p["zeta"] == pytest.approx(4.40328e-4, rel=1e-5)
    assert p["tau"] == pytest.approx(omega0 * 1e-3, rel=1e-6)
    assert p["D"] == pytest.approx(2e-12 / (0.0307**2 * omega0**3 * x0**2), rel=1e-6)
    m = s.model()
    assert isinstance(m, ss.get_model("langevin"))
    assert m.params()["v_b"] == p["v_b"] and m.params()["tau"] == p["tau"]
    text = s.describe()
    assert "V/(omega0 x0)" in text and "c/(m omega0)" in text and "(F_s - F_k - c V)/k" in text


def test_undamped_noise_free_cycle_closed_form():
    """omega0 T_sl = 2 pi - 2 arctan(omega0 x0 / V) exactly; the force drop is 2 (F_s -
    F_k) (x_sl = -x0 by energy); the stick reloads it at k V; and for V << omega0 x0,
    omega0 T_sl -> pi + 2 V / (omega0 x0)."""
    s = Slider(M, K, V, F_S, F_K)
    w = math.sqrt(K / M)
    x0 = (F_S - F_K) / K
    cyc = s.deterministic()
    t_sl = (2 * math.pi - 2 * math.atan(w * x0 / V)) / w
    assert cyc["slip_time"][0] == pytest.approx(t_sl, rel=1e-12)
    assert cyc["force_drop"][0] == pytest.approx(2 * (F_S - F_K), rel=1e-12)
    assert cyc["slip_distance"][0] == pytest.approx(2 * x0, rel=1e-12)
    assert cyc["stick_time"][0] == pytest.approx(2 * (F_S - F_K) / (K * V), rel=1e-12)
    assert cyc["period"][0] == pytest.approx(t_sl + 2 * (F_S - F_K) / (K * V), rel=1e-12)
    assert cyc["slider_travel"][0] == pytest.approx(2 * x0 + V * t_sl, rel=1e-12)
    assert cyc["peak_force"][0] == pytest.approx(F_S, rel=1e-12)
    u = V / (w * x0)  # 0.018: the limit holds to O(u^3)
    assert w * t_sl == pytest.approx(math.pi + 2 * u, abs=u**3)
    # and the same from the equation of motion in the lab frame
    ref = lab_frame_slip(M, K, V, F_S, F_K, 0.0)
    assert cyc["slip_time"][0] == pytest.approx(ref[0], rel=1e-8)
    assert cyc["force_drop"][0] == pytest.approx(ref[1], rel=1e-6)
    assert cyc["slider_travel"][0] == pytest.approx(ref[2], rel=1e-8)


@pytest.mark.parametrize(
    "c, V_",
    [(1e-3, 42e-6), (0.2, 42e-6), (0.05, 4e-3)],  # zeta 4.4e-4, 0.088, 0.022; v_b up to 1.7
)
def test_noise_free_cycle_matches_the_lab_frame(c, V_):
    s = Slider(M, K, V_, F_S, F_K, damping=c)
    t_sl, drop, travel = lab_frame_slip(M, K, V_, F_S, F_K, c)
    cyc = s.deterministic()
    assert cyc["slip_time"][0] == pytest.approx(t_sl, rel=1e-8)
    assert cyc["force_drop"][0] == pytest.approx(drop, rel=1e-6)
    assert cyc["slider_travel"][0] == pytest.approx(travel, rel=1e-8)
    assert cyc["stick_time"][0] == pytest.approx(drop / (K * V_), rel=1e-6)


@pytest.mark.parametrize("zeta", [0.05, 0.5])
def test_noise_free_slip_agrees_with_the_critical_speed(zeta):
    from stickslip.units import noise_free_slip

    v_c = ss.critical_speed(ss.get_model("langevin")(1.0, zeta, 0.0, 1.0, 1.0))
    assert math.isfinite(noise_free_slip(zeta, 0.999 * v_c)[0])
    assert noise_free_slip(zeta, 1.001 * v_c) == (math.inf, math.inf)
    t, _ = noise_free_slip(zeta, 0.5 * v_c)
    assert t == pytest.approx(ss.deterministic_slip(ss.get_model("langevin")(
        1.0, zeta, 0.0, 0.5 * v_c, 1.0)), rel=1e-9)  # fmt: skip


def test_simulation_without_noise_is_the_deterministic_slip():
    c = 0.2
    s = Slider(M, K, V, F_S, F_K, damping=c)
    t_sl, drop, travel = lab_frame_slip(M, K, V, F_S, F_K, c)
    run = s.simulate(3, seed=0)
    assert len(run) == 3 and run.units["force_drop"] == "N" and run.units["slip_time"] == "s"
    np.testing.assert_allclose(run["slip_time"], t_sl, rtol=1e-6)
    np.testing.assert_allclose(run["force_drop"], drop, rtol=1e-6)
    np.testing.assert_allclose(run["slider_travel"], travel, rtol=1e-6)
    np.testing.assert_allclose(run["stick_time"], drop / (K * V), rtol=1e-6)
    np.testing.assert_allclose(run["peak_force"], F_S, rtol=1e-12)
    # the dt given in seconds reaches the simulator in model units
    assert run.info["dt"] == pytest.approx(0.02 / math.sqrt(K / M), rel=1e-12)
    assert run.ensemble.info["dt"] == pytest.approx(0.02, rel=1e-12)


def test_random_static_friction_maps_onto_random_threshold():
    c, mean, sd = 0.05, F_S, 0.1 * DROP
    s = Slider(M, K, V, None, F_K, damping=c, threshold=("normal", {"mean": mean, "sd": sd}))
    offset = F_K + c * V
    x0 = (mean - offset) / K
    p = s.dimensionless()
    assert s.scales.length == pytest.approx(x0, rel=1e-12)
    assert p["threshold"] == "normal"
    assert p["threshold_params"]["mean"] == pytest.approx(1.0, rel=1e-12)
    assert p["threshold_params"]["sd"] == pytest.approx(sd / (K * x0), rel=1e-12)
    assert isinstance(s.model(), ss.get_model("random-threshold"))
    run = s.simulate(400, seed=3)
    F = run["peak_force"]
    # the drawn static friction has the law's mean and sd (its truncation at F_k + c V lies
    # 5 sd below the mean: 3e-7 of the mass); tolerances from the sampling error
    assert abs(F.mean() - mean) < 4 * sd / math.sqrt(F.size)
    assert abs(F.std(ddof=1) / sd - 1) < 4 / math.sqrt(2 * (F.size - 1))
    # each cycle is the noise-free slip from its own threshold (lab frame)
    for i in range(2):
        t_sl, drop, _ = lab_frame_slip(M, K, V, F[i], F_K, c)
        assert run["slip_time"][i] == pytest.approx(t_sl, rel=1e-6)
        assert run["force_drop"][i] == pytest.approx(drop, rel=1e-6)
    # the stick reloads the spring at k V from its stick force to the next threshold
    next_peak = s.force(run.ensemble.next_onset_state[:, 0])
    expected = np.maximum(next_peak - (F - run["force_drop"]), 0.0) / (K * V)
    np.testing.assert_allclose(run["stick_time"], expected, rtol=1e-9)


def test_round_trips():
    s = Slider(M, K, V, F_S, F_K, damping=0.01, noise=3e-12, noise_time=2e-3)
    back = s.si_parameters(s.dimensionless())
    for name in ("damping", "noise", "noise_time", "v_b", "static_friction"):
        assert back[name] == pytest.approx(getattr(s, name), rel=1e-12), name
    law = ("uniform", {"low": F_S - 0.2 * DROP, "high": F_S + 0.2 * DROP})
    r = Slider(M, K, V, None, F_K, damping=0.01, threshold=law)
    back = r.si_parameters(r.dimensionless())
    assert back["threshold"][0] == "uniform"
    for key, value in law[1].items():
        assert back["threshold"][1][key] == pytest.approx(value, rel=1e-12)
    # SI results -> model units: the simulated ensemble's own numbers
    run = s.simulate(20, seed=1)
    ens = run.ensemble
    model_units = s.to_model({k: run[k] for k in ("slip_time", "stick_time", "slip_distance")})
    np.testing.assert_allclose(model_units["slip_time"], ens.slip_time, rtol=1e-12)
    np.testing.assert_allclose(model_units["stick_time"], ens.stick_time, rtol=1e-12)
    np.testing.assert_allclose(model_units["slip_distance"], ens.slip_distance, rtol=1e-12)
    drop = s.to_model({"force_drop": run["force_drop"], "peak_force": run["peak_force"]})
    np.testing.assert_allclose(drop["force_drop"], ens.slip_distance, rtol=1e-12)
    np.testing.assert_allclose(drop["peak_force"], ens.onset_state[:, 0], rtol=1e-12)
    assert s.seconds(1.0) == pytest.approx(math.sqrt(M / K), rel=1e-12)
    assert s.newtons(2.0) == pytest.approx(2 * (F_S - F_K - 0.01 * V), rel=1e-12)
    assert s.metres(2.0) == pytest.approx(2 * (F_S - F_K - 0.01 * V) / K, rel=1e-12)


def test_measured_cycles_to_model_units_keep_their_settings():
    from stickslip.extract import Cycles

    s = Slider(M, K, V, F_S, F_K, damping=0.01)
    w = s.scales.omega0
    table = {
        "release_time": np.array([1.0, 2.5]), "slip_time": np.array([0.04, 0.05]),
        "slip_distance": np.array([6e-5, 7e-5]), "stick_time": np.array([1.4, 1.6]),
        "period": np.array([1.44, 1.65]), "peak_force": np.array([0.096, 0.097]),
        "force_drop": np.array([0.01, 0.0118]),
    }  # fmt: skip
    out = s.to_model(Cycles(table, {"sampling_interval": 5e-4, "v_b": V, "stiffness": K}))
    assert isinstance(out, Cycles)
    assert out.info["sampling_interval"] == pytest.approx(5e-4 * w, rel=1e-12)
    assert out.info["v_b"] == pytest.approx(s.dimensionless()["v_b"], rel=1e-12)
    assert out.info["si"]["stiffness"] == K
    np.testing.assert_allclose(out["period"], table["period"] * w, rtol=1e-12)
    np.testing.assert_allclose(
        out["force_drop"], table["force_drop"] / (K * s.scales.length), rtol=1e-12
    )


def test_density_in_si_units():
    """A small noise: the slip-time density in 1/s is a narrow peak at the lab frame's
    noise-free slip time, with unit mass over seconds (the first-order truncation n1: one
    upcrossing in the window; the decoupling's mass would be 1 - 1/e here)."""
    c = 0.2
    s = Slider(M, K, V, F_S, F_K, damping=c, noise=1e-10, noise_time=2e-3)
    t_det = lab_frame_slip(M, K, V, F_S, F_K, c)[0]
    t = np.linspace(0.8, 1.2, 801) * t_det  # seconds
    p = s.density("slip_time", t, method="truncation")
    mass = integrate.trapezoid(p, t)
    mean = integrate.trapezoid(t * p, t) / mass
    sd = math.sqrt(integrate.trapezoid((t - mean) ** 2 * p, t) / mass)
    assert mass == pytest.approx(1.0, abs=1e-3)
    assert abs(mean - t_det) < 0.1 * sd and sd < 0.02 * t_det


def test_to_si_refuses_another_models_ensemble():
    s = Slider(M, K, V, F_S, F_K, damping=0.2)
    other = Slider(M, K, 2 * V, F_S, F_K, damping=0.2)
    ens = ss.simulate(other.model(), 2, 0.02, 20.0, seed=0)
    with pytest.raises(ss.ParameterError, match="'ensemble'.*another model"):
        s.to_si(ens)


BAD = [
    (dict(mass=-0.03), "mass"),
    (dict(mass=float("nan")), "mass"),
    (dict(stiffness=0.0), "stiffness"),
    (dict(kinetic_friction=0.1), "kinetic_friction"),  # F_k > F_s
    (dict(kinetic_friction=-0.01), "kinetic_friction"),
    (dict(damping=-1.0), "damping"),
    (dict(noise=1e-12), "noise_time"),  # white noise
    (dict(noise=1e-12, noise_time=0.0), "noise_time"),
    # units off by orders
    (dict(noise=1e9, noise_time=1e-3), "noise"),  # N^2 s: a noise level of 1e15
    (dict(noise=1e-12, noise_time=1e-16), "noise_time"),  # 1/tau beyond 1e12 rates
    (dict(v_b=42.0), "v_b"),  # um/s typed as m/s: c V fills the friction drop
    (dict(v_b=1.0), "v_b"),  # x0 > 0 but v_b = 690, above the critical speed (~13)
    (dict(damping=1e3), "damping"),  # overdamped
    (dict(static_friction=None), "static_friction"),
    (dict(threshold=("normal", {"mean": F_S, "sd": 1e-3})), "static_friction"),  # both
]


@pytest.mark.parametrize("change, field", BAD, ids=[f"{f}-{i}" for i, (_, f) in enumerate(BAD)])
def test_bad_input_names_the_field(change, field):
    kwargs = dict(mass=M, stiffness=K, v_b=V, static_friction=F_S, kinetic_friction=F_K)
    kwargs["damping"] = 2e-3
    kwargs.update(change)
    with pytest.raises(ss.ParameterError) as err:
        Slider(**kwargs)
    assert err.value.parameter == field
    message = str(err.value)
    assert "\n" not in message and len(message) < 400 and message.startswith("Slider:")


@pytest.mark.parametrize(
    "law, field",
    [
        (("lognormal", {"median": F_S, "sigma": 0.1}), "threshold"),
        (("normal", {"mean": F_K * 0.99, "sd": 1e-3}), "threshold.mean"),
        (("uniform", {"low": F_K, "high": F_S}), "threshold.low"),
        (("uniform", {"low": F_S, "high": 0.9 * F_S}), "threshold.high"),
        (("normal", {"mean": F_S}), "threshold.sd"),
        (("normal", {"mean": F_S, "sd": 1e-3, "shape": 2}), "threshold.shape"),
        ("normal", "threshold"),
    ],
)
def test_bad_threshold_names_the_field(law, field):
    with pytest.raises(ss.ParameterError) as err:
        Slider(M, K, V, None, F_K, damping=2e-3, threshold=law)
    assert err.value.parameter == field


def test_bad_use_names_the_argument():
    s = Slider(M, K, V, F_S, F_K)  # undamped: closed forms only
    with pytest.raises(ss.ParameterError, match="'damping'"):
        s.model()
    d = Slider(M, K, V, F_S, F_K, damping=0.2)
    with pytest.raises(ss.ParameterError, match="'dt'.*seconds"):
        d.simulate(2, dt=5.0)  # 5 ms typed as 5 s
    with pytest.raises(ss.ParameterError, match="'cycles.x'"):
        d.to_model({"x": np.ones(3)})
    with pytest.raises(ss.ParameterError, match="'kind'"):
        d.density("stick_time", [0.1])


@pytest.mark.slow  # runs examples/units.py in a new process (~8 s CPU)
def test_example_runs():
    import pathlib
    import subprocess
    import sys

    script = pathlib.Path(__file__).resolve().parents[1] / "examples" / "units.py"
    out = subprocess.run(
        [sys.executable, str(script), "--paths", "50"], capture_output=True, text=True,
        timeout=300, check=True,
    ).stdout  # fmt: skip
    assert "V/(omega0 x0)" in out and "50 simulated cycles" in out and "force_drop" in out


def test_a_fitted_natural_frequency_in_si():
    """The model in this slider's units with omega0 = w is the model of a slider of mass
    m / w^2 in its own units (time rescaled by w): a Slider built from `si_parameters`
    with that mass has the dimensionless numbers zeta / w, D / w^3, v_b / w, tau w."""
    slider = Slider(M, K, 45e-6, 0.098, 0.093, damping=2e-3)
    w, zeta, D, tau = 1.37, 0.02, 0.3, 0.1
    p = slider.dimensionless()
    si = slider.si_parameters({"omega0": w, "zeta": zeta, "D": D, "tau": tau})
    assert si["mass"] == pytest.approx(K / (w * slider.scales.omega0) ** 2, rel=1e-12)
    rebuilt = Slider(
        mass=si["mass"], stiffness=K, v_b=45e-6, static_friction=0.098,
        kinetic_friction=0.093 - si["damping"] * 45e-6 + 2e-3 * 45e-6,
        damping=si["damping"], noise=si["noise"], noise_time=si["noise_time"],
    )  # fmt: skip
    q = rebuilt.dimensionless()
    assert rebuilt.scales.length == pytest.approx(slider.scales.length, rel=1e-12)
    assert q["zeta"] == pytest.approx(zeta / w, rel=1e-12)
    assert q["D"] == pytest.approx(D / w**3, rel=1e-12)
    assert q["v_b"] == pytest.approx(p["v_b"] / w, rel=1e-12)
    assert q["tau"] == pytest.approx(tau * w, rel=1e-12)
    # omega0 = 1 leaves the slider's own mass; the map is decreasing in omega0
    assert slider.si_parameters({"omega0": 1.0})["mass"] == pytest.approx(M, rel=1e-12)
    with pytest.raises(ss.ParameterError, match="omega0"):
        slider.si_parameters({"omega0": -1.0})


def _trace_cycles():
    """The Cycles of a force trace, with the settings extract_cycles records."""
    from stickslip.extract import Cycles

    table = {
        "slip_time": np.array([0.030, 0.032, 0.034]),
        "stick_time": np.array([1.2, 1.5, 1.4]),
        "peak_force": np.array([0.097, 0.099, 0.098]),
        "force_drop": np.array([0.010, 0.012, 0.014]),
    }
    return Cycles(table, {"stiffness": K, "v_b": 42e-6, "v_b_estimated": 45e-6})


def test_the_reference_slider_of_a_trace():
    """From a trace's cycles: the stiffness and the measured loading speed of its settings,
    F_s the median peak force, F_k = F_s - (median drop) / 2, damping zeta m omega0; then
    the force unit k x0 is half the median drop less c V."""
    slider = Slider.from_cycles(_trace_cycles(), M, zeta=2e-3)
    assert (slider.stiffness, slider.v_b) == (K, 45e-6)
    assert slider.static_friction == pytest.approx(0.098, rel=1e-12)
    assert slider.kinetic_friction == pytest.approx(0.098 - 0.006, rel=1e-12)
    assert slider.damping == pytest.approx(2e-3 * math.sqrt(K * M), rel=1e-12)
    assert slider.scales.force == pytest.approx(0.006 - slider.damping * 45e-6, rel=1e-12)
    given = Slider.from_cycles(_trace_cycles(), M, stiffness=100.0, v_b=40e-6)
    assert (given.stiffness, given.v_b) == (100.0, 40e-6)


@pytest.mark.parametrize(
    "cycles, kwargs, field",
    [
        ({"peak_force": [1.0]}, {}, "cycles"),
        ("no force", {}, "cycles"),
        ("no stiffness", {}, "stiffness"),
        ("ok", {"zeta": 0.0}, "zeta"),
        ("ok", {"v_b": -1.0}, "v_b"),
    ],
)
def test_the_reference_slider_refuses_in_one_line(cycles, kwargs, field):
    from stickslip.extract import Cycles

    good = _trace_cycles()
    if cycles == "ok":
        cycles = good
    elif cycles == "no force":
        cycles = Cycles({"slip_time": good["slip_time"]}, dict(good.info))
    elif cycles == "no stiffness":
        cycles = Cycles(dict(good.table), {"v_b": 42e-6})
    with pytest.raises(ss.ParameterError) as err:
        Slider.from_cycles(cycles, M, **kwargs)
    assert err.value.parameter.split(".")[0] == field and "\n" not in str(err.value)


def test_a_fits_parameters_in_si():
    """Each row maps its fitted parameter, estimate and both interval ends, through the
    slider's scales (decreasing maps swap the ends); no interval gives nan; a spread's
    interval stops at 0; D is S itself where omega0 is not fitted."""
    slider = Slider.from_cycles(_trace_cycles(), M)
    s = slider.scales
    fit = type("FitResult", (), {})()
    fit.estimate = {"omega0": 1.4, "D": 0.2, "threshold_params.mean": 1.1,
                    "threshold_params.sd": 0.3, "tau": 0.1}  # fmt: skip
    fit.ci = {"omega0": (1.3, 1.5), "D": (0.1, 0.4), "threshold_params.mean": (1.0, 1.2),
              "threshold_params.sd": (-0.1, 0.5), "tau": (math.nan, math.nan)}  # fmt: skip
    rows = {r["quantity"]: r for r in slider.si_table(fit)}
    mass = rows["effective mass k / omega_eff^2"]
    assert (mass["unit"], mass["parameter"]) == ("kg", "omega0")
    assert (mass["estimate"], mass["low"], mass["high"]) == pytest.approx(
        (M / 1.4**2, M / 1.5**2, M / 1.3**2), rel=1e-12
    )
    w = rows["natural frequency omega_eff"]
    assert (w["estimate"], w["low"], w["high"]) == pytest.approx(
        (1.4 * s.omega0, 1.3 * s.omega0, 1.5 * s.omega0), rel=1e-12
    )
    noise = rows["noise intensity S / m_eff^2"]
    assert noise["estimate"] == pytest.approx(0.2 * s.omega0**3 * s.length**2, rel=1e-12)
    sd = rows["sd of the static friction F_s"]
    assert (sd["estimate"], sd["low"], sd["high"]) == pytest.approx(
        (0.3 * s.force, 0.0, 0.5 * s.force), rel=1e-12
    )
    assert rows["mean of F_s - F_k - c V"]["high"] == pytest.approx(1.2 * s.force, rel=1e-12)
    tau = rows["noise correlation time tau_c"]
    assert tau["estimate"] == pytest.approx(0.1 * s.time) and math.isnan(tau["low"])
    fit.estimate, fit.ci = {"D": 0.2}, {"D": (0.1, 0.4)}
    (row,) = slider.si_table(fit)
    assert row["quantity"] == "noise intensity S" and row["unit"] == "N^2 s"
    assert row["estimate"] == pytest.approx(slider.si_parameters({"D": 0.2})["noise"])
    with pytest.raises(ss.ParameterError, match="must be a FitResult"):
        slider.si_table({"D": 0.2})
