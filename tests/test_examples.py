"""Every example runs (in a reduced form)."""

import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_public_reference_example(tmp_path):
    out = tmp_path / "results"
    run = subprocess.run(
        [
            sys.executable,
            str(ROOT / "examples" / "public_reference.py"),
            "--out",
            str(out),
            "--n-paths",
            "2000",
        ],
        capture_output=True,
        text=True,
    )
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


def test_white_noise_example():
    run = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "white_noise_degeneracy.py"), "--n-paths", "300"],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert "Brownian bridge" in run.stdout


def test_throughput_benchmark_runs(tmp_path):
    run = subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks" / "throughput.py"),
            "--n-paths",
            "1000",
            "--json",
            str(tmp_path / "b.json"),
        ],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert "numpy_exact_dropping / stickslip_exact_continuous" in run.stdout


def test_estimator_benchmark_runs():
    run = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "estimator.py"), "--quick"],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert "decoupling order 1" in run.stdout
