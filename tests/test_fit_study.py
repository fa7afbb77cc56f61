"""A study's `fit` block with the measurement (issue 40, item 7): a cycles CSV written by
`stickslip cycles` is read with its settings and fitted through its measurement, any other
table as per-cycle values; `fit.json` and `summary.md` carry the p-values, the Monte Carlo
noise check, the optimiser and a plain verdict (the written files: tests/test_fit.py)."""

from __future__ import annotations

import types

import numpy as np
import pytest
import yaml

from stickslip._inference import fit as fit_module
from stickslip._inference.measurement import Measurement
from stickslip.extract import Cycles
from stickslip.study import fitting, run_fit
from stickslip.study.load import StudyError

BASE = dict(omega0=1.0, zeta=0.1, v_b=1.0, x0=1.0)
GOOD = np.random.default_rng(42).exponential(1.0, 200)
INFO = dict(input="x", sampling_interval=0.1, noise_sd=0.014, min_stick=2,
            tol_rule="5 robust sd of |v - v_b| near v_b", tol=0.07, v_b=1.0)  # fmt: skip


def cycles_csv(path):
    table = dict(release_time=np.cumsum(2 * GOOD + 1.0), slip_time=GOOD + 0.5,
                 slip_distance=GOOD + 0.1, stick_time=GOOD + 0.5,
                 period=2 * GOOD + 1.0)  # fmt: skip
    Cycles(table, INFO).to_csv(path)
    return path


def study(tmp_path, data="cycles.csv", **fit):
    spec = {
        "title": "fit study test",
        "model": {"name": "langevin", "params": {**BASE, "D": 0.4, "tau": 0.1}},
        "fit": {"data": str(data), "free": {"D": [0.05, 2.0]}, **fit},
    }
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


class Stop(Exception):
    pass


@pytest.fixture
def spy(monkeypatch):
    """`fit` as the study calls it: its data and keyword arguments recorded, then stopped."""
    seen = {}

    def stop(model, data, free, fixed=None, **kwargs):
        seen.update(data=data, kwargs=kwargs)
        raise Stop

    monkeypatch.setattr(fit_module, "fit", stop)
    return seen


def test_a_cycles_csv_is_read_with_its_settings(tmp_path):
    path = cycles_csv(tmp_path / "cycles.csv")
    got = fitting.read_fit_data(path)
    assert isinstance(got, Cycles) and got.info == INFO
    assert set(got.table) == {"slip_time", "slip_distance", "stick_time", "period"}
    np.testing.assert_allclose(got.table["slip_time"], GOOD + 0.5, rtol=1e-11)
    m = Measurement.from_cycles(got)  # the measurement can be modelled from what was read
    assert m.sampling_interval == 0.1 and m.min_stick == 2
    only = fitting.read_fit_data(path, ["stick_time"])
    assert list(only.table) == ["stick_time"] and only.info == INFO


def test_a_plain_table_is_per_cycle_values(tmp_path):
    path = tmp_path / "plain.csv"
    path.write_text("slip_time\n" + "".join(f"{float(v)!r}\n" for v in GOOD))
    got = fitting.read_fit_data(path)
    assert isinstance(got, dict) and list(got) == ["slip_time"]


def test_a_broken_cycles_csv_is_one_line_at_fit_data_without_its_content(tmp_path):
    path = cycles_csv(tmp_path / "cycles.csv")
    lines = path.read_text().splitlines()
    lines[-1] = "hunter2," + lines[-1].split(",", 1)[1]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(StudyError) as err:
        fitting.read_fit_data(path, source="s.yaml")
    text = str(err.value)
    assert "fit.data" in text and "not a number" in text and "hunter2" not in text
    with pytest.raises(StudyError, match="has no column peak_force"):
        fitting.read_fit_data(cycles_csv(tmp_path / "c2.csv"), ["peak_force"])


def test_the_study_fits_a_cycles_csv_through_its_measurement(tmp_path, spy):
    cycles_csv(tmp_path / "cycles.csv")
    with pytest.raises(Stop):
        run_fit(study(tmp_path, columns=["slip_time", "stick_time"]))
    assert isinstance(spy["data"], Cycles) and list(spy["data"].table) == [
        "slip_time", "stick_time",
    ]  # fmt: skip
    assert spy["kwargs"]["n_sim"] is None  # fit's default for a measurement
    assert "trace" not in spy["kwargs"] and "sampling" not in spy["kwargs"]


def test_the_deprecated_trace_setting_is_warned_about(tmp_path, spy):
    cycles_csv(tmp_path / "cycles.csv")
    with pytest.warns(DeprecationWarning, match="trace and sampling are deprecated"):
        with pytest.raises(Stop):
            run_fit(study(tmp_path, trace=True, sampling=0.1))
    assert isinstance(spy["data"], Cycles)


@pytest.mark.parametrize(
    "p_values, says",
    [
        (None, "not checked"),
        ({"slip_time": 0.004, "period": 0.5}, "The data reject the model: slip_time (p = 0.004)"),
        (
            {"slip_time": 0.2, "period": 0.5},
            "do not reject the model: every p-value is at least 0.2",
        ),
    ],
)
def test_the_verdict_is_one_plain_sentence(p_values, says):
    sentence = fitting._verdict(types.SimpleNamespace(p_values=p_values))
    assert says in sentence and "\n" not in sentence


# -- several candidate models in one study (issue 40, item 7) -------------------------------
FORCE_INFO = dict(
    input="force", sampling_interval=5e-4, noise_sd=1.9e-4, window=29,
    thresholds=dict(spike=5.0, slip=5.0, extent=2.0, drop=5.0, split=25.0),
    n_spikes=8239, n_samples=751281, spike_threshold=1.3e-3, lines_removed=[50.01],
)  # fmt: skip
CANDIDATES = [
    {"name": "white", "params": {"tau": 0.03}, "free": {"D": [0.05, 2.0]}},
    {"name": "ou", "free": {"D": [0.05, 2.0], "tau": [0.01, 3.0]}},
    {
        "name": "random.sd",
        "model": {"name": "random-threshold", "params": {
            "omega0": 1.0, "zeta": 0.1, "v_b": 1.0, "D": 0.4, "tau": 0.1, "threshold": "normal",
            "threshold_params": {"mean": 1.0, "sd": 0.1}}},
        "free": {"threshold_params.sd": [0.0, 1.0]},
    },
]  # fmt: skip


def _fake_fit(seen: list):
    """A stand-in for `fit`: records how it was called and returns a `FitResult` whose
    estimate is each box's geometric (or arithmetic, from 0) centre, never the truth."""
    from stickslip._inference.result import FitResult

    def fake(model, data, free, fixed=None, **kwargs):
        seen.append(dict(model=model, data=data, free=free, fixed=fixed, kwargs=kwargs))
        est = {k: (lo * hi) ** 0.5 if lo > 0 else (lo + hi) / 2 for k, (lo, hi) in free.items()}
        diagnostics = dict(
            n_sim=1000, dt=0.2, t_max=60.0, seed=kwargs["seed"], n_data={"slip_time": 200},
            measurement=None, covariance=[[0.01] * len(free)] * len(free), evaluations=7,
            optimizer={"evaluations": 7}, mc_noise={"seed": 5}, seconds=0.5,
            warnings=[f"{model} warns about {', '.join(free)}"],
        )  # fmt: skip
        return FitResult(
            estimate=est, ci={k: (0.5 * v, 2.0 * v + 0.1) for k, v in est.items()},
            log_likelihood=-100.0 - len(seen), method=f"fake fit of {model}",
            diagnostics=diagnostics,
            data={k: v for k, v in data.table.items() if k != "release_time"},
            model=model,
        )  # fmt: skip

    return fake


@pytest.fixture
def fake_fits(monkeypatch):
    """`fit` replaced by `_fake_fit`, `compare_fits` by a recorder that chooses the second
    candidate with a table naming both; `FitResult.plot` writes a stub figure."""
    from stickslip._inference import compare as compare_module
    from stickslip._inference.result import FitResult

    seen, compared = [], {}
    monkeypatch.setattr(fit_module, "fit", _fake_fit(seen))
    monkeypatch.setattr(FitResult, "plot", lambda self, path, **kw: path.write_bytes(b"png"))
    # each candidate's simulated cycles: the data shifted by its log-likelihood's offset
    monkeypatch.setattr(FitResult, "simulated", lambda self, n_sim=None, seed=None: {
        k: v + 0.01 * (-100.0 - self.log_likelihood) for k, v in self.data.items()})  # fmt: skip

    def compare(fits, *, alpha, n_boot, seed):
        compared.update(fits=fits, alpha=alpha, n_boot=n_boot, seed=seed)
        names = list(fits)
        table = [
            dict(rank=i + 1, name=k, model=str(fits[k].model), free=list(fits[k].estimate),
                 n_free=len(fits[k].estimate), log_likelihood=fits[k].log_likelihood,
                 statistic=None if i == 0 else 12.5, p_value=None if i == 0 else 0.004,
                 verdict="chosen: stub" if i == 0 else "rejected against stub")
            for i, k in enumerate([names[1], names[0], *names[2:]])
        ]  # fmt: skip
        return compare_module.Comparison(
            chosen=fits[names[1]], table=table, tests=[], alpha=alpha, n_boot=n_boot or 199,
            method="stub comparison", warnings=["the choice hangs on the simulation"],
            fits=fits,
        )  # fmt: skip

    monkeypatch.setattr(compare_module, "compare_fits", compare)
    return seen, compared


def test_each_candidate_is_fitted_to_the_same_data_and_compared(tmp_path, fake_fits):
    """Every candidate's model, free boxes and held parameters reach `fit` (the study's
    model with a candidate's `params` changes, or a candidate's own model block), with the
    fit block's shared settings; `compare_fits` gets every fit by name, the level, the
    replicates and a seed other than the fits'."""
    from stickslip._inference.compare import Comparison

    seen, compared = fake_fits
    cycles_csv(tmp_path / "cycles.csv")
    path = study(tmp_path, columns=["slip_time", "stick_time"], n_sim=3000, seed=5,
                 alpha=0.05, n_boot=39)  # fmt: skip
    spec = yaml.safe_load(path.read_text())
    del spec["fit"]["free"]
    spec["fit"]["candidates"] = CANDIDATES
    path.write_text(yaml.safe_dump(spec))
    got = run_fit(path)
    assert isinstance(got, Comparison)
    assert [s["model"] for s in seen] == ["langevin", "langevin", "random-threshold"]
    assert [s["free"] for s in seen] == [
        {"D": (0.05, 2.0)}, {"D": (0.05, 2.0), "tau": (0.01, 3.0)},
        {"threshold_params.sd": (0.0, 1.0)},
    ]  # fmt: skip
    assert seen[0]["fixed"] == {**BASE, "tau": 0.03}  # the study's model, tau changed
    assert seen[1]["fixed"] == BASE  # D and tau free
    assert seen[2]["fixed"]["threshold"] == "normal" and "x0" not in seen[2]["fixed"]
    for s in seen:
        assert isinstance(s["data"], Cycles) and list(s["data"].table) == ["slip_time",
                                                                        "stick_time"]  # fmt: skip
        assert s["kwargs"]["seed"] == 5 and s["kwargs"]["n_sim"] == 3000
        assert s["kwargs"]["scales"] is None
    assert list(compared["fits"]) == ["white", "ou", "random.sd"]
    assert (compared["alpha"], compared["n_boot"]) == (0.05, 39)
    assert compared["seed"] != 5


def test_the_choice_is_written_with_every_candidate(tmp_path, fake_fits):
    """fit.json: the chosen one's record on top (as a single fit writes it), `chosen`,
    every candidate and the comparison; a figure per candidate; summary.md states the
    chosen model, its estimates and intervals, the table and every warning."""
    import json

    cycles_csv(tmp_path / "cycles.csv")
    path = study(tmp_path)
    spec = yaml.safe_load(path.read_text())
    del spec["fit"]["free"]
    spec["fit"]["candidates"] = CANDIDATES[:2]
    path.write_text(yaml.safe_dump(spec))
    out = tmp_path / "out"
    run_fit(path, out)
    record = json.loads((out / "fit.json").read_text())
    assert record["chosen"] == "ou" and list(record["candidates"]) == ["white", "ou"]
    assert record["estimate"] == record["candidates"]["ou"]["estimate"]
    assert record["candidates"]["white"]["fixed"]["tau"] == 0.03
    assert record["comparison"]["method"] == "stub comparison"
    assert [r["name"] for r in record["comparison"]["table"]] == ["ou", "white"]
    written = {p.name for p in out.iterdir()}
    assert written >= {"fit.json", "fit.png", "fit_white.png", "fit_ou.png", "candidates.png",
                       "summary.md"}  # fmt: skip
    assert (out / "candidates.png").read_bytes().startswith(b"\x89PNG")
    text = (out / "summary.md").read_text()
    tau = record["estimate"]["tau"]
    lo, hi = record["ci95"]["tau"]
    assert "**Chosen model: ou** (langevin, D, tau free)" in text
    assert f"| tau | {tau:.4g} | [{lo:.4g}, {hi:.4g}] |" in text
    assert "| 2 | white | langevin | D | " in text and "rejected against stub" in text
    assert "- model choice: the choice hangs on the simulation" in text
    assert "- white: langevin warns about D" in text and "- ou: langevin warns about D, tau" in text
    assert "Units: the model's" in text


def test_a_force_trace_takes_scales_and_other_data_refuse_them(tmp_path, spy):
    """`scales` reaches `fit` as what `Measurement.from_cycles` reads (time and force);
    with the cycles of a position trace it is refused at fit.scales, before any fit."""
    table = dict(release_time=np.cumsum(2 * GOOD + 1.0), slip_time=GOOD + 0.5,
                 slip_distance=GOOD + 0.1, stick_time=GOOD + 0.5, period=2 * GOOD + 1.0,
                 peak_force=GOOD + 1.0,
                 force_drop=GOOD + 0.1)  # fmt: skip
    Cycles(table, FORCE_INFO).to_csv(tmp_path / "force.csv")
    with pytest.raises(Stop):
        run_fit(study(tmp_path, data="force.csv", scales={"time": 0.0135, "force": 0.0053}))
    scales = spy["kwargs"]["scales"]
    m = Measurement.from_cycles(spy["data"], scales=scales)
    assert m.signal == "force"
    assert m.sampling_interval == pytest.approx(5e-4 / 0.0135)
    assert m.noise_sd == pytest.approx(1.9e-4 / 0.0053)
    cycles_csv(tmp_path / "cycles.csv")
    spy.clear()
    with pytest.raises(StudyError, match=r"fit\.scales: applies to the cycles of a force trace"):
        run_fit(study(tmp_path, scales={"time": 1.0, "force": 1.0}))
    assert spy == {}


def test_parameters_in_si_match_the_slider_formulas():
    """The summary's SI column against `Slider`'s own definitions: a slider's D, tau and
    threshold spread in model units, taken back through `scales`, are its S (N^2 s),
    tau_c (s) and sd (N)."""
    from stickslip.units import Slider

    slider = Slider(mass=0.0307, stiffness=168.0, v_b=42e-6, static_friction=None,
                    kinetic_friction=0.0911, damping=1e-3, noise=2e-9, noise_time=3e-3,
                    threshold=("normal", {"mean": 0.0964, "sd": 0.0008}))  # fmt: skip
    s = types.SimpleNamespace(time=slider.scales.time, force=slider.scales.force)
    d = slider.dimensionless()
    assert fitting._in_data_units("D", d["D"], s)[0] == pytest.approx(2e-9, rel=1e-12)
    assert fitting._in_data_units("tau", d["tau"], s)[0] == pytest.approx(3e-3, rel=1e-12)
    sd = fitting._in_data_units("threshold_params.sd", d["threshold_params"]["sd"], s)
    assert sd == (pytest.approx(0.0008, rel=1e-12), "N")
    offset = slider.kinetic_friction + slider.damping * slider.v_b
    mean = fitting._in_data_units("threshold_params.mean", d["threshold_params"]["mean"], s)[0]
    assert mean + offset == pytest.approx(0.0964, rel=1e-12)
    assert fitting._in_data_units("zeta", d["zeta"], s) is None
    assert fitting._in_data_units("D", d["D"], None) is None


@pytest.mark.slow  # ~30 s on 2 busy cores: two fits with their goodness of fit, a comparison
def test_the_candidates_example_runs(tmp_path):
    """examples/fit_candidates.yaml end to end through the command line: OU noise (its
    data's truth, tau = 0.3) is chosen over the white limit (tau held at 0.03), and the
    committed data are what its documented command writes."""
    import json
    import pathlib
    import subprocess
    import sys

    root = pathlib.Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "examples" / "data"))
    try:
        import fit_candidates as generator
    finally:
        sys.path.pop(0)
    committed = (root / "examples" / "data" / "fit_candidates.csv").read_text()
    assert generator.csv_text(generator.cycles()) == committed
    out = tmp_path / "out"
    run = subprocess.run(
        [sys.executable, "-m", "stickslip.cli", "fit",
         str(root / "examples" / "fit_candidates.yaml"), "--out", str(out), "-q"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    record = json.loads((out / "fit.json").read_text())
    assert record["chosen"] == "ou", record["comparison"]["table"]
    assert "**Chosen model: ou**" in (out / "summary.md").read_text()


def test_an_error_of_a_candidates_fit_names_its_field(tmp_path):
    """`fit`'s argument names become the candidate's fields: its free box, its changed
    parameters, its own model block's parameters."""
    from stickslip import ParameterError

    data = tmp_path / "cycles.csv"
    box = ParameterError("fit", "free['tau']", "must be > 0 at both ends", (0.0, 1.0))
    assert fitting._fit_field(box, data, "fit.candidates.1") == (
        "fit.candidates.1.free.tau", "must be > 0 at both ends (got (0.0, 1.0))",
    )  # fmt: skip
    held = ParameterError("fit", "fixed['x0']", "must be > 0", -1.0)
    assert fitting._fit_field(held, data, "fit.candidates.0")[0] == "fit.candidates.0.params.x0"
    assert fitting._fit_field(held, data, "fit.candidates.2.model")[0] == (
        "fit.candidates.2.model.params.x0"
    )
    assert fitting._fit_field(held, data)[0] == "model.params.x0"  # a single fit
    assert fitting._fit_field(box, data)[0] == "fit.free.tau"


def test_validate_names_the_candidates(tmp_path):
    from click.testing import CliRunner

    from stickslip.cli import main

    cycles_csv(tmp_path / "cycles.csv")
    path = study(tmp_path)
    spec = yaml.safe_load(path.read_text())
    del spec["fit"]["free"]
    spec["fit"]["candidates"] = CANDIDATES[:2]
    path.write_text(yaml.safe_dump(spec))
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 0, result.output
    assert "fit: 2 candidates (white, ou)" in result.output


def test_measurement_is_public():
    import stickslip as ss

    assert ss.Measurement is Measurement and "Measurement" in ss.__all__
    assert "Measurement" in dir(ss)
