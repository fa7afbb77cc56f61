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
