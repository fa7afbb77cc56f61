"""`fit`: friction-noise parameters back from per-cycle data (issue: from a measured trace to
parameters). Data are simulated from known parameters with seeds the fit does not use."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from conftest import run_cli

import stickslip as ss
from stickslip._inference.forward import simulate_values

BASE = dict(omega0=1.0, zeta=0.1, v_b=1.0, x0=1.0)
TRUTH = dict(D=0.4, tau=0.1)


def slip_times(n, seed, **params):
    """`n` slip times of positive length from the Langevin model (exact stepping)."""
    model = ss.get_model("langevin")(**{**BASE, **TRUTH, **params})
    sim = simulate_values(model, int(n * 1.3) + 100, 0.2, 200.0, seed)
    assert sim["slip_time"].size >= n
    return sim["slip_time"][:n]


def test_one_free_parameter_is_recovered_within_three_standard_errors():
    """D free (tau fixed at the truth): 1500 slip times, 2e4 simulated cycles per point; the
    estimate within 3 of its standard errors (taken from its 95 % interval) of the truth.
    (Coverage of the intervals themselves: the slow tier.)"""
    data = {"slip_time": slip_times(1500, seed=101)}
    r = ss.fit(
        "langevin", data, free={"D": (0.05, 2.0)}, fixed={**BASE, "tau": 0.1}, seed=7,
        n_sim=20_000, check=False,
    )  # fmt: skip
    lo, hi = r.ci["D"]
    se = np.log(hi / lo) / (2 * 1.959964)  # the interval is Wald's in log D
    assert abs(np.log(r.estimate["D"] / TRUTH["D"])) < 3 * se, r.summary()  # 99.7 %
    assert abs(r.estimate["D"] / TRUTH["D"] - 1) < 0.25
    assert 1.02 < hi / lo < 1.6  # an interval that says something
    assert np.isfinite(r.log_likelihood)
    assert "sandwich" in r.method
    # the curvature the interval divides by, and the goodness of fit's one-step replicates
    # use: the plain quadratic through both seeds' values over the design, least squares
    # written out here (a column per term, the curvature halved on its square)
    des = r.diagnostics.design
    du = np.asarray(des.points, float)[:, 0] - des.centre[0]
    values = np.mean(np.asarray(des.values, float), axis=0)
    ok = np.isfinite(values)
    c = np.linalg.lstsq(np.stack([du**0, du, 0.5 * du**2], 1)[ok], values[ok], rcond=None)[0]
    assert np.asarray(r.diagnostics.hessian)[0, 0] == pytest.approx(c[2], rel=1e-9)


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


def test_the_deprecated_trace_arguments_say_what_to_pass_instead():
    """`trace=`/`sampling=` are replaced by the `Cycles`' measurement: a dict cannot be
    fitted as a trace any more (no extraction settings), and says so with the warning."""
    data = {"slip_time": np.linspace(1.0, 2.0, 50)}
    with (
        pytest.warns(DeprecationWarning, match="pass the Cycles"),
        pytest.raises(ss.ParameterError, match="'trace' cannot model a dict's measurement"),
    ):
        ss.fit("langevin", data, {"D": (0.1, 1)}, fixed=BASE | {"tau": 0.1}, trace=True,
               sampling=0.1)  # fmt: skip


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
    proc = run_cli("fit", study, "--out", out, "-q")
    assert proc.returncode == 0, proc.stderr
    record = json.loads((out / "fit.json").read_text())
    lo, hi = record["ci95"]["D"]
    assert lo < record["estimate"]["D"] < hi
    assert record["fixed"]["tau"] == 0.1 and "D" not in record["fixed"]
    assert (out / "fit.png").stat().st_size > 1000
    # the goodness of fit, the checks and the warnings (issue 40, item 7)
    p = record["p_values"]["slip_time"]
    assert 0 < p <= 1 and record["rejected"] is (p < 0.01)
    assert record["measurement"] is None  # a plain table: per-cycle values
    assert record["optimizer"]["cap"] > 0 and record["mc_noise"]["seed"] > 0
    assert isinstance(record["warnings"], list)
    summary = (out / "summary.md").read_text()
    assert f"| D | {record['estimate']['D']:.4g} | [{lo:.4g}, {hi:.4g}] |" in summary
    assert f"| slip_time | {p:.3g} |" in summary
    assert ("The data reject the model" if p < 0.01 else "do not reject the model") in summary


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
    proc = run_cli("fit", study, "--out", out)
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
            seed=2000 + i, check=False,
        )  # fmt: skip
        for k, truth in TRUTH.items():
            cover[k] += r.ci[k][0] <= truth <= r.ci[k][1]
    print(f"coverage over 20 data sets: {cover}")
    for k in TRUTH:
        assert 17 <= cover[k] <= 20, cover


def test_a_model_that_makes_no_positive_slip_time_is_refused_not_fitted():
    """The white-noise langevin (tau=None) ends its slips at once (docs/simulator.md): its
    likelihood of positive slip times is the same at every D. fit said nothing and returned
    an interval of zero width; now one line names the column and the way out."""
    data = {"slip_time": np.random.default_rng(42).exponential(1.0, 300)}
    with pytest.raises(ss.DataError) as err:
        ss.fit("langevin", data, {"D": (0.1, 1.0)}, BASE | {"tau": None}, n_sim=1000,
               check=False)  # fmt: skip
    text = str(err.value)
    assert "do not constrain D" in text and "no slip_time above zero" in text
    assert "tau=None" in text and "\n" not in text
