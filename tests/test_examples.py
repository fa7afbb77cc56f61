"""Every example runs (in a reduced form)."""

import json
import pathlib
import subprocess
import sys

import pytest
from conftest import run_script

import stickslip as ss

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_public_reference_example(tmp_path):
    out = tmp_path / "results"
    run = run_script(ROOT / "examples" / "public_reference.py", "--out", out, "--n-paths", 2000)
    assert run.returncode == 0, run.stderr
    for name in (
        "summary.md",
        "ensemble.npz",
        "slip_time.png",
        "slip_distance.png",
        "time_series.png",
    ):
        assert (out / name).stat().st_size > 0
    assert "mean slip time" in (out / "summary.md").read_text()


@pytest.mark.slow  # 10 s and more on a cold cache
def test_carlson_langer_example(tmp_path):
    """Reduced: 100 blocks for 3000 time units; the run has localized and delocalized
    events and the small-event fit is made."""
    run = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "carlson_langer.py"), "--out", str(tmp_path),
         "--n-blocks", "100", "--t-max", "3000"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "carlson_langer.png").stat().st_size > 0
    assert "small-event slope" in run.stdout


def test_white_noise_example():
    run = run_script(ROOT / "examples" / "white_noise_degeneracy.py", "--n-paths", 300)
    assert run.returncode == 0, run.stderr
    assert "Brownian bridge" in run.stdout


@pytest.mark.slow
def test_throughput_benchmark_runs(tmp_path):
    run = subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks" / "throughput.py"),
            "--n-paths",
            "1000",
            "--pass-n",
            "20000",
            "--json",
            str(tmp_path / "b.json"),
        ],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert "numpy_exact_dropping / stickslip_exact_continuous" in run.stdout
    assert "ratio (NumPy / stickslip, compiled, equal accuracy)" in run.stdout


@pytest.mark.slow
def test_estimator_benchmark_runs():
    run = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "estimator.py"), "--quick"],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert "decoupling order 1" in run.stdout


def _load_benchmark(name):
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow  # ~10 s from an empty cache
def test_accuracy_cost_pipeline_end_to_end(tmp_path, monkeypatch):
    """A tiny accuracy-cost run (small reference, two methods) writes a table and chart that
    the method selection reads back."""
    from stickslip.selection import load_table, select_method

    ac = _load_benchmark("accuracy_cost")
    monkeypatch.setattr(ac, "CACHE", tmp_path / "cache")
    cfg = dict(ref_paths=20_000, ref_dt=0.02, analytic=["Fg1"], period_analytic=[],
               mc={"exact": [0.02]}, n_paths=[1_000, 4_000], repeats=2)  # fmt: skip
    rows, edges = ac.measure("public", ac.SETS["public"], cfg, lambda text: None)
    ac.pareto(rows)
    ac.write_csv(rows, tmp_path / "accuracy_cost.csv")
    ac.chart(rows, tmp_path / "accuracy_cost.png")
    assert (tmp_path / "accuracy_cost.png").stat().st_size > 10_000
    assert len(rows) == 1 + 2 * 2 and any(r["pareto"] for r in rows)
    mc = [r for r in rows if r["family"] == "mc" and r["output"] == "slip_time"]
    assert mc[1]["l1"] < mc[0]["l1"]  # more paths, smaller error
    table = load_table(str(tmp_path / "accuracy_cost.csv"))
    choice = select_method(
        ss.get_model("langevin")(**ac.SETS["public"]),
        0.9 * mc[0]["l1"],
        table=str(tmp_path / "accuracy_cost.csv"),
    )
    assert choice.settings["n_paths"] == 4_000 and len(table) == len(rows)


@pytest.mark.slow
def test_accuracy_cost_quick_mode(tmp_path):
    run = subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks" / "accuracy_cost.py"),
            "--quick",
            "--out",
            str(tmp_path),
        ],  # fmt: skip
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "accuracy_cost.csv").exists() and (tmp_path / "accuracy_cost.png").exists()


@pytest.mark.slow
def test_row_over_time_benchmark_runs(tmp_path):
    """One sample of the table's public L1 0.02 row and the paper's method (the table's own
    timing code), written as a JSON line and summed up against the 0.15 s criterion."""
    out = tmp_path / "samples.jsonl"
    run = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "row_over_time.py"), "--samples", "1",
         "--out", str(out)],
        capture_output=True, text=True,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    sample = json.loads(out.read_text())
    for key in ("exact_dt0.8", "euler_dt0.002"):
        assert len(sample[key]["runs"]) == 3 and 0.0 < sample[key]["l1"] < 0.1
    assert "by the criterion fixed in advance" in run.stdout


@pytest.mark.slow
def test_fit_trace_example(tmp_path):
    """Reduced: 2 traces of 300 time units, 2000 simulated cycles per point: the pipeline
    trace -> cycles -> fit -> figure runs and writes every file."""
    run = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "fit_trace.py"), "--out", str(tmp_path),
         "--paths", "2", "--t-max", "300", "--n-sim", "2000"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    for name in ("trace.csv", "cycles.csv", "fit_study.yaml", "fit/fit.json", "fit/fit.png"):
        assert (tmp_path / name).stat().st_size > 0, name
    assert "95 % interval" in run.stdout and "truth tau = 0.1" in run.stdout


@pytest.mark.slow
def test_campaign_example_reads_the_grid_and_checks_its_laws(tmp_path):
    """The reduced form: the six runs read, the campaign written, each law's box built on
    every stick-slip run (the fits themselves take 20-40 minutes)."""
    run = run_script(ROOT / "examples" / "campaign.py", "--out", tmp_path, "--check-only")
    assert run.returncode == 0, run.stderr
    assert "3 runs" not in run.stdout and "6 runs read" in run.stdout
    assert run.stdout.count("every run's model builds") == 3
    assert (tmp_path / "campaign" / "runs.csv").stat().st_size > 0
