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
# Bounds: a Monte Carlo row's mean L1 + 2 sd, the sd at least sqrt(1 - 2/pi)/sqrt(N) (0.019 at
# 1000 paths, 0.006 at 10^4): 1000 paths bound 0.238, 10^4 paths 0.075, 10^5 paths 0.024.
@pytest.mark.parametrize(
    "tol, key, n",
    [(0.3, "Fg1", None), (0.25, "mc_exact", 1_000), (0.2, "mc_exact", 10_000),
     (0.05, "mc_exact", 100_000)],
)  # fmt: skip
def test_cheapest_measured_method_meeting_the_tolerance(table, tol, key, n):
    choice = select_method(langevin(), tol, table=table)
    assert choice.chosen.key == key and choice.reference_set == "s" and choice.promised
    assert choice.chosen.error <= tol
    if n is not None:
        assert choice.settings == dict(solver="exact", dt=0.02, n_paths=n)
    assert key in choice.reason or "Monte Carlo" in choice.reason


def test_monte_carlo_rows_carry_a_margin_from_their_spread(tmp_path):
    """A row whose mean L1 meets the tolerance is not enough: mean + 2 sd must (the
    tolerance-0.02 choice that measured 0.01997 +- 0.0012 had even odds of missing)."""
    rows = [
        dict(mc_row(100_000, 0.01997, 0.2), l1_sd=0.0012),
        dict(mc_row(300_000, 0.0115, 0.6), l1_sd=0.0010),
    ]
    choice = select_method(langevin(), 0.02, table=write_table(tmp_path / "t.csv", rows))
    assert choice.settings["n_paths"] == 300_000
    assert choice.chosen.error == pytest.approx(0.0115 + 2 * 0.603 / math.sqrt(300_000), rel=1e-3)


def test_reason_names_the_cheaper_methods_not_chosen(table):
    choice = select_method(langevin(), 0.1, table=table)
    assert "Fg1" in choice.reason and "0.28 > 0.1" in choice.reason
    assert "selection:" in choice.reason


def test_extrapolates_monte_carlo_beyond_the_measured_paths(table):
    """0.0105 is below every measured row: the fit sqrt(A^2/N + B^2) (nearly pure sampling
    noise, A = 6.3, B = 0.001) with the 2-sd margin asks for ((6.3 + 1.2) / 0.0095)^2, about
    6.2e5 paths."""
    choice = select_method(langevin(), 0.0105, table=table)
    assert choice.kind == "simulation" and 5.5e5 <= choice.settings["n_paths"] <= 7e5
    assert "predicted" in choice.chosen.basis and choice.chosen.error <= 0.0105


def test_no_method_meets_a_tolerance_below_the_bias_floor(tmp_path):
    rows = [mc_row(n, 0.05, n * 1e-5) for n in (1_000, 10_000, 100_000)]
    table = write_table(tmp_path / "t.csv", rows)
    with pytest.raises(SelectionError, match="no method meets L1 <= 0.01"):
        select_method(langevin(), 0.01, table=table)


@pytest.mark.slow  # a pilot simulation of its own (~7 s CPU)
def test_nothing_measured_elsewhere_is_borrowed():
    """v_b = 1.24 is within 25 % of the public set's v_b = 1 but beyond the critical speed
    1.2335: no measured error is carried over (the old rule chose F_g^(1) with the public
    set's L1 0.28); the pilot of the model itself sizes an exact-stepping run."""
    choice = select_method(langevin(v_b=1.24), 0.3, seed=1)
    assert choice.reference_set is None and choice.kind == "simulation" and choice.promised
    assert choice.pilot["n_paths"] > 0 and "pilot" in choice.reason
    assert not [c for c in choice.candidates if c.kind == "analytic" and c.error <= 0.3]
    assert choice.settings["solver"] == "exact" and choice.chosen.error <= 0.3


def test_costs_are_scaled_to_the_running_machine(table, tmp_path):
    """A table measured on a machine twice as fast as this one (half this calibration time)
    gives twice the predicted run times."""
    from stickslip.selection import calibration_seconds

    base = select_method(langevin(), 0.1, table=table)
    assert base.speed == 1.0  # this table has no calibration: costs as measured
    rows = list(csv.DictReader(open(table)))
    for r in rows:
        r["calibration_seconds"] = 0.5 * calibration_seconds()
    fast = tmp_path / "fast.csv"
    with open(fast, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=[*FIELDS, "calibration_seconds"])
        w.writeheader()
        w.writerows(rows)
    choice = select_method(langevin(), 0.1, table=str(fast))
    assert choice.speed == pytest.approx(2.0)
    assert choice.chosen.seconds == pytest.approx(2 * base.chosen.seconds)


def test_stability_notes_veto_an_unstable_approximation(tmp_path):
    """Fn2 measured (falsely, in this table) as accurate, but the benchmark saw its density go
    negative: it is not chosen, and the reason says why."""
    rows = [
        dict(analytic_row("Fn2", 0.01, 0.001), note="truncation order 2: density negative"),
        mc_row(10_000, 0.05, 0.2),
    ]
    table = write_table(tmp_path / "t.csv", rows)
    choice = select_method(langevin(), 0.1, table=table)
    assert choice.chosen.key == "mc_exact"
    vetoed = [c for c in choice.candidates if c.key == "Fn2"][0]
    assert vetoed.rejected.startswith("stability: ") and "negative" in vetoed.rejected
    assert "Fn2" in choice.reason


def test_white_noise_has_no_method():
    with pytest.raises(SelectionError, match="does not converge in dt"):
        select_method(langevin(tau=None), 0.1)


def test_a_model_without_exact_stepping_says_it_cannot_promise():
    model = ss.get_model("friction-block").example()
    choice = select_method(model, 0.2)
    assert not choice.promised and choice.settings["solver"] == "euler"
    assert "cannot promise L1 <= 0.2" in choice.reason and "step bias" in choice.reason
    with pytest.warns(ss.SelectionWarning, match="cannot promise"):
        res = first_passage_density(model, np.arange(0.05, 10.0, 0.1), 0.2)
    assert res.standard_error is not None


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


def test_packaged_table_says_how_fast_its_machine_was():
    rows = load_table()
    assert all(r["calibration_seconds"] > 0 for r in rows)


@pytest.mark.parametrize("output", ["slip_time", "period"])
@pytest.mark.parametrize("tol", [0.3, 0.1, 0.05, 0.02])
def test_public_set_choice_meets_tolerance_with_its_margin(tol, output):
    """On the public set the choice's bound (measured L1 + margin) meets the tolerance, and
    the margin costs at most 4x the cheapest row whose *mean* L1 meets it."""
    choice = select_method(langevin(), tol, output)
    rows = [r for r in load_table() if r["set"] == "public" and r["output"] == output]
    meeting = [r for r in rows if r["l1"] <= tol]
    assert meeting, f"the packaged table measures no method reaching {tol} on the public set"
    cheapest = min(r["run_seconds"] for r in meeting) * choice.speed
    assert choice.chosen.error <= tol and choice.chosen.basis.startswith(("measured", "predicted"))
    assert choice.chosen.seconds <= 4 * cheapest


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


# -- off the measured sets: the promise against an independent converged run ---------------------
def reference_run(model, output, n_paths, seed=424242):
    """A converged Monte Carlo reference: exact stepping at a step 10x below the pilot's, a
    seed of its own; its cells (150 or 100 on its 99.9 % range), masses and the bound on its
    own L1 noise, (A + 2 sqrt(1 - 2/pi)) / sqrt(N) with A from its own masses."""
    lg = model.linear_gaussian()
    slow = 1.0 / np.min(np.abs(np.linalg.eigvals(np.asarray(lg.A, float))))
    ens = ss.simulate(model, n_paths, 0.02 * slow, 100.0, seed=seed, solver="exact")
    x = np.asarray(getattr(ens, output))
    bins = 150 if output == "slip_time" else 100
    edges = np.linspace(0.0, float(np.nanquantile(x, 0.999)), bins + 1)
    counts, _ = np.histogram(x[np.isfinite(x)], bins=edges)
    p = counts / n_paths
    A = math.sqrt(2 / math.pi) * np.sum(np.sqrt(p * (1 - p)))
    noise = (A + 2 * math.sqrt(1 - 2 / math.pi)) / math.sqrt(n_paths)
    return edges, p, noise


def check_promise(model, tol, output="slip_time", n_ref=100_000, seed=3):
    """first_passage_density on the reference's cell centres: its L1 to the reference is
    within the tolerance plus the reference's own noise (triangle inequality), or it
    refuses with one clear line. Returns the choice (None if refused)."""
    edges, p_ref, noise = reference_run(model, output, n_ref)
    centres = 0.5 * (edges[1:] + edges[:-1])
    try:
        res = first_passage_density(model, centres, tol, output=output, seed=seed)
    except SelectionError as err:
        assert "\n" not in str(err)
        return None
    assert res.choice.promised and res.choice.reference_set is None
    l1 = float(np.sum(np.abs(res.density * np.diff(edges) - p_ref)))
    assert l1 <= tol + noise, (res.choice.reason, l1, noise)
    return res.choice


@pytest.mark.slow  # 6 s cold; test_first_passage_density_runs_the_choice runs a choice by default
def test_the_promise_holds_on_a_parameter_set_never_measured():
    """omega0 = 1.5, tau = 0.03, D = 0.3: not in the table; its choice, run, is within the
    tolerance of a converged run."""
    model = langevin(omega0=1.5, tau=0.03, D=0.3)
    choice = check_promise(model, 0.1)
    assert choice is not None and choice.kind == "simulation"


@pytest.mark.slow
@pytest.mark.parametrize("output", ["slip_time", "period"])
@pytest.mark.parametrize("tol", [0.1, 0.05])
@pytest.mark.parametrize(
    "name, kw",
    [
        ("near the critical speed", dict(D=0.05, v_b=1.2)),
        ("beyond the critical speed", dict(v_b=1.3)),
        ("short tau", dict(tau=0.01)),
        ("long tau", dict(tau=2.0, D=0.2)),
        ("stiff, weakly damped", dict(omega0=3.0, zeta=0.03, D=1.0)),
    ],
)
def test_the_promise_holds_off_the_measured_sets(name, kw, tol, output):
    check_promise(langevin(**kw), tol, output, n_ref=400_000)


@pytest.mark.slow
def test_the_promise_holds_for_a_random_threshold():
    model = ss.get_model("random-threshold")(
        1.0, 0.1, 0.4, 1.0, "uniform", {"low": 0.6, "high": 1.4}, tau=0.1
    )
    check_promise(model, 0.05, n_ref=400_000)


@pytest.mark.slow
@pytest.mark.parametrize("kw", [dict(omega0=1.5, tau=0.03, D=0.3), dict(D=0.05, v_b=1.2)])
def test_the_check_of_a_level_crossing_approximation_bounds_its_error(monkeypatch, kw):
    """Every level-crossing approximation checked against a pilot (as select_method does off
    the measured sets when it can pay; forced here for all of them): its bound is at least
    its true error (against a converged run) less the reference's own noise, so one that
    passes the check meets the tolerance."""
    import stickslip.selection as sel

    monkeypatch.setattr(sel, "CHECK_WORTH", 0.0)
    model = langevin(**kw)
    rows = [r for r in load_table() if r["output"] == "slip_time"]
    pilot = sel._pilot(model, "slip_time", 100.0, seed=2)
    # A tolerance just above the pilot's own noise bound: none passes, so none stops the rest.
    tol = 1.01 * sel._mc_bound(pilot["noise_constant"], 0.0, pilot["n_paths"])
    checked = sel._checked_analytic(model, rows, tol, 1.0, pilot, "slip_time", [])
    assert {c.key for c in checked} == set(sel.ANALYTIC)
    edges, p_ref, noise = reference_run(model, "slip_time", 400_000)
    for c in checked:
        values = sel._analytic_cells(model, c.settings, "slip_time", edges)
        true = float(np.sum(np.abs(values * np.diff(edges) - p_ref)))
        assert c.error >= true - noise, (c.key, c.error, true)


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
