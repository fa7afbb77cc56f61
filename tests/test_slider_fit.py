"""The measured slider fitted end to end (examples/slider_fit.py) and the pieces it needs:
a force trace's cycles in SI fitted in the model's units, the fitted model's cycles as the
data see them (a fitted natural frequency in SI: tests/test_units.py)."""

import importlib.util
import itertools
import json
import math
import pathlib
import subprocess
import sys
import types

import numpy as np
import pytest

import stickslip as ss
from stickslip._extract import Cycles
from stickslip._inference.data import measurement_of
from stickslip.units import Slider

ROOT = pathlib.Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "slider_fit.py"
RIG = dict(mass=0.0307, stiffness=168.0, v_b=45e-6, static_friction=0.098,
           kinetic_friction=0.093, damping=2e-3)  # fmt: skip


def _force_cycles(n=12, seed=0):
    """A force trace's cycles in s, m and N, with the settings extract_cycles records."""
    rng = np.random.default_rng(seed)
    drop = rng.uniform(0.004, 0.016, n)
    slip = rng.uniform(0.02, 0.04, n)
    stick = drop / (168.0 * 45e-6) + rng.normal(0, 0.05, n)
    table = dict(slip_time=slip, slip_distance=drop / 168.0, stick_time=stick,
                 period=slip + stick, peak_force=0.098 + rng.normal(0, 0.003, n),
                 force_drop=drop)  # fmt: skip
    info = dict(
        input="force", sampling_interval=5e-4, noise_sd=1.9e-4, window=29,
        thresholds=dict(spike=5.0, slip=5.0, extent=2.0, drop=5.0, split=25.0),
        n_spikes=8239, n_samples=751281, spike_threshold=1.3e-3, lines_removed=[50.01],
        v_b=42e-6, v_b_estimated=45e-6, stiffness=168.0,
    )  # fmt: skip
    return Cycles(table, info)


def test_a_force_trace_in_si_is_fitted_in_the_model_units():
    """fit's data are put in the units its measurement was read in: the table of a force
    trace in s, m and N with `scales` becomes what `Slider.to_model` makes of it (before,
    stick times in seconds were scored against simulated ones in units of 1/omega0)."""
    slider = Slider(**RIG)
    cycles = _force_cycles()
    table, measurement = measurement_of(cycles, scales=slider)
    # by hand: omega0 = sqrt(k/m), x0 = (F_s - F_k - c V)/k
    omega0 = math.sqrt(168.0 / 0.0307)
    x0 = (0.098 - 0.093 - 2e-3 * 45e-6) / 168.0
    np.testing.assert_allclose(table["stick_time"], cycles["stick_time"] * omega0, rtol=1e-12)
    np.testing.assert_allclose(table["slip_time"], cycles["slip_time"] * omega0, rtol=1e-12)
    np.testing.assert_allclose(table["slip_distance"], cycles["slip_distance"] / x0, rtol=1e-12)
    np.testing.assert_allclose(table["force_drop"], cycles["force_drop"] / (168.0 * x0),
                               rtol=1e-12)  # fmt: skip
    # the slip distance of a force trace is its drop over k: one number in the model's units
    np.testing.assert_allclose(table["slip_distance"], table["force_drop"], rtol=1e-12)
    assert measurement.sampling_interval == pytest.approx(5e-4 * omega0, rel=1e-12)
    # the same as converting first (Slider.to_model): no second conversion
    converted, again = measurement_of(slider.to_model(cycles), scales=slider)
    assert again == measurement
    for name, values in converted.items():
        np.testing.assert_allclose(table[name], values, rtol=1e-12, err_msg=name)
    # a study's scales (time and force only): the length from the trace's stiffness; the
    # peak force, which needs the force offset and is not fitted, is left out
    study = types.SimpleNamespace(time=slider.scales.time, force=slider.scales.force)
    plain, _ = measurement_of(cycles, scales=study)
    assert set(plain) == set(table) - {"peak_force"}
    for name, values in plain.items():
        np.testing.assert_allclose(values, table[name], rtol=1e-12, err_msg=name)


def test_a_model_loaded_off_the_datas_speed_is_warned_about():
    """The sticks of the measured trace load at 7 % above the nominal speed: a model fixed
    at the nominal v_b would put every stick time 7 % off; fit says so (the check itself:
    the loading speed in the data against the fixed v_b through the scales)."""
    from stickslip._inference.fit import _loading_speed_mismatch

    slider = Slider(**RIG)
    velocity = slider.scales.velocity
    cycles = _force_cycles()  # loaded at 45 um/s
    said = _loading_speed_mismatch(cycles, {"v_b": 42e-6 / velocity}, slider)
    assert "-7 % off the speed the data's sticks were loaded at" in said
    assert "\n" not in said
    assert _loading_speed_mismatch(cycles, {"v_b": 45e-6 / velocity}, slider) is None
    # the same through Slider.to_model (the settings under info["si"])
    converted = slider.to_model(cycles)
    assert _loading_speed_mismatch(converted, {"v_b": 42e-6 / velocity}, slider.scales) == said
    # nothing to compare: per-cycle values, a free v_b, no scales
    assert _loading_speed_mismatch(cycles.table, {"v_b": 1.0}, slider) is None
    assert _loading_speed_mismatch(cycles, {}, slider) is None
    assert _loading_speed_mismatch(cycles, {"v_b": 1.0}, None) is None


def test_the_fitted_models_cycles_as_the_data_see_them():
    """`FitResult.simulated`: per-cycle values are the slips of positive length that
    ended, as `simulate` gives them (an independent call here), with the data's columns."""
    from stickslip._inference.result import FitResult

    m = ss.get_model("langevin")(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
    diagnostics = dict(n_sim=2000, dt=0.2, t_max=60.0, seed=5, measurement=None)
    data = {"slip_time": np.ones(10), "stick_time": np.ones(10)}
    r = FitResult({}, {}, 0.0, "", diagnostics, data, m)
    got = r.simulated(1500, seed=9)
    ens = ss.simulate(m, 1500, 0.2, 60.0, seed=9)
    keep = ens.stuck & ~ens.immediate
    assert set(got) == set(data)
    np.testing.assert_array_equal(got["slip_time"], ens.slip_time[keep])
    np.testing.assert_array_equal(got["stick_time"], ens.stick_time[keep])
    assert r.simulated()["slip_time"].size > 1000  # the fit's own n_sim and seed


def test_many_measured_cycles_go_in_chunks(monkeypatch):
    """A request through a measurement is simulated in chunks (a bootstrap's 50 000 cycles
    of the measured slider asked 17.9 GB for one recorded trace): up to a chunk nothing
    changes, beyond it the first chunk is the request of one chunk and the others are
    further, independent cycles."""
    from stickslip._inference import forward
    from stickslip._inference.measurement import Measurement, measured_cycles

    m = ss.get_model("langevin")(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
    meas = Measurement(sampling_interval=0.1, signal="x", noise_sd=1e-3,
                       columns=("slip_time", "stick_time"))  # fmt: skip
    monkeypatch.setattr(forward, "MEASURED_CHUNK", 40)
    one = forward.simulate_values(m, 40, None, None, 7, meas)
    alone = measured_cycles(m, meas, 40, 7)
    for k in alone:
        np.testing.assert_array_equal(one[k], alone[k])
    many = forward.simulate_values(m, 95, None, None, 7, meas)  # chunks of 40, 40 and 15
    first = alone["slip_time"].size
    np.testing.assert_array_equal(many["slip_time"][:first], alone["slip_time"])
    rest = many["slip_time"][first:]
    assert rest.size > alone["slip_time"].size  # 55 model cycles against 40
    assert not np.isin(rest, alone["slip_time"]).any()  # other draws


def _example():
    spec = importlib.util.spec_from_file_location("slider_fit", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_examples_pieces():
    """The candidates nest (the random threshold's law contains the fixed one: sd = 0),
    share what is known, and the SI rows map each free parameter's interval end to end by
    the slider's scales."""
    ex = _example()
    cycles = _force_cycles(40)
    slider = ex.reference_slider(cycles)
    s = slider.scales
    assert slider.v_b == 45e-6  # the sticks' measured slope, not the nominal speed
    assert s.omega0 == pytest.approx(math.sqrt(168.0 / 0.0307), rel=1e-12)
    # the force unit k x0 = F_s - F_k - c V: half the median drop, less the viscous c V
    half_drop = 0.5 * np.median(cycles["force_drop"])
    assert s.force == pytest.approx(half_drop - slider.damping * 45e-6, rel=1e-12)
    specs = ex.candidates(slider)
    (m1, free1, fixed1), (m2, free2, fixed2) = specs["fixed threshold"], specs["random threshold"]
    assert (m1, m2) == ("langevin", "random-threshold")
    assert set(free1) - {"x0"} <= set(free2) and free2["threshold_params.sd"][0] == 0.0
    assert all(fixed2[k] == v for k, v in fixed1.items())
    fake = type("R", (), {})()
    fake.estimate = {"omega0": 1.4, "threshold_params.mean": 1.1,
                     "threshold_params.sd": 0.3, "D": 0.2}  # fmt: skip
    fake.ci = {"omega0": (1.3, 1.5), "threshold_params.mean": (1.0, 1.2),
               "threshold_params.sd": (0.2, 0.4), "D": (0.1, 0.4)}  # fmt: skip
    rows = {label: (unit, v, lo, hi) for label, unit, v, lo, hi in ex.si_parameters(fake, slider)}
    unit, v, lo, hi = rows["effective mass k / omega_eff^2"]
    assert (unit, v) == ("kg", pytest.approx(0.0307 / 1.4**2, rel=1e-12))
    assert (lo, hi) == (pytest.approx(0.0307 / 1.5**2), pytest.approx(0.0307 / 1.3**2))
    assert rows["sd of the static friction F_s"][1:] == pytest.approx(
        (0.3 * s.force, 0.2 * s.force, 0.4 * s.force), rel=1e-12
    )
    assert rows["half period pi / omega_eff"][1] == pytest.approx(
        math.pi * math.sqrt(0.0307 / 168.0) / 1.4, rel=1e-12
    )
    si = ex.to_si({"slip_time": [2.0], "stick_time": [100.0], "slip_distance": [2.0]}, slider)
    assert si["force_drop"][0] == pytest.approx(2.0 * s.force, rel=1e-12)
    assert si["stick_time"][0] == pytest.approx(100.0 / s.omega0, rel=1e-12)


@pytest.mark.slow  # the whole example: two fits through the measurement, the comparison
def test_the_slider_fit_example_end_to_end(tmp_path):
    """The verdict file agrees with the fit results it reports: the chosen model is the
    comparison's, the verdict says "does not reproduce" exactly when a p-value is below
    0.01, and the SI rows are the chosen fit's estimates through the rig's scales."""
    run = subprocess.run([sys.executable, str(EXAMPLE), "--out", str(tmp_path)],
                         capture_output=True, text=True)  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    record = json.loads((tmp_path / "slider_fit.json").read_text())
    text = (tmp_path / "slider_fit.md").read_text()
    assert (tmp_path / "slider_fit.png").stat().st_size > 0
    chosen = record["chosen"]
    assert chosen in record["candidates"] and record["table"][0]["name"] == chosen
    assert f"Chosen model: {chosen}" in text
    rejected = any(p < 0.01 for p in record["p_values"].values())
    assert record["rejected"] is rejected
    assert ("does not reproduce the measurement" in text) is rejected
    assert ("It reproduces the measurement" in text) is (not rejected)
    estimate = record["candidates"][chosen]["estimate"]
    ci = record["candidates"][chosen]["ci"]
    omega = math.sqrt(168.0 / 0.0307)
    row = record["si"]["natural frequency omega_eff"]
    assert row["estimate"] == pytest.approx(estimate["omega0"] * omega, rel=1e-9)
    warned = record["candidates"][chosen]["warnings"]
    if any("no interval" in w for w in warned):  # the fit said why it gave none
        assert all(math.isnan(c) for c in row["ci"])
        assert "none (see the warnings)" in text
    else:
        assert row["ci"] == pytest.approx([c * omega for c in ci["omega0"]], rel=1e-9)
    mass = record["si"]["effective mass k / omega_eff^2"]
    assert mass["estimate"] == pytest.approx(168.0 / (estimate["omega0"] * omega) ** 2)
    for name, p in record["p_values"].items():
        assert f"p = {p:.3g}" in text, name


@pytest.mark.slow  # 28 points through the measurement, ~0.2 s each
def test_the_measured_sliders_likelihood_is_smooth_between_neighbouring_points():
    """On the measured slider's cycles, the fixed-threshold model's log-likelihood at
    points 0.5 % apart in omega0 and in D (the fit's own settings: 1000 model cycles
    through the data's measurement; seeds 1 and 2) moves by less than 4 units a step about
    its own slope over the seven points (the secant's: the curvature a fit regresses on is
    the signal, the jitter about it the noise): the surface a fit regresses on. Before the
    force noise was keyed by cycle and the kernel estimate floored
    (`likelihood.FLOOR_POINTS`), steps of 0.5 % jumped by up to 15 units (three data slips
    shorter than a sampling interval, scored against the rare model cycles that came and
    went). Measured at seeds 1-4: 0.4-2.5 units about the slope with one path of 1000
    cycles a point, 0.6-3.2 with two of 500 (the steps themselves, slope included, reached
    3.5 and 4.0)."""
    from stickslip._inference.data import to_fit_scale
    from stickslip._inference.likelihood import _per_cycle, bandwidth_of
    from stickslip._inference.measurement import Measurement

    ex = _example()
    t, force = ex.load("k168Nm_v42.mat")
    cycles, _ = ex.extract(t, force)
    slider = ex.reference_slider(cycles)
    measurement = Measurement.from_cycles(
        ss.Cycles({k: cycles[k] for k in ex.COLUMNS}, cycles.info), slider
    )
    s = slider.scales
    data = {"slip_time": cycles["slip_time"] / s.time, "stick_time": cycles["stick_time"] / s.time,
            "slip_distance": cycles["force_drop"] / s.force}  # fmt: skip
    bandwidth = {k: bandwidth_of(to_fit_scale(k, v), 1000) for k, v in data.items()}  # as fit
    model, _, fixed = ex.candidates(slider)["fixed threshold"]
    Model = ss.get_model(model)
    base = dict(omega0=1.2, D=0.25, x0=1.05)
    for name, seed in itertools.product(("omega0", "D"), (1, 2)):
        values = []
        for f in np.exp(0.005 * np.arange(7)):
            point = Model(**fixed, **(base | {name: base[name] * f}))
            terms = _per_cycle(point, data, bandwidth, 1000, None, None, seed, measurement)
            values.append(sum(float(np.sum(v)) for v in terms.values()))
        steps = np.diff(values)
        assert np.max(np.abs(steps - steps.mean())) < 4.0, (name, seed, np.round(values, 2))
