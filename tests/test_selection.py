"""Method auto-selection: the cheapest method that meets a tolerance, from measured data and
the stability rules (stickslip.selection), in the library and in studies."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

import stickslip as ss
from stickslip.selection import (
    SelectionError,
    first_passage_density,
    load_table,
    select_method,
)

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
FIELDS = [
    "set", "output", "method", "family", "solver", "dt", "n_paths", "l1", "l1_sd", "repeats",
    "ref_floor", "noise_constant", "run_seconds", "compile_seconds", "path_steps", "pareto",
    "note", "params",
]  # fmt: skip


def langevin(**kw):
    return ss.get_model("langevin")(**{**PUBLIC, **kw})


def write_table(path, rows):
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in FIELDS})
    return str(path)


def analytic_row(method, l1, seconds, output="slip_time"):
    return dict(set="s", output=output, method=method, family="analytic", l1=l1,
                run_seconds=seconds, noise_constant=7.0, params=json.dumps(PUBLIC))  # fmt: skip


def mc_row(n, l1, seconds, dt=0.02, solver="exact", output="slip_time"):
    return dict(set="s", output=output, method=f"mc_{solver}", family="mc", solver=solver, dt=dt,
                n_paths=n, l1=l1, run_seconds=seconds, noise_constant=7.0,
                path_steps=n * 200, params=json.dumps(PUBLIC))  # fmt: skip


@pytest.fixture
def table(tmp_path):
    rows = [
        analytic_row("Fg1", 0.28, 0.003),
        analytic_row("Fg2", 0.15, 3.0),
        mc_row(1_000, 0.20, 0.05),
        mc_row(10_000, 0.063, 0.15),
        mc_row(100_000, 0.02, 1.0),
    ]
    return write_table(tmp_path / "t.csv", rows)


# -- the choice on a measured set ---------------------------------------------------------------
@pytest.mark.parametrize(
    "tol, key, n", [(0.3, "Fg1", None), (0.2, "mc_exact", 1_000), (0.1, "mc_exact", 10_000)]
)
def test_cheapest_measured_method_meeting_the_tolerance(table, tol, key, n):
    choice = select_method(langevin(), tol, table=table)
    assert choice.chosen.key == key and choice.distance == 0 and choice.reference_set == "s"
    assert choice.chosen.error <= tol
    if n is not None:
        assert choice.settings == dict(solver="exact", dt=0.02, n_paths=n)
    assert key in choice.reason or "Monte Carlo" in choice.reason


def test_reason_names_the_cheaper_methods_not_chosen(table):
    choice = select_method(langevin(), 0.1, table=table)
    assert "Fg1" in choice.reason and "0.28 > 0.1" in choice.reason


def test_extrapolates_monte_carlo_beyond_the_measured_paths(table):
    """0.0105 is below every measured row: the fit sqrt(A^2/N + B^2) (here nearly pure
    sampling noise, A = 6.3, B = 0.001) asks for A^2 / (0.9 * 0.0105)^2 = 4.5e5 paths: 5e5
    on the 1-2-5 ladder."""
    choice = select_method(langevin(), 0.0105, table=table)
    assert choice.kind == "simulation" and choice.settings["n_paths"] == 500_000
    assert "predicted" in choice.chosen.basis and choice.chosen.error <= 0.0105


def test_no_method_meets_a_tolerance_below_the_bias_floor(tmp_path):
    rows = [mc_row(n, 0.05, n * 1e-5) for n in (1_000, 10_000, 100_000)]
    table = write_table(tmp_path / "t.csv", rows)
    with pytest.raises(SelectionError, match="no method meets L1 <= 0.01"):
        select_method(langevin(), 0.01, table=table)


def test_analytic_error_is_not_transferred_far_from_a_measured_set(table):
    far = langevin(D=0.1)  # a factor 4 from the measured D
    choice = select_method(far, 0.3, table=table)
    assert choice.distance == pytest.approx(math.log(4))
    rejected = {c.key: c.rejected for c in choice.candidates if c.kind == "analytic"}
    assert "no measured error within" in rejected["Fg1"]
    assert choice.kind == "simulation"


def test_stability_rules_veto_an_unstable_approximation(tmp_path):
    """Fn2 measured (falsely, in this table) as accurate: its density goes negative on the
    public set, so the stability rules refuse it and the next method is chosen."""
    rows = [analytic_row("Fn2", 0.01, 0.001), mc_row(10_000, 0.05, 0.2)]
    table = write_table(tmp_path / "t.csv", rows)
    choice = select_method(langevin(), 0.1, table=table)
    assert choice.chosen.key == "mc_exact"
    vetoed = [c for c in choice.candidates if c.key == "Fn2"][0]
    assert vetoed.rejected.startswith("stability: ") and "negative" in vetoed.rejected
    assert "Fn2" in choice.reason


def test_white_noise_has_no_method():
    with pytest.raises(SelectionError, match="does not converge in dt"):
        select_method(langevin(tau=None), 0.1)


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(tolerance=0.0), "tolerance"),
        (dict(tolerance=0.1, output="slip_distance"), "output"),
    ],
)
def test_bad_arguments(kw, match):
    with pytest.raises(ss.ParameterError, match=match):
        select_method(langevin(), **kw)


# -- the packaged table (acceptance) -------------------------------------------------------------
def test_packaged_table_covers_three_sets_and_every_method():
    rows = load_table()
    assert {r["set"] for r in rows} >= {"public", "paper_fig6a", "near_critical"}
    public = [r for r in rows if r["set"] == "public" and r["output"] == "slip_time"]
    assert {r["method"] for r in public} >= {"Fn1", "Fg1", "Fn2", "Fg2", "mc_exact", "mc_euler"}
    assert any(r["solver"] == "euler" and r["dt"] == 0.002 and r["n_paths"] == 100_000
               for r in public)  # fmt: skip


@pytest.mark.parametrize("output", ["slip_time", "period"])
@pytest.mark.parametrize("tol", [0.3, 0.1, 0.05, 0.02])
def test_public_set_choice_meets_tolerance_within_twice_the_cheapest(tol, output):
    """Acceptance: the method chosen on the public set has a measured error within the
    tolerance and costs at most twice the cheapest measured method that meets it."""
    choice = select_method(langevin(), tol, output)
    rows = [r for r in load_table() if r["set"] == "public" and r["output"] == output]
    meeting = [r for r in rows if r["l1"] <= tol]
    assert meeting, f"the packaged table measures no method reaching {tol} on the public set"
    cheapest = min(r["run_seconds"] for r in meeting)
    assert choice.chosen.error <= tol and choice.chosen.basis == "measured"
    assert choice.chosen.seconds <= 2 * cheapest


# -- running the chosen method -----------------------------------------------------------------
def test_first_passage_density_runs_the_choice(table):
    t = np.arange(0.05, 15.0, 0.1)
    res = first_passage_density(langevin(), t, 0.1, table=table, seed=3)
    assert res.choice.settings["n_paths"] == 10_000
    assert res.standard_error is not None and res.density.shape == t.shape
    mass = float(np.sum(res.density) * 0.1)
    assert mass == pytest.approx(1.0, abs=0.02)
    res = first_passage_density(langevin(), t, 0.3, table=table)
    assert res.choice.chosen.key == "Fg1" and res.standard_error is None


def test_first_passage_density_rejects_uneven_times(table):
    with pytest.raises(ss.ParameterError, match="evenly spaced"):
        first_passage_density(langevin(), [0.1, 0.2, 0.5], 0.1, table=table)


@pytest.mark.slow
def test_predicted_monte_carlo_meets_the_tolerance_off_the_measured_sets():
    """Off every measured set, the predicted Monte Carlo choice is checked against a 20x
    larger run: the mean L1 of its runs over 4 seeds, less the larger run's own noise (in
    quadrature), meets the tolerance within 3 standard errors of that mean."""
    model = langevin(D=0.2, v_b=0.8)
    tol = 0.1
    choice = select_method(model, tol, seed=5)
    assert choice.kind == "simulation" and choice.distance > 0
    s = choice.settings
    n = s["n_paths"]
    ref = ss.simulate(model, 20 * n, 0.01, 100.0, seed=12, solver="exact")
    edges = np.linspace(0.0, np.nanquantile(ref.slip_time, 0.999), 151)

    def mass(e):
        counts, _ = np.histogram(e.slip_time[np.isfinite(e.slip_time)], bins=edges)
        return counts / e.n_paths

    p_ref = mass(ref)
    ref_noise = math.sqrt(2 / math.pi) * np.sum(np.sqrt(p_ref * (1 - p_ref) / ref.n_paths))
    errs = []
    for seed in (11, 21, 31, 41):
        ens = ss.simulate(model, n, s["dt"], 100.0, seed=seed, solver=s["solver"])
        errs.append(float(np.sum(np.abs(mass(ens) - p_ref))))
    mean, se = np.mean(errs), np.std(errs, ddof=1) / math.sqrt(len(errs))
    own = math.sqrt(max(mean**2 - ref_noise**2, 0.0))
    assert own <= tol + 3 * se, (errs, ref_noise)


# -- method: auto in a study ---------------------------------------------------------------------
def auto_study(**kw):
    study = dict(model=dict(name="langevin", params=PUBLIC), method="auto", tolerance=0.1)
    study.update(kw)
    return study


@pytest.mark.parametrize(
    "kw, field, reason",
    [
        (dict(tolerance=None), "tolerance", "is required with method: auto"),
        (dict(method="compare"), "tolerance", "applies only to method: auto"),
        (dict(analytic=[{"method": "decoupling"}]), "analytic", "chooses the method itself"),
        (dict(simulation={"n_paths": 10}), "simulation.n_paths", "is chosen by method: auto"),
        (dict(outputs=["slip_distance"]), "outputs.0", "slip_time and period only"),
        (dict(method="automatic"), "method", ""),
    ],
)
def test_auto_study_bad_input_names_the_field(kw, field, reason):
    with pytest.raises(ss.StudyError) as err:
        ss.load_study(auto_study(**kw))
    text = str(err.value)
    assert field in text and reason in text and "\n" not in text


def test_auto_study_runs_the_choice_and_says_why(tmp_path):
    ds = ss.run_study(auto_study(outputs=["slip_time"]), tmp_path / "out")
    choice = json.loads(ds.attrs["method_choice"])["slip_time"]
    assert choice["error"] <= 0.1
    summary = (tmp_path / "out" / "summary.md").read_text()
    assert "## Method (auto)" in summary and "cheapest" in summary
    if choice["settings"].get("n_paths"):
        assert f"{choice['settings']['n_paths']} paths" in summary
        assert "mc_slip_time" in ds
