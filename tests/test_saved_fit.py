"""A fit saved and loaded (`FitResult.save`, `stickslip.load_fit`): the loaded fit is the
saved one where it counts, checked by what it does, not by its fields alone: it simulates
the same cycles for a seed (the model, the settings and the measurement rebuilt), its
summary and p-values read the same and it plots; bad files get one line naming them."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import stickslip as ss
from stickslip._inference.measurement import Measurement

BASE = dict(omega0=1.0, zeta=0.1, v_b=1.0, x0=1.0, tau=0.1)


@pytest.fixture(scope="module")
def result():
    model = ss.get_model("langevin")(**BASE, D=0.4)
    e = ss.simulate(model, 700, 0.2, 200.0, 5, progress=False)
    keep = np.asarray(e.stuck) & ~np.asarray(e.immediate)
    data = {"slip_time": np.asarray(e.slip_time)[keep][:500]}
    r = ss.fit("langevin", data, {"D": (0.1, 1.5)}, BASE, n_sim=1000, seed=3, check=False)
    with pytest.warns(UserWarning, match="n_rep"):  # (20 replicates: no verdict at 0.01)
        checked = ss.goodness_of_fit(r, n_rep=20, seed=4)
    return dataclasses.replace(r, goodness=checked)


def test_a_loaded_fit_is_the_saved_one(result, tmp_path):
    path = tmp_path / "fit.json"
    result.save(path)
    back = ss.load_fit(path)
    assert back.estimate == result.estimate and back.ci == result.ci
    assert back.log_likelihood == result.log_likelihood and back.method == result.method
    assert back.summary() == result.summary()
    assert back.p_values == result.p_values
    assert type(back.model) is type(result.model) and back.model.params() == result.model.params()
    for k in result.data:
        np.testing.assert_array_equal(back.data[k], result.data[k])
    a, b = result.simulated(seed=11), back.simulated(seed=11)
    np.testing.assert_array_equal(a["slip_time"], b["slip_time"])
    # the loaded fit plots and compares as the saved one
    back.plot(tmp_path / "fit.png")
    assert (tmp_path / "fit.png").stat().st_size > 0


def test_a_goodness_of_fits_statistic_comes_back(result, tmp_path):
    """Its statistic by class (one of stickslip's), or by name and symbol (a user's: its
    code is not saved, and calling it says so); a file saved before the statistic was a
    choice reads as the Anderson-Darling, then the only one."""

    class Mine(ss.Statistic):
        name, symbol = "my distance", "M"

        def __call__(self, u):
            return float(np.max(np.abs(np.sort(u) - np.linspace(0, 1, u.size))))

    for statistic in (ss.CramerVonMises(), Mine()):
        r = dataclasses.replace(
            result, goodness=dataclasses.replace(result.goodness, statistic=statistic)
        )
        path = tmp_path / "fit.json"
        r.save(path)
        back = ss.load_fit(path).goodness
        assert (type(back.statistic).__name__ == "CramerVonMises") == (
            statistic.name != "my distance"
        )
        assert back.statistic.symbol == statistic.symbol and back.statistic.name == statistic.name
        # one of stickslip's comes back equal to the one saved; a user's by name only
        assert (back.statistic == statistic) == (not isinstance(statistic, Mine))
        if isinstance(statistic, Mine):
            with pytest.raises(TypeError, match="only its name was kept"):
                back.statistic(np.array([0.5]))
    document = json.loads(path.read_text())
    del document["goodness"]["statistic"]
    path.write_text(json.dumps(document))
    assert isinstance(ss.load_fit(path).goodness.statistic, ss.AndersonDarling)


def _with(result, m):
    """`result` as if fitted through the measurement `m` (its settings, its columns)."""
    d = dict(result.diagnostics, measurement=m, observe=m, trace=True,
             sampling=m.sampling_interval)  # fmt: skip
    data = {k: result.data["slip_time"] for k in m.columns}
    return dataclasses.replace(result, diagnostics=d, data=data)


def test_a_measured_fits_measurement_comes_back(result, tmp_path):
    """The measurement is rebuilt: the loaded fit's cycles simulated through it are the
    saved one's for the same seed (a position trace), and a force trace's settings
    (thresholds, lines, spikes) come back equal."""
    m = Measurement(sampling_interval=0.05, signal="x", noise_sd=1e-3,
                    columns=("slip_time", "stick_time"))  # fmt: skip
    measured = _with(result, m)
    measured.save(tmp_path / "measured.json")
    back = ss.load_fit(tmp_path / "measured.json")
    assert back.diagnostics["measurement"] == m
    a, b = measured.simulated(n_sim=300, seed=2), back.simulated(n_sim=300, seed=2)
    for k in m.columns:
        np.testing.assert_array_equal(a[k], b[k])
    force = Measurement(sampling_interval=0.05, signal="force", noise_sd=0.01, window=11,
                        thresholds={"drop": 5.0, "extent": 2.0, "slip": 5.0, "spike": 5.0,
                                    "split": 25.0},
                        spike_fraction=0.01, spike_height=0.2, lines=(0.7,),
                        line_amplitude=0.01, columns=("slip_time", "stick_time"))  # fmt: skip
    _with(result, force).save(tmp_path / "force.json")
    assert ss.load_fit(tmp_path / "force.json").diagnostics["measurement"] == force


def test_save_replaces_a_file_whole(result, tmp_path):
    path = tmp_path / "fit.json"
    path.write_text("an older file")
    result.save(path)
    assert json.loads(path.read_text())["format"] == "stickslip fit"
    assert [p.name for p in tmp_path.iterdir()] == ["fit.json"]  # no partial file left


@pytest.mark.parametrize("text, said", [
    ("not json {", "cannot be read as a saved fit"),
    ('{"format": "something else"}', "is not a saved stickslip fit"),
    ('{"format": "stickslip fit", "version": 99, "stickslip": "9.0"}', "format version 99"),
    ('{"format": "stickslip fit", "version": 1}', "lacks model"),
])  # fmt: skip
def test_a_file_that_is_no_saved_fit_is_one_line(tmp_path, text, said):
    path = tmp_path / "fit.json"
    path.write_text(text)
    with pytest.raises(ss.DataError, match=said) as err:
        ss.load_fit(path)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


def test_a_fit_pickled_with_its_diagnostics_as_a_dict_reads_back(result):
    """A fit kept (pickled) by an earlier version held its diagnostics as a dict: it comes
    back typed, and summarises, simulates and checks as the fit it was."""
    import pickle

    from stickslip._inference.diagnostics import Design, FitDiagnostics

    state = dict(result.__dict__)
    old = {k: v for k, v in result.diagnostics.items() if k not in ("design",)}
    old["design"] = dict(result.diagnostics.design)
    state["diagnostics"] = old
    kept = object.__new__(type(result))
    kept.__setstate__(pickle.loads(pickle.dumps(state)))
    assert isinstance(kept.diagnostics, FitDiagnostics)
    assert isinstance(kept.diagnostics.design, Design)
    assert kept.summary() == result.summary()
    assert kept.diagnostics.design.seeds == result.diagnostics.design.seeds
    again = pickle.loads(pickle.dumps(result))
    assert again.diagnostics.box == result.diagnostics.box == {"D": (0.1, 1.5)}
    # (and as a mapping, the keys the dict had, the measurement's aliases among them)
    assert {"n_sim", "design", "observe", "trace", "sampling"} <= set(result.diagnostics)
    assert len(dict(result.diagnostics)) == len(result.diagnostics)
