"""The Python API's limits (issue 42): degenerate or overflowing models refused where they
are built, memory estimated before anything is allocated, time-scale mismatches warned about
or refused, a miss bound that is a probability, and one error family for bad values."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import stickslip as ss
from stickslip import ParameterError, ResourceError, StickSlipError

Langevin = ss.get_model("langevin")
RandomThreshold = ss.get_model("random-threshold")
FrictionBlock = ss.get_model("friction-block")
BurridgeKnopoff = ss.get_model("burridge-knopoff")

BASE = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
VW = {"F0": 1.0, "alpha": 1.0, "sigma": 0.2}


def _one_line(err):
    text = str(err)
    assert "\n" not in text and text.isprintable() and len(text) <= 500, text
    return text


@pytest.fixture
def memory_limit(monkeypatch):
    """A fixed memory limit (64 GiB), so that the refusals do not depend on the machine."""
    monkeypatch.setenv("STICKSLIP_MEMORY_LIMIT", str(64 * 2**30))
    return 64 * 2**30


# -- 1. degenerate and overflowing models, refused where they are built ------------------------
@pytest.mark.parametrize(
    "change, parameter",
    [
        ({"omega0": 1e20}, "omega0"),
        ({"zeta": 1e20}, "zeta"),
        ({"tau": 1e-20}, "tau"),
        ({"D": 1e300}, "D"),
        ({"D": 1e-300}, "D"),
        ({"omega0": 1e300}, "omega0"),
    ],
)
def test_langevin_scales_refused_on_construction(change, parameter):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning (overflow) before the error
        with pytest.raises(ParameterError) as info:
            Langevin(**dict(BASE, **change))
    assert info.value.parameter == parameter
    assert "1e+12" in _one_line(info.value)  # the admissible range is stated


def test_langevin_scale_limits_are_the_stated_ones():
    # Just inside each stated limit is accepted, just outside refused.
    Langevin(**dict(BASE, omega0=1e12, zeta=1e12, tau=1e-12, D=1e36))  # D/omega0^3 = 1
    for D in (1e12 * 0.99, 1e-100 * 1.01, 0.0):
        Langevin(**dict(BASE, D=D))
    for D in (1e12 * 1.01, 1e-100 * 0.99):
        with pytest.raises(ParameterError, match="noise level"):
            Langevin(**dict(BASE, D=D))
    # The level is D / (omega0^3 x0^2): the same D is admissible at a larger x0.
    Langevin(**dict(BASE, D=1e13, x0=10.0))
    with pytest.raises(ParameterError, match="rate omega0"):
        Langevin(**dict(BASE, omega0=1.01e12))


def test_admissible_fast_model_runs():
    # A model scaled to the fastest admissible rate (1/tau = 1e12 per time unit) still
    # simulates: the limit is where the numbers stop, not before (measured: at 1e14 the
    # covariance tables overflow).
    w = 1e11
    m = Langevin(omega0=w, zeta=0.1 * w, D=0.4 * w, v_b=1.0, x0=1.0 / w, tau=0.1 / w)
    ens = ss.simulate(m, 16, 0.05 / w, 200 / w, seed=1)
    assert np.all(np.isfinite(ens.slip_time))
    # the slip lasts about a period of the scaled oscillation (pi/omega0 ... a few times it)
    assert 1.0 < np.mean(ens.slip_time) * w < 20.0


def test_random_threshold_spread_refused():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ParameterError) as info:
            RandomThreshold(1.0, 0.1, 0.4, 1.0, "lognormal", {"median": 1.0, "sigma": 1e3})
    assert info.value.parameter == "threshold_params.sigma"
    assert "0 or inf" in _one_line(info.value)
    # The stated bound: quantiles 1e-12 within 30 decades of the median (sigma <= 9.8).
    RandomThreshold(1.0, 0.1, 0.4, 1.0, "lognormal", {"median": 1.0, "sigma": 9.5}, tau=0.1)
    with pytest.raises(ParameterError, match="threshold_params.sigma"):
        RandomThreshold(1.0, 0.1, 0.4, 1.0, "lognormal", {"median": 1.0, "sigma": 10.0})
    with pytest.raises(ParameterError, match="threshold_params.shape"):
        RandomThreshold(1.0, 0.1, 0.4, 1.0, "weibull", {"shape": 0.3, "scale": 1.0})
    # the noise level uses the median threshold as x0
    with pytest.raises(ParameterError, match="noise level"):
        RandomThreshold(1.0, 0.1, 1e15, 1.0, "lognormal", {"median": 1.0, "sigma": 0.3})


def test_friction_block_and_chain_noise_refused():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ParameterError) as info:
            FrictionBlock(k=1.0, v_b=0.5, D=1e300, tau=0.1, friction="velocity-weakening",
                          friction_params=VW)  # fmt: skip
    assert info.value.parameter == "D" and "noise level" in _one_line(info.value)
    with pytest.raises(ParameterError, match="'D'"):
        BurridgeKnopoff(4, k_c=1.0, k_p=1.0, v_b=0.1, friction="velocity-weakening",
                        friction_params=VW, D=1e300, tau=0.1)  # fmt: skip
    with pytest.raises(ParameterError, match="'k_c'"):
        BurridgeKnopoff(4, k_c=1e30, k_p=1.0, v_b=0.1, friction="velocity-weakening",
                        friction_params=VW)  # fmt: skip


# -- 2. limits before allocating ----------------------------------------------------------------
def test_simulate_too_many_paths_refused(memory_limit):
    with pytest.raises(ResourceError) as info:
        ss.simulate(Langevin(**BASE), 2**32 - 1, 0.1, 10.0)
    text = _one_line(info.value)
    # 2**32 paths of 3 states need over a terabyte; the figure and the limit are named
    gib = float(text.split("needs about ")[1].split(" GiB")[0])
    assert gib > 2**32 * 3 * 8 * 3 / 2**30
    assert "limit of 64 GiB" in text


def test_simulate_chain_too_many_paths_refused(memory_limit):
    m = BurridgeKnopoff(4, k_c=1.0, k_p=1.0, v_b=0.1, friction="velocity-weakening",
                        friction_params=VW)  # fmt: skip
    with pytest.raises(ResourceError, match=r"needs about [0-9.e+]+ GiB, past the limit of 64 GiB"):
        ss.simulate_chain(m, 10**12, 0.01, 10.0)


def test_simulate_cycles_recording_too_large_refused(memory_limit):
    # 64 paths x 1e8 steps x (3 states + time + flag): about 0.5 TB of time series
    with pytest.raises(ResourceError, match="record=False"):
        ss.simulate_cycles(Langevin(**BASE), 64, 1e-4, 1e4)


def test_estimator_grid_too_large_refused(memory_limit):
    # omega0 = 1e8: the default grid step is a fifth of 1/omega0; the period density's time
    # grid to t = 8 would hold 2**32 points (XLA was asked for 309 GB)
    est = ss.CrossingEstimator(Langevin(**dict(BASE, omega0=1e8)))
    assert est.dt == pytest.approx(2e-9)
    with pytest.raises(ResourceError, match="time grid to t = 8 at dt = 2e-09"):
        est.period_density(np.array([1.0, 2.0, 3.0]))


def test_memory_limit_setting_checked(monkeypatch):
    monkeypatch.setenv("STICKSLIP_MEMORY_LIMIT", "lots")
    with pytest.raises(ParameterError, match="STICKSLIP_MEMORY_LIMIT"):
        ss.simulate(Langevin(**BASE), 4, 0.1, 1.0)


# -- 3. time-scale mismatch and the miss bound --------------------------------------------------
@pytest.mark.parametrize("D", [0.4, 0.0])
def test_hopeless_step_refused(D):
    m = Langevin(**dict(BASE, omega0=1e8, D=D))
    with pytest.raises(ParameterError) as info:
        ss.simulate(m, 4, 0.2, 1.0)
    text = _one_line(info.value)
    assert info.value.parameter == "dt"
    # dt / (pi / omega0) = 0.2 / 3.14e-8
    assert f"{0.2 * 1e8 / math.pi:.2g} times" in text and "pi/rho(A) = 3.1e-08" in text


@pytest.mark.parametrize(
    "dt, kwargs, floor",
    [
        (5e-324, {}, 1e-6),  # hypothesis's case: a LinAlgError from the bridge tables
        (1e-7, {}, 1e-6),  # every path stuck in its first step, silently
        (1e-10, {"monitor": "grid"}, 1.5e-9),
    ],
    ids=["subnormal", "bridge", "grid"],
)
def test_too_fine_step_refused(dt, kwargs, floor):
    # The public set's fastest rate is 1/tau = 10 (the oscillator's |eig| is omega0 = 1): the
    # bridge detector certifies down to 1e-5 / rho = 1e-6, float64 keeps half the digits of
    # a step's change down to sqrt(eps) / rho = 1.49e-9 (said rounded up, 1.5e-9).
    m = Langevin(**BASE)
    with pytest.raises(ParameterError) as info:
        ss.simulate(m, 4, dt, 10 * dt, **kwargs)
    text = _one_line(info.value)
    assert info.value.parameter == "dt" and "too fine" in text
    assert f"take dt >= {floor:.3g}" in text
    ens = ss.simulate(m, 4, floor, 10 * floor, **kwargs)  # the step it names is taken
    assert not ens.stuck.any()  # (the first slip lasts ~3; none ends in ten such steps)


def test_model_in_extreme_units_refused():
    # A noise level D / (omega0^3 x0^2) = 1e-100 is admitted, but with x0 = 1e-100 the
    # step's position variance falls below float64's normal range: was a LinAlgError.
    m = Langevin(**dict(BASE, D=1e-300, v_b=1e-100, x0=1e-100))
    with pytest.raises(ParameterError) as info:
        ss.simulate(m, 4, 0.1, 1.0)
    assert info.value.parameter == "model" and "units" in _one_line(info.value)


@pytest.mark.slow
def test_step_at_the_fine_floor_keeps_the_law():
    """At the finest step the bridge detector is given (dt = 1e-6 on the public set), the
    slips that end by t = 0.01 are as many as at dt = 1e-3, within 4 standard errors (below
    the floor, at 1e-7, every path ended in its first step)."""
    m = Langevin(**BASE)
    fine = ss.simulate(m, 50_000, 1e-6, 0.01, seed=5, progress=False)
    coarse = ss.simulate(m, 200_000, 1e-3, 0.01, seed=6, progress=False)
    p_f, p_c = fine.stuck.mean(), coarse.stuck.mean()
    se = math.sqrt(p_f * (1 - p_f) / 50_000 + p_c * (1 - p_c) / 200_000)
    assert p_c > 0.005  # (enough slips end by 0.01 to be counted: ~1.3 %)
    assert abs(p_f - p_c) < 4 * se, (p_f, p_c, se)
    assert fine.stats["miss_bound"] < 1e-6


def test_coarse_step_warns_for_noisy_model():
    m = Langevin(**dict(BASE, omega0=1e7))
    with pytest.warns(UserWarning, match=r"times the slip's time scale pi/rho\(A\) = 3.1e-07"):
        ens = ss.simulate(m, 8, 0.2, 1.0)
    assert np.all(np.isfinite(ens.slip_time))


def test_unbounded_miss_bound_is_clipped_and_warned():
    # OU noise of correlation time 1e-12: the certification cannot resolve it, and the summed
    # bounds pass 1 per path
    m = Langevin(**dict(BASE, tau=1e-12))
    with pytest.warns(UserWarning, match="unbounded"):
        ens = ss.simulate(m, 16, 1e-12, 1e-9)
    assert ens.stats["miss_bound"] == 1.0


def test_valid_run_miss_bound_is_a_probability():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ens = ss.simulate(Langevin(**BASE), 16, 0.1, 20.0)
    assert 0.0 <= ens.stats["miss_bound"] < 1e-3


# -- 4. one error family ------------------------------------------------------------------------
def _chain():
    return BurridgeKnopoff(4, k_c=1.0, k_p=1.0, v_b=0.1, friction="velocity-weakening",
                           friction_params=VW)  # fmt: skip


@pytest.mark.parametrize(
    "kwargs, parameter",
    [
        ({"seed": -1}, "seed"),
        ({"seed": "a"}, "seed"),
        ({"seed": 2**64}, "seed"),
        ({"record_blocks": "yes"}, "record_blocks"),
        ({"record_dt": 1e300}, "record_dt"),
    ],
)
def test_simulate_chain_bad_values(kwargs, parameter):
    with pytest.raises(ParameterError) as info:
        ss.simulate_chain(_chain(), 1, 0.01, 1.0, **kwargs)
    assert info.value.parameter == parameter
    _one_line(info.value)


@pytest.fixture(scope="module")
def estimator():
    return ss.CrossingEstimator(Langevin(**BASE))


@pytest.mark.parametrize(
    "call",
    [
        lambda e: e.first_passage("abc"),
        lambda e: e.first_passage(["1", "x"]),
        lambda e: e.first_passage(None),
        lambda e: e.first_passage(object()),
        lambda e: e.first_passage_cells("abc"),
        lambda e: e.period_density("abc"),
        lambda e: e.slip_distance_density([0.0, "x"]),
        lambda e: e.n1("abc"),
        lambda e: e.n2("abc", [1.0]),
        lambda e: e.diagnostics("abc"),
    ],
)
def test_estimator_bad_values(estimator, call):
    with pytest.raises(ParameterError) as info:
        call(estimator)
    _one_line(info.value)


@pytest.fixture
def tables(tmp_path):
    (tmp_path / "columns.csv").write_text("a,b\n1,2\n")
    (tmp_path / "empty.csv").write_text("")
    (tmp_path / "binary.csv").write_bytes(b"\xff\xfe\x00\x81garbage")
    return tmp_path


@pytest.mark.parametrize(
    "name, reason",
    [
        ("columns.csv", "not an accuracy-cost table"),
        ("empty.csv", "holds no rows"),
        ("binary.csv", "not a UTF-8 text"),
        ("missing.csv", "names no file"),
        (".", "is a folder"),
    ],
)
def test_select_method_bad_table(tables, name, reason):
    with pytest.raises(ParameterError, match=reason) as info:
        ss.select_method(Langevin(**BASE), 0.05, table=str(tables / name))
    text = _one_line(info.value)
    assert "garbage" not in text and info.value.parameter == "table"


@pytest.mark.parametrize("table", [123, ["x"], ""])
def test_select_method_table_of_wrong_kind(table):
    with pytest.raises(ParameterError, match="'table'"):
        ss.select_method(Langevin(**BASE), 0.05, table=table)


def test_selection_bad_values():
    m = Langevin(**BASE)
    with pytest.raises(ParameterError, match="'seed'"):
        ss.select_method(m, 0.05, seed=-1)
    for t in ("abc", ["a", "b"]):
        with pytest.raises(ParameterError, match="'t'"):
            ss.first_passage_density(m, t)


def test_simulate_cycles_record_flag():
    with pytest.raises(ParameterError, match="'record'"):
        ss.simulate_cycles(Langevin(**BASE), 1, 0.1, 1.0, record="x")


def test_wrong_signature_stays_type_error():
    # Python's own TypeError for a call that does not fit the signature
    with pytest.raises(TypeError) as info:
        ss.simulate_chain(_chain())
    assert not isinstance(info.value, StickSlipError)


@pytest.mark.parametrize("v_b", [1e-300, 1e-13, 1e13])
def test_driving_speed_out_of_the_slips_scale_is_refused(v_b):
    """v_b / (omega0 x0) = 1e-300 gave stick times of inf (found by tests/test_fuzz.py)."""
    Model = ss.get_model("langevin")
    with pytest.raises(ss.ParameterError, match="v_b") as err:
        Model(omega0=1.0, zeta=0.1, D=0.0, v_b=v_b, x0=1.0, tau=0.1)
    assert "\n" not in str(err.value)
