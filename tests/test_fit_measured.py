"""`fit` with the measurement inside the forward model (issue 40, item 1): cycles extracted
from a sampled, noisy trace (`Cycles`) are fitted against the model's own trace sampled,
made noisy and extracted alike; a dict is per-cycle truth.

The data's traces are made here, independently of `measured_cycles`: the model's
successive cycles (`simulate_cycles`, a step ten times finer than the fit's), each slip's
recorded states interpolated onto the sampling grid and each stick in closed form
($x$ grows at $v_b$), Gaussian noise on the position, then `extract_cycles`. Seeds differ
from the fit's; boxes are not centred on the truth."""

from __future__ import annotations

import math
import time
import warnings

import numpy as np
import pytest

import stickslip as ss
from stickslip._inference import likelihood
from stickslip._inference.forward import simulate_values
from stickslip._inference.measurement import Measurement
from stickslip.extract import Cycles

PARAMS = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)  # the public set
FIXED = {k: v for k, v in PARAMS.items() if k != "D"}
H = 0.1  # sampling interval: a tenth of the slip time scale
NOISE = 1e-3  # position noise sd
Z99 = 2.5758293035489  # the normal's 99.5 % quantile
Z95 = 1.959963984540054


def sampled_trace(series, path, t_max, h, v_b):
    """Position of one simulated path on a grid of spacing `h`: each slip's recorded states
    interpolated, each stick in closed form (x grows at v_b from the stick position)."""
    t, states, slipping = series.trajectory(path)
    rows = series.cycles["path"] == path
    cyc = {k: series.cycles[k][rows] for k in ("release_time", "slip_time", "period")}
    grid = np.arange(0.0, t_max, h)
    x = np.full(grid.size, np.nan)
    ends = np.nonzero(~slipping)[0]
    starts = np.concatenate([[0], ends[:-1] + 1])
    for c, (s, e) in enumerate(zip(starts, ends, strict=False)):
        t0, t_sl, period = cyc["release_time"][c], cyc["slip_time"][c], cyc["period"][c]
        slip = (grid >= t0) & (grid < t0 + t_sl)
        x[slip] = np.interp(grid[slip], t[s : e + 1], states[s : e + 1, 0])
        stick = (grid >= t0 + t_sl) & (grid < t0 + period)
        x[stick] = states[e, 0] + v_b * (grid[stick] - (t0 + t_sl))
    ok = np.isfinite(x)
    return grid[ok], x[ok]


def measured_data(seed, n_paths=4, t_max=600.0, **params) -> Cycles:
    """The cycles `extract_cycles` finds in `n_paths` noisy position traces of `t_max` each
    (about 80 cycles a path at the public set), joined into one `Cycles`."""
    model = ss.get_model("langevin")(**{**PARAMS, **params})
    series = ss.simulate_cycles(model, n_paths, 0.01, t_max, seed=seed)
    rng = np.random.default_rng([seed, 1])
    found = []
    for p in range(n_paths):
        t, x = sampled_trace(series, p, t_max, H, PARAMS["v_b"])
        found.append(ss.extract_cycles(t, x + rng.normal(0.0, NOISE, x.size), v_b=1.0))
    table = {k: np.concatenate([c.table[k] for c in found]) for k in found[0].table}
    return Cycles(table, found[0].info)


@pytest.fixture(scope="module")
def data():
    return measured_data(seed=123)


def log_se(result, name):
    """The standard error of log(name) from the 95 % Wald interval (log scale)."""
    lo, hi = result.ci[name]
    return math.log(hi / lo) / (2 * Z95)


@pytest.mark.slow  # a whole fit through the measurement, ~17 s CPU; the
# default tier keeps the measured route's own checks below
def test_cycles_of_a_noisy_trace_give_D_with_an_interval_around_the_truth(data):
    """D free in a box whose log-centre (0.45) is not the truth: the truth inside the 99 %
    interval (a miss 1 % of the time at the stated coverage), and an interval that says
    something."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = ss.fit("langevin", data, {"D": (0.1, 2.0)}, FIXED, seed=7, n_sim=2000, check=False)
    se = log_se(r, "D")
    assert abs(math.log(r.estimate["D"] / PARAMS["D"])) < Z99 * se, r.summary()
    assert 1.05 < math.exp(2 * Z95 * se) < 2.0, r.summary()  # hi / lo
    assert r.diagnostics["measurement"].sampling_interval == pytest.approx(H)
    assert "through the data's measurement" in r.method
    assert set(r.data) == {"slip_time", "slip_distance", "stick_time", "period"}


class Stop(Exception):
    pass


def test_a_dict_and_a_cycles_of_the_same_data_take_different_routes(monkeypatch, data):
    """The same table: as a `Cycles` it is simulated through its measurement, as a dict
    (its table) as per-cycle values, with no measurement. (A slip the extraction timed as 0,
    which per-cycle values cannot have, is dropped from both.)"""
    keep = data.table["slip_time"] > 0
    data = Cycles({k: v[keep] for k, v in data.table.items()}, data.info)
    seen = []

    def spy(model, n, dt, t_max, seed, measurement=None):
        seen.append((n, measurement))
        raise Stop

    monkeypatch.setattr(likelihood, "simulate_values", spy)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the dict looks sampled, and is said to
        routes = []
        for given in (data, dict(data.table)):
            seen.clear()
            with pytest.raises(Stop):
                ss.fit("langevin", given, {"D": (0.1, 2.0)}, FIXED)
            # (through a measurement the grid's points start in threads: several calls)
            assert len(set(map(repr, seen))) == 1, seen
            routes.append(seen[0])
    (n_measured, measured), (n_per_cycle, none) = routes
    assert measured == Measurement.from_cycles(data) and none is None
    assert (n_measured, n_per_cycle) == (4000, 100_000)


def test_the_measured_route_joins_cycles():
    """Through the measurement, zero-length sticks and sticks shorter than the extraction
    resolves join their neighbouring slips: no zero stick is left, fewer cycles than
    simulated, longer slips. Per-cycle values keep their zero sticks (38 % at the public
    set). The counts are far apart: each fraction's sampling error is below 0.01."""
    model = ss.get_model("langevin")(**PARAMS)
    m = Measurement(sampling_interval=H, signal="x", noise_sd=NOISE * H / math.sqrt(2.0) * 10,
                    min_stick=2)  # fmt: skip
    n = 3000
    measured = simulate_values(model, n, None, None, 5, m)
    per_cycle = simulate_values(model, n, 0.2, 200.0, 5)
    assert np.mean(per_cycle["stick_time"] == 0) > 0.3
    assert np.all(measured["stick_time"] > 0)
    assert measured["slip_time"].size < 0.8 * n
    assert np.median(measured["slip_time"]) > np.median(per_cycle["slip_time"])


def test_a_point_with_no_measured_cycles_scores_minus_infinity(monkeypatch, data):
    """Where the simulated trace shows no cycles (`measured_cycles` raises `DataError`) or
    fewer than `MIN_SIMULATED`, the point's log-likelihood is -inf, not a crash; per-cycle
    data still raise."""

    def nothing(model, n, dt, t_max, seed, measurement=None):
        raise ss.DataError("measured_cycles: the simulated trace shows no cycles")

    monkeypatch.setattr(likelihood, "simulate_values", nothing)
    cols = {k: data.table[k] for k in ("slip_time", "stick_time")}
    model = ss.get_model("langevin")(**PARAMS)
    bandwidth = dict(slip_time=0.1, stick_time=0.1)
    m = Measurement.from_cycles(data)
    assert likelihood._per_cycle(model, cols, bandwidth, 2000, None, None, 0, m) is None
    with pytest.raises(ss.DataError):
        likelihood._per_cycle(model, cols, bandwidth, 2000, 0.2, 50.0, 0, None)
    # a trace with a handful of cycles has no density to compare with: -inf too
    few = {k: v[: likelihood.MIN_SIMULATED - 1] for k, v in cols.items()}
    monkeypatch.setattr(likelihood, "simulate_values", lambda *args: few)
    assert likelihood._per_cycle(model, cols, bandwidth, 2000, None, None, 0, m) is None
    enough = {k: v[: likelihood.MIN_SIMULATED] for k, v in cols.items()}
    monkeypatch.setattr(likelihood, "simulate_values", lambda *args: enough)
    terms = likelihood._per_cycle(model, cols, bandwidth, 2000, None, None, 0, m)
    assert all(np.all(np.isfinite(t)) for t in terms.values())


@pytest.mark.slow
def test_coverage_with_the_measurement_in_the_model():
    """Coverage over 20 simulated data sets (the issue asks for 40: 20 fit the slow tier's
    time on 2 cores, ~20 s a fit), each ~320 cycles extracted from noisy traces, D free
    (tau known) in a box not centred on the truth: the 95 % interval covers the truth in at
    least 16 of 20 sets (at a true 95 %, 15 or fewer happen 1.6 % of the time), and the
    spread of log D's estimates matches the mean reported standard error within three of
    its own sampling errors (relative sd of an sd from 20 values: 1 / sqrt(38))."""
    n_sets = 20
    estimates, ses, cover = [], [], 0
    wall = time.perf_counter()
    for i in range(n_sets):
        d = measured_data(seed=5000 + i)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = ss.fit("langevin", d, {"D": (0.1, 2.0)}, FIXED, seed=11 + i, check=False)
        lo, hi = r.ci["D"]
        cover += lo <= PARAMS["D"] <= hi
        estimates.append(math.log(r.estimate["D"]))
        ses.append(log_se(r, "D"))
    spread = float(np.std(estimates, ddof=1))
    ratio = spread / float(np.mean(ses))
    print(
        f"measured coverage of D over {n_sets} sets: {cover}/{n_sets}; sd of log D "
        f"{spread:.4f}, mean SE {np.mean(ses):.4f} (ratio {ratio:.3f}); "
        f"{time.perf_counter() - wall:.0f} s"
    )
    assert cover >= 16, cover
    assert abs(ratio - 1.0) < 3.0 / math.sqrt(2 * (n_sets - 1)), ratio
