"""`fit`: friction-noise parameters back from per-cycle data (issue: from a measured trace to
parameters). Data are simulated from known parameters with seeds the fit does not use."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest

import stickslip as ss
from stickslip._fit import _simulate, visible_cycles

BASE = dict(omega0=1.0, zeta=0.1, v_b=1.0, x0=1.0)
TRUTH = dict(D=0.4, tau=0.1)


def slip_times(n, seed, **params):
    """`n` slip times of positive length from the Langevin model (exact stepping)."""
    model = ss.get_model("langevin")(**{**BASE, **TRUTH, **params})
    sim = _simulate(model, int(n * 1.3) + 100, 0.2, 200.0, seed)
    assert sim["slip_time"].size >= n
    return sim["slip_time"][:n]


def visible_by_loop(slip, stick):
    """An independent, phase-by-phase statement of what a trace shows (`visible_cycles`)."""
    phases = []  # [kind, duration] with adjacent kinds merged and zero lengths dropped
    for s, k in zip(slip, stick, strict=True):
        for kind, d in ((0, s), (1, k)):
            if d == 0.0:
                continue
            if phases and phases[-1][0] == kind:
                phases[-1][1] += d
            else:
                phases.append([kind, d])
    if phases and phases[0][0] == 1:
        phases = phases[1:]
    cycles = [(phases[i][1], phases[i + 1][1]) for i in range(0, len(phases) - 1, 2)]
    cycles = cycles[1:-1]
    return [c for c in cycles if np.isfinite(c[0]) and np.isfinite(c[1])]


def test_visible_cycles_join_zero_length_phases_as_a_trace_does():
    rng = np.random.default_rng(3)
    n = 400
    slip = np.where(rng.random(n) < 0.15, 0.0, rng.exponential(2.0, n))
    stick = np.where(rng.random(n) < 0.3, 0.0, rng.exponential(1.0, n))
    slip[rng.random(n) < 0.02] = np.nan  # slips cut at t_max
    got = visible_cycles(slip, stick)
    want = visible_by_loop(slip, stick)
    assert got["slip_time"].size == len(want) > 100
    np.testing.assert_allclose(got["slip_time"], [c[0] for c in want], rtol=1e-12)
    np.testing.assert_allclose(got["stick_time"], [c[1] for c in want], rtol=1e-12)
    np.testing.assert_allclose(got["period"], got["slip_time"] + got["stick_time"])


def test_one_free_parameter_is_recovered_within_three_standard_errors():
    """D free (tau fixed at the truth): 1500 slip times, 2e4 simulated cycles per point; the
    estimate within 3 of its standard errors (taken from its 95 % interval) of the truth.
    (Coverage of the intervals themselves: the slow tier.)"""
    data = {"slip_time": slip_times(1500, seed=101)}
    r = ss.fit(
        "langevin", data, free={"D": (0.05, 2.0)}, fixed={**BASE, "tau": 0.1}, seed=7,
        n_sim=20_000,
    )  # fmt: skip
    lo, hi = r.ci["D"]
    se = np.log(hi / lo) / (2 * 1.959964)  # the interval is Wald's in log D
    assert abs(np.log(r.estimate["D"] / TRUTH["D"])) < 3 * se, r.summary()  # 99.7 %
    assert abs(r.estimate["D"] / TRUTH["D"] - 1) < 0.25
    assert 1.02 < hi / lo < 1.6  # an interval that says something
    assert np.isfinite(r.log_likelihood)
    assert "sandwich" in r.method


@pytest.mark.parametrize(
    "data, free, match",
    [
        ({}, {"D": (0.1, 1)}, "data"),
        ({"slip": np.ones(50)}, {"D": (0.1, 1)}, "has none of the columns"),
        ({"slip_time": -np.ones(50)}, {"D": (0.1, 1)}, "must be > 0"),
        ({"slip_time": np.ones(5)}, {"D": (0.1, 1)}, "at least 10"),
        ({"slip_time": np.ones(50), "period": np.ones(40)}, {"D": (0.1, 1)}, "one length"),
        ({"slip_time": np.ones(50)}, {"D": (1, 0.1)}, "low < high"),
        ({"slip_time": np.ones(50)}, {}, "non-empty"),
    ],
)
def test_bad_input_is_one_line_naming_the_field(data, free, match):
    with pytest.raises(ss.StickSlipError, match=match) as err:  # ParameterError or DataError
        ss.fit("langevin", data, free, fixed=BASE | {"tau": 0.1})
    assert "\n" not in str(err.value) and str(err.value).startswith("fit: parameter")


def test_slip_distances_of_a_trace_are_refused():
    data = {"slip_time": np.ones(50), "slip_distance": np.ones(50)}
    with pytest.raises(ss.ParameterError, match="cannot be fitted from a trace"):
        ss.fit(
            "langevin", data, {"D": (0.1, 1)}, fixed=BASE | {"tau": 0.1}, trace=True, sampling=0.1
        )


def _study(tmp_path, csv_name="cycles.csv", free=None, **fit):
    import yaml

    study = {
        "title": "fit test",
        "model": {"name": "langevin", "params": {**BASE, **TRUTH}},
        "fit": {"data": csv_name, "free": free or {"D": [0.05, 2.0]}, "n_sim": 5000, **fit},
    }
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(study))
    return path


def test_fit_command_writes_estimates_intervals_and_figure(tmp_path):
    x = slip_times(400, seed=202)
    np.savetxt(tmp_path / "cycles.csv", x[:, None], delimiter=",", header="slip_time",
               comments="")  # fmt: skip
    study = _study(tmp_path)
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "stickslip.cli", "fit", str(study), "--out", str(out), "-q"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    record = json.loads((out / "fit.json").read_text())
    lo, hi = record["ci95"]["D"]
    assert lo < record["estimate"]["D"] < hi
    assert record["fixed"]["tau"] == 0.1 and "D" not in record["fixed"]
    assert (out / "fit.png").stat().st_size > 1000
    assert "| D |" in (out / "summary.md").read_text()


@pytest.mark.parametrize(
    "content, field",
    [
        ("period_x\n1\n2\n", "fit.data"),
        ("", "fit.data"),
        ("slip_time\n1\n-2\n", "fit.data"),
        ("slip_time\n1\nabc\n", "fit.data"),
    ],
)
def test_fit_command_bad_data_is_one_line_and_writes_nothing(tmp_path, content, field):
    (tmp_path / "cycles.csv").write_text(content)
    study = _study(tmp_path)
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "stickslip.cli", "fit", str(study), "--out", str(out)],
        capture_output=True, text=True,
    )  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and field in lines[0], lines
    assert not out.exists()


def test_fit_block_names_an_unknown_parameter(tmp_path):
    study = _study(tmp_path, free={"tua": [0.01, 1.0]})
    with pytest.raises(ss.StudyError, match="fit.free.tua: is not a parameter.*did you mean 'tau'"):
        ss.load_study(study)


@pytest.mark.slow
def test_noise_intensity_and_correlation_time_from_3000_slip_times():
    """The issue's acceptance: D and tau free, 3000 slip times: both within 25 % of the truth
    and within 4 standard errors of it (one data set: a 95 % interval misses one parameter
    of two about 10 % of the time, which the 20-set coverage test below measures; the time
    is printed; about 30-45 s on 2 cores)."""
    data = {"slip_time": slip_times(3000, seed=12345)}
    t0 = time.perf_counter()
    r = ss.fit("langevin", data, free={"D": (0.1, 1.0), "tau": (0.02, 0.5)}, fixed=BASE, seed=1)
    print(f"fit of D and tau: {time.perf_counter() - t0:.1f} s\n{r.summary()}")
    for k, truth in TRUTH.items():
        lo, hi = r.ci[k]  # Wald intervals on the log scale (the boxes are positive)
        se = (np.log(hi) - np.log(lo)) / (2 * 1.959963984540054)
        assert abs(np.log(r.estimate[k] / truth)) < 4 * se, r.summary()
        assert abs(r.estimate[k] / truth - 1) < 0.25


@pytest.mark.slow
def test_intervals_cover_the_truth_over_20_data_sets():
    """Coverage: 20 synthetic data sets of 3000 slip times (seeds 1000..1019, fits with seeds
    2000..2019): each parameter's 95 % interval holds the truth in 85-100 % of them."""
    cover = {k: 0 for k in TRUTH}
    for i in range(20):
        data = {"slip_time": slip_times(3000, seed=1000 + i)}
        r = ss.fit(
            "langevin", data, free={"D": (0.1, 1.0), "tau": (0.02, 0.5)}, fixed=BASE,
            seed=2000 + i,
        )  # fmt: skip
        for k, truth in TRUTH.items():
            cover[k] += r.ci[k][0] <= truth <= r.ci[k][1]
    print(f"coverage over 20 data sets: {cover}")
    for k in TRUTH:
        assert 17 <= cover[k] <= 20, cover


def test_a_trace_needs_its_sampling_interval():
    with pytest.raises(ss.ParameterError, match="'sampling' is required with trace=True"):
        ss.fit("langevin", {"slip_time": np.ones(50)}, {"D": (0.1, 1)}, BASE | {"tau": 0.1},
               trace=True)  # fmt: skip


def test_visible_cycles_drop_what_the_sampling_cannot_see():
    """Phases no longer than the resolution join their neighbours (the loop statement with
    those phases set to zero length)."""
    rng = np.random.default_rng(5)
    n = 300
    slip, stick = rng.exponential(1.0, n), rng.exponential(0.5, n)
    got = visible_cycles(slip, stick, min_slip=0.2, min_stick=0.3)
    want = visible_by_loop(np.where(slip <= 0.2, 0.0, slip), np.where(stick <= 0.3, 0.0, stick))
    np.testing.assert_allclose(got["slip_time"], [c[0] for c in want], rtol=1e-12)
    np.testing.assert_allclose(got["stick_time"], [c[1] for c in want], rtol=1e-12)
