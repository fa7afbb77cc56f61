"""One parameter set fitted to several runs: `fit(model, [run, ...])`.

- `Slider.model_parameters` puts a slider with another mass, damping or friction into a
  reference slider's units: the model it gives, simulated noise-free, makes the other
  slider's closed-form cycle (`Slider.deterministic`) in SI; it inverts `si_parameters`.
- Bad runs and names are one clear line each.
- Two runs of an independent generator (other springs, the same slider): the joint fit
  finds the slider's mass and noise within their intervals' reach, and `compare_fits`
  keeps its fixed threshold against a random one fitted to the same runs (slow).
- `compare_fits` refuses a loaded joint fit, and joint fits of other runs.
"""

import dataclasses
import warnings

import numpy as np
import pytest
from conftest import benchmark_module

import stickslip as ss
from stickslip import ParameterError
from stickslip.units import Slider

REF = dict(mass=0.03, stiffness=168.0, v_b=42e-6, static_friction=0.0964,
           kinetic_friction=0.0911, damping=4e-3)  # fmt: skip


@pytest.mark.parametrize(
    "si",
    [
        {"mass": 0.02},
        {"mass": 0.05, "damping": 9e-3},
        {"static_friction": 0.0990, "kinetic_friction": 0.0900},
    ],
)
def test_another_slider_in_a_reference_sliders_units(si):
    """The other slider's noise-free cycle, in closed form in its own units, against the
    reference-unit model simulated (the simulator's exact steps, no noise)."""
    ref = Slider(**REF)
    other = dataclasses.replace(ref, **si)
    p = ref.model_parameters(si)
    model = ss.get_model("langevin")(**p)
    ens = ss.simulate(model, 1, 0.001, 200.0, seed=0)
    s = ref.scales
    truth = other.deterministic()
    np.testing.assert_allclose(float(ens.slip_time[0]) * s.time, truth["slip_time"][0],
                               rtol=1e-6)  # fmt: skip
    np.testing.assert_allclose(float(ens.slip_distance[0]) * s.force, truth["force_drop"][0],
                               rtol=1e-6)  # fmt: skip


def test_model_parameters_invert_si_parameters():
    ref = Slider(**{**REF, "static_friction": None, "noise": 1e-8, "noise_time": 1e-3},
                 threshold=("normal", {"mean": 0.0964, "sd": 0.002}))  # fmt: skip
    np.testing.assert_allclose(ref.model_parameters()["D"], ref.dimensionless()["D"], rtol=1e-12)
    si = {"mass": 0.021, "noise": 2.5e-8, "threshold.mean": 0.0975, "threshold.sd": 0.0031}
    p = ref.model_parameters(si)
    back = ref.si_parameters({k: p[k] for k in ("omega0", "D", "threshold_params")})
    assert back["mass"] == pytest.approx(0.021, rel=1e-12)
    assert back["noise"] == pytest.approx(2.5e-8, rel=1e-12)
    assert back["threshold"][1]["mean"] == pytest.approx(0.0975, rel=1e-12)
    assert back["threshold"][1]["sd"] == pytest.approx(0.0031, rel=1e-12)
    with pytest.raises(ParameterError, match="'stiffness'.*not a slider parameter"):
        ref.model_parameters({"stiffness": 200.0})


@pytest.fixture(scope="module")
def run():
    from _force_traces import Rig, make_trace

    rig = Rig()
    t, force, _ = make_trace(5, duration=40.0, rig=rig)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ss.analyse_run(t, force, stiffness=rig.stiffness, v_b=rig.v_b, mass=rig.mass)


@pytest.mark.parametrize(
    "change, match",
    [
        (dict(free={"stiffness": (100, 200)}), r"free\['stiffness'\].*not a slider parameter"),
        (dict(free={"mass": (0.05, 0.01)}), r"free\['mass'\].*low < high"),
        (dict(fixed={"x0": 1.0}), r"fixed\['x0'\].*not a slider parameter"),
        (dict(scales=Slider(**REF)), r"'scales'.*each run's reference Slider"),
        (dict(model="friction-block"), r"does not take a slider's parameters"),
    ],
)
def test_bad_joint_fits_are_one_line(run, change, match):
    args = dict(model="langevin", free={"mass": (0.01, 0.05)}, fixed=None, scales=None)
    args.update(change)
    with pytest.raises(ParameterError, match=match):
        ss.fit(args["model"], [run, run], args["free"], args["fixed"], scales=args["scales"])


def test_a_run_without_its_mass_or_its_cycles_is_named(run):
    no_mass = dataclasses.replace(run, settings={**run.settings, "mass": None})
    with pytest.raises(ParameterError, match=r"data\[1\].*without its mass"):
        ss.fit("langevin", [run, no_mass], {"mass": (0.01, 0.05)})
    sliding = dataclasses.replace(run, regime="steady sliding", cycles=None)
    with pytest.raises(ParameterError, match=r"data\[0\].*steady sliding, not stick-slip"):
        ss.fit("langevin", [sliding, run], {"mass": (0.01, 0.05)})


def _generator():
    return benchmark_module("independent_slider")


def _two_springs(duration, columns):
    """The generator's traces of one slider (a fixed threshold) on springs of 168 and 400
    N/m, `duration` s each: the runs `(Cycles of columns, Slider)` a joint fit takes, each
    trace's whole cycles, and the second rig."""
    gen = _generator()
    runs, full = [], []
    for i, k in enumerate((168.0, 400.0)):
        rig = dataclasses.replace(gen.Rig(gap_sd=0.0, hum=1.5e-4), stiffness=k)
        t, force, _ = gen.make_trace(500 + i, duration, rig)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cycles = ss.extract_cycles(t, force=force, stiffness=k, v_b=rig.v_b)
        full.append(cycles)
        runs.append((ss.Cycles({c: cycles[c] for c in columns}, cycles.info),
                     Slider.from_cycles(cycles, mass=0.03)))  # fmt: skip
    return runs, full, rig


@pytest.mark.slow
def test_a_joint_fit_finds_the_slider_behind_two_springs(tmp_path):
    """Two traces of one slider (mass 17.8 g, noise 2.44e-8 N^2 s, a fixed threshold) on
    springs of 168 and 400 N/m, from a generator that shares no code with the library;
    the boxes are not centred on the truth, the reference mass (30 g) is not it either.
    Each estimate within 3.3 standard errors of the truth (a 1e-3 chance each)."""
    runs, full, rig = _two_springs(200.0, ("slip_time", "stick_time", "slip_distance"))
    truth = {"mass": rig.mass, "noise": rig.noise_intensity,
             "static_friction": rig.kinetic_friction + rig.gap_mean}  # fmt: skip
    fixed = {"kinetic_friction": rig.kinetic_friction, "damping": rig.damping,
             "noise_time": rig.noise_time}  # fmt: skip
    free = {"mass": (0.005, 0.05), "noise": (3e-9, 3e-7), "static_friction": (0.093, 0.099)}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = ss.fit("langevin", runs, free, fixed, n_sim=1000, seed=7)
    for k, v in truth.items():
        lo, hi = r.ci[k]
        log = k != "static_friction"
        f = np.log if log else (lambda x: x)
        se = (f(hi) - f(lo)) / (2 * 1.96)
        assert abs(f(r.estimate[k]) - f(v)) < 3.3 * se, (k, r.estimate[k], v, (lo, hi))
    assert [row["stiffness"] for row in r.diagnostics["runs"]] == [168.0, 400.0]
    assert set(r.diagnostics["runs"][0]["p_values"]) == set(runs[0][0].table)
    # kept and carried: the saved fit loads with its runs; it predicts the second run
    r.save(tmp_path / "joint.json")
    back = ss.load_fit(tmp_path / "joint.json")
    assert back.estimate == r.estimate
    assert [row["name"] for row in back.diagnostics["runs"]] == ["run 0", "run 1"]
    p = r.predict(full[1])
    assert p.regime == "stick-slip" and set(p.p_values) == {"stick_time", "slip_time", "force_drop"}
    # the fixed threshold is true: compare_fits keeps it against a random one fitted to
    # the same runs (a calibrated test rejects a true law in 1 % of data sets)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        random = ss.fit("random-threshold-held", runs,
                        {"mass": free["mass"], "noise": free["noise"],
                         "threshold.mean": free["static_friction"], "threshold.sd": (1e-4, 0.01)},
                        fixed, n_sim=1000, seed=7)  # fmt: skip
        c = ss.compare_fits({"fixed": r, "random": random}, seed=11)
    assert c.chosen is r, c.summary()


def test_a_joint_fit_keeps_its_design_cycles_for_compare_fits():
    """A joint fit keeps each run's cycles at its design points, and the comparison's
    scores from them are those of the same cycles simulated again (a function of the
    point, the run and the seed): the generator's traces of one slider on two springs."""
    from stickslip._inference.compare import _Candidate

    runs, _, rig = _two_springs(40.0, ("slip_time", "stick_time"))
    fixed = {"kinetic_friction": rig.kinetic_friction, "damping": rig.damping,
             "noise_time": rig.noise_time, "noise": rig.noise_intensity,
             "static_friction": rig.kinetic_friction + rig.gap_mean}  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = ss.fit("langevin", runs, {"mass": (0.005, 0.05)}, fixed, n_sim=1000, seed=7)
    kept = _Candidate.of("kept", r)
    design = kept.design()
    assert all(len(per_run) == 2 and all(isinstance(x, dict) for x in per_run)
               for per_seed in design[2] for per_run in per_seed)  # fmt: skip
    again = list(design)
    again[2] = [[[None, None] for _ in per_seed] for per_seed in design[2]]
    for which in (0, 1):
        a = kept.best(design, kept.columns, 1, which)
        b = kept.best(tuple(again), kept.columns, 1, which)
        assert np.isfinite(a).all() and np.array_equal(a, b), (a, b)


def _joint_result(names, log_likelihood=-10.0, joint=True):
    from stickslip._inference.result import FitResult

    return FitResult(
        estimate={"mass": 0.02}, ci={"mass": (0.01, 0.03)}, log_likelihood=log_likelihood,
        method="", data={"slip_time": np.arange(4.0)}, model=None,
        diagnostics={"runs": [{"name": n} for n in names], **({"joint": object()} if joint
                                                             else {})},
    )  # fmt: skip


def test_one_run_checks_refuse_a_joint_fit():
    """goodness_of_fit calibrates one run's statistics: a joint fit is refused by name."""
    with pytest.raises(ParameterError, match="several runs"):
        ss.goodness_of_fit(_joint_result(["a", "b"], joint=False))


def test_compare_fits_refuses_joint_fits_it_cannot_compare():
    """A loaded joint fit (its map to each run's model is not saved), and joint fits of
    other runs, or a joint fit against a fit of one data set, are one line each."""
    from stickslip import DataError

    with pytest.raises(ParameterError, match="loaded fit of several runs"):
        ss.compare_fits({"a": _joint_result(["a", "b"], joint=False),
                         "b": _joint_result(["a", "b"], -9.0, joint=False)})  # fmt: skip
    with pytest.raises(DataError, match="y was fitted to the runs a, c and x to the runs a, b"):
        ss.compare_fits({"x": _joint_result(["a", "b"]), "y": _joint_result(["a", "c"], -9.0)})
    with pytest.raises(DataError, match="one data set"):
        ss.compare_fits({"x": _joint_result(["a", "b"]), "y": _joint_result([], -9.0)})


def test_a_value_of_one_run_overrides_the_shared_one(run):
    """`NAME[i]`: run i's own value; the others keep the shared one."""
    from stickslip._inference.joint import Runs

    runs = Runs(ss.get_model("langevin"), [run, run, run])
    fixed, free = runs.checked(
        {"static_friction": 0.0990, "static_friction[1]": 0.0980, "kinetic_friction": 0.0911},
        {"mass": (0.01, 0.05)},
    )
    models = runs.build({"mass": 0.02})
    ref = runs.sliders[0]
    x0 = [m.params()["x0"] for m in models]
    offset = 0.0911 + ref.damping * ref.v_b
    assert x0[0] == pytest.approx((0.0990 - offset) / ref.scales.force, rel=1e-12)
    assert x0[1] == pytest.approx((0.0980 - offset) / ref.scales.force, rel=1e-12)
    assert x0[2] == x0[0]
    with pytest.raises(ParameterError, match=r"names run 3: there are 3 runs"):
        runs.checked({}, {"mass[3]": (0.01, 0.05)})


def test_a_run_the_fitted_slider_shows_no_cycles_on_is_rejected_not_a_crash(run, monkeypatch):
    """The per-run check after a joint fit: a run on which the fitted slider's simulated
    trace shows no cycles through its measurement gets p-values of 0 and the reason; the
    other runs are checked as usual."""
    from stickslip import DataError
    from stickslip._inference import forward
    from stickslip._inference.joint import Runs
    from stickslip._inference.result import FitResult

    runs = Runs(ss.get_model("langevin"), [run, run])
    runs.checked({"static_friction": 0.0990, "kinetic_friction": 0.0911}, {"mass": (0.01, 0.05)})
    result = FitResult(
        estimate={"mass": 0.02}, ci={"mass": (0.01, 0.03)}, log_likelihood=-1.0, method="",
        data=runs.data, model=None,
        diagnostics={"runs": runs.describe(runs.build({"mass": 0.02})), "warnings": []},
    )  # fmt: skip
    real = forward.simulate_values

    def second_shows_nothing(model, n, dt, t_max, seed, measurement=None):
        if measurement is runs.measurements[1]:
            raise DataError("measured_cycles: the simulated trace shows no cycles")
        return real(model, n, dt, t_max, seed, measurement)

    monkeypatch.setattr(forward, "simulate_values", second_shows_nothing)
    runs.p_values(result, 200, 3)
    first, second = result.diagnostics["runs"]
    assert set(first["p_values"]) == set(runs.columns[0]) and "unresolved" not in first
    assert all(0.0 <= p <= 1.0 for p in first["p_values"].values())
    assert set(second["p_values"].values()) == {0.0} and "no cycles" in second["unresolved"]
    assert "no cycles" in result.summary()


@pytest.mark.slow  # (~3.5 min: three fits of one run, two comparisons)
def test_fits_in_other_units_compare_on_the_data_in_si():
    """One trace of the independent generator (a fixed threshold), fitted by the same law
    in the units of two reference sliders (30 g and 15 g: times and lengths in other
    units), and by a random threshold in the second's: the two fits of one law find the
    same slider, and their log-likelihoods, a hundred units apart in their own units, agree
    in SI (`compare_fits`' units: each value a density scores adds -log of its unit) to
    within the simulation's own noise (the two seeds' difference of either fit); the
    comparison of the first against the random threshold, across units, gives the same
    statistic as the second's, within the same units, to that noise, and keeps the true
    fixed threshold."""
    from stickslip._inference.compare import _Candidate

    gen = _generator()
    rig = dataclasses.replace(gen.Rig(gap_sd=0.0, hum=1.5e-4), stiffness=168.0)
    t, force, _ = gen.make_trace(500, 200.0, rig)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cycles = ss.extract_cycles(t, force=force, stiffness=168.0, v_b=rig.v_b)
    data = ss.Cycles({c: cycles[c] for c in ("slip_time", "stick_time", "slip_distance")},
                     cycles.info)  # fmt: skip
    refs = {u: Slider.from_cycles(cycles, mass=m) for u, m in (("a", 0.03), ("b", 0.015))}
    fixed = {"kinetic_friction": rig.kinetic_friction, "damping": rig.damping,
             "noise_time": rig.noise_time}  # fmt: skip
    free = {"mass": (0.005, 0.05), "noise": (3e-9, 3e-7), "static_friction": (0.093, 0.099)}
    fits = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for u, ref in refs.items():
            fits[u] = ss.fit("langevin", [(data, ref)], free, fixed, n_sim=1000, seed=7)
        random = ss.fit("random-threshold-held", [(data, refs["b"])],
                        {"mass": free["mass"], "noise": free["noise"],
                         "threshold.mean": free["static_friction"], "threshold.sd": (1e-4, 0.01)},
                        fixed, n_sim=1000, seed=7)  # fmt: skip
    noise = max(abs(r.diagnostics.mc_noise["log_likelihood_difference"]) for r in fits.values())
    own = {u: r.log_likelihood for u, r in fits.items()}
    si = {u: _Candidate.of(u, r).in_si().log_likelihood for u, r in fits.items()}
    assert abs(own["a"] - own["b"]) > 20 * noise  # the units' own difference
    assert abs(si["a"] - si["b"]) < noise, (si, noise)
    for k in free:
        lo, hi = fits["b"].ci[k]
        assert abs(fits["a"].estimate[k] - fits["b"].estimate[k]) < 0.2 * (hi - lo), k
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        across = ss.compare_fits({"fixed a": fits["a"], "random b": random}, seed=11)
        within = ss.compare_fits({"fixed b": fits["b"], "random b": random}, seed=11)
    assert across.chosen is fits["a"] and within.chosen is fits["b"]
    assert across.table[0]["log_likelihood"] == pytest.approx(si["a"], abs=1e-9)
    for x, y in zip(across.tests[0]["statistic"], within.tests[0]["statistic"], strict=True):
        assert abs(x - y) < 2 * noise, (across.tests, within.tests)


def test_compare_fits_in_other_units_needs_the_same_data_in_si():
    """Fits in other units compare on the data in SI: one without physical units, or data
    that differ once in SI, are one line each."""
    from stickslip import DataError
    from stickslip._inference.result import FitResult

    a, b = Slider(**REF), Slider(**{**REF, "mass": REF["mass"] / 2})  # other time units

    def result(units, slip_times, ll):
        return FitResult(
            estimate={"omega0": 1.0}, ci={"omega0": (0.9, 1.1)}, log_likelihood=ll, method="",
            data={"slip_time": np.asarray(slip_times, float)}, model=None,
            diagnostics={"units": units},
        )  # fmt: skip

    x = np.linspace(1.0, 2.0, 20)  # in a's units
    with pytest.raises(DataError, match="one has no physical units"):
        ss.compare_fits({"a": result(a, x, -1.0), "none": result(None, x, -2.0)})
    with pytest.raises(DataError, match=r"different data \(slip_time in SI, first at row 0"):
        ss.compare_fits({"a": result(a, x, -1.0), "b": result(b, x, -2.0)})
