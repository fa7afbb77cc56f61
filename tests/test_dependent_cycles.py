"""Fits of dependent cycles and of nested candidates.

A row of cycles is a slip and the stick that follows it; a random static threshold ends
that stick and starts the next row's slip, so neighbouring rows share a draw. The
sandwich's meat then carries the scores' lagged cross products (`intervals._meat`), the lag
from the model's structure (`structural_lag`) or from the scores' own autocorrelation
(`_dependence`). Checked against moving-average series, whose long-run variance is known
in closed form. `compare_fits` takes a nested pair's statistic as at least 0 (`_nested`).
"""

import math
import types

import numpy as np
import pytest

import stickslip as ss
from stickslip._inference import compare, intervals
from stickslip._inference.diagnostics import FitDiagnostics

BASE = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, tau=0.1)


def _ma(theta, n, rng, p=1):
    """A moving average g_t = e_t + theta_1 e_{t-1} + ...: lag-L dependent scores."""
    theta = np.atleast_1d(theta)
    e = rng.standard_normal(n + theta.size)
    g = e[theta.size :].copy()
    for j, th in enumerate(theta, start=1):
        g += th * e[theta.size - j : n + theta.size - j]
    return g


def test_the_meat_of_lag_dependent_scores_is_their_long_run_variance():
    """For g_t = e_t + theta e_{t-1} the long-run variance is (1 + theta)^2 (closed form),
    against 1 + theta^2 that independent rows would assume; the mean of 60 estimates of
    n = 3000 within 4 of their own standard errors of it."""
    rng = np.random.default_rng(20261205)
    theta, n = 0.6, 3000
    lag1, lag0 = [], []
    for _ in range(60):
        G = (_ma(theta, n, rng) - 0.0)[:, None]
        G2 = G + 0.3 * rng.standard_normal(G.shape)  # a second seed's noise, independent
        lag1.append(float(intervals._meat(G, G2, 1)[0, 0]) / n)
        lag0.append(float(intervals._meat(G, G2, 0)[0, 0]) / n)
    for got, want in ((lag1, (1 + theta) ** 2), (lag0, 1 + theta**2)):
        se = np.std(got, ddof=1) / math.sqrt(len(got))
        assert abs(np.mean(got) - want) < 4 * se, (np.mean(got), want, se)


def test_the_scores_say_how_far_the_dependence_reaches():
    """An MA(2) series is found dependent to lag 2 (its lag-1 and lag-2 autocorrelations,
    0.52 and 0.21, against a band of 3/sqrt(n) = 0.04); independent rows to none."""
    rng = np.random.default_rng(7)
    n = 6000
    dependent = np.c_[_ma([0.6, 0.3], n, rng), rng.standard_normal(n)]
    found = intervals._dependence(dependent, None, ["a", "b"], 0)
    assert found["lag"] == 2 and found["from_scores"]
    want = [(0.6 + 0.6 * 0.3) / (1 + 0.36 + 0.09), 0.3 / (1 + 0.36 + 0.09)]
    assert np.allclose(found["acf"]["a"][:2], want, atol=4 / math.sqrt(n))
    independent = intervals._dependence(rng.standard_normal((n, 2)), None, ["a", "b"], 0)
    assert independent["lag"] == 0
    # the structural lag is kept even where the scores do not show it
    assert intervals._dependence(rng.standard_normal((n, 2)), None, ["a", "b"], 1)["lag"] == 1


def test_the_structural_lag_follows_the_onset():
    """A random onset position (a random threshold) couples a row with the next; a fixed
    one does not (sd 0 is the fixed threshold); a model with memory leaves it to the
    scores."""
    RT = ss.get_model("random-threshold")
    assert intervals.structural_lag(ss.get_model("langevin")(**BASE, x0=1.0)) == 0
    random = RT(**BASE, threshold="normal", threshold_params={"mean": 1.0, "sd": 0.3})
    fixed = RT(**BASE, threshold="normal", threshold_params={"mean": 1.0, "sd": 0.0})
    assert intervals.structural_lag(random) == 1
    assert intervals.structural_lag(fixed) == 0

    class Remembers:  # a model that carries state across cycles: no probe, the scores
        carries_state = True

    assert intervals.structural_lag(Remembers()) is None


def _candidate(name, model, box, n_free):
    result = types.SimpleNamespace(model=model, diagnostics=FitDiagnostics(box=box))
    return types.SimpleNamespace(name=name, result=result, n_free=n_free, units=(None,))


def test_nesting_is_read_from_the_models_and_the_boxes():
    L = ss.get_model("langevin")(**BASE, x0=1.1)
    RT = ss.get_model("random-threshold")
    rt = RT(**BASE, threshold="normal", threshold_params={"mean": 1.0, "sd": 0.2})
    fixed = _candidate("fixed", L, {"x0": (0.5, 2.0), "D": (0.1, 2.0)}, 2)
    wide = {"threshold_params.mean": (0.5, 2.0), "threshold_params.sd": (0.0, 1.0),
            "D": (0.1, 2.0)}  # fmt: skip
    assert compare._nested(fixed, _candidate("random", rt, wide, 3))
    # a box of sd that does not reach 0 does not hold the fixed threshold
    narrow = {**wide, "threshold_params.sd": (0.05, 1.0)}
    assert not compare._nested(fixed, _candidate("random", rt, narrow, 3))
    # a parameter fixed at another value: not nested
    other = RT(**{**BASE, "zeta": 0.2}, threshold="normal",
               threshold_params={"mean": 1.0, "sd": 0.2})  # fmt: skip
    assert not compare._nested(fixed, _candidate("random", other, wide, 3))
    # the same class, a subset of the free parameters whose fixed value lies in the box
    only_x0 = _candidate("x0", ss.get_model("langevin")(**BASE, x0=1.2), {"x0": (0.5, 2.0)}, 1)
    assert compare._nested(only_x0, fixed)
    assert not compare._nested(only_x0, _candidate("fixed", L, {"x0": (0.5, 2.0),
                                                               "D": (0.5, 2.0)}, 2))  # fmt: skip
    # no box recorded (a fit from an earlier version): not taken as nested
    assert not compare._nested(fixed, _candidate("random", rt, None, 3))


def test_a_nested_pair_never_scores_below_zero():
    """The richer fit's surface below the nested one's (by 15 log-likelihood units, as a
    fit that missed its maximum gives): the statistic is 0, not -30, for the data and the
    replicates alike, and the comparison says why."""
    L = ss.get_model("langevin")(**BASE, x0=1.0)
    rt = ss.get_model("random-threshold")(**BASE, threshold="normal",
                                          threshold_params={"mean": 1.0, "sd": 0.1})  # fmt: skip
    n, n_boot = 20, 9
    rng = np.random.default_rng(3)
    low = rng.normal(0.0, 1.0, n_boot + 1)

    def cand(name, model, box, shift):
        c = _candidate(name, model, box, len(box))
        c.setting = None
        c.parts, c.columns = (None,), ({"slip_time": np.ones(n)},)  # one data set
        c.design = lambda: ([], np.zeros((0, 1)), [[], []])
        c.best = lambda design, pooled, n_sets, which: low + shift
        return c

    a = cand("fixed", L, {"x0": (0.5, 2.0)}, 0.0)
    b = cand("random", rt, {"threshold_params.mean": (0.5, 2.0),
                            "threshold_params.sd": (0.0, 1.0)}, -15.0)  # fmt: skip
    reps = compare.Replicates(fit=(), n_boot=n_boot, seed=0,
                              sets=({"slip_time": np.ones(n * n_boot)},))  # fmt: skip
    t = compare._test(a, b, reps, {})
    assert t["nested"] and t["raw_statistic"] == [-30.0, -30.0]
    assert t["statistic"] == [0.0, 0.0] and t["p_value"] == 1.0
    # not nested (the box of sd away from 0): the statistic as it came
    b_far = cand("random", rt, {"threshold_params.mean": (0.5, 2.0),
                                "threshold_params.sd": (0.05, 1.0)}, -15.0)  # fmt: skip
    t = compare._test(a, b_far, reps, {})
    assert not t["nested"] and t["statistic"] == pytest.approx([-30.0, -30.0])


def test_newey_west_meat_of_a_chain_against_its_closed_form():
    """A chain's meat: Bartlett's weights 1 - l/(L+1) over L lags. For MA(1) scores
    e_t + theta e_{t-1} (unit innovations) its expected value per row is, in closed form,
    (1 + theta^2) + 2 (1 - 1/(L+1)) theta; the lag is Newey and West's rule."""
    lags = [intervals.newey_west_lag(n) for n in (100, 180, 272, 273, 620, 621)]
    assert lags == [4, 4, 4, 5, 5, 6]  # floor(4 (n/100)^(2/9))
    rng = np.random.default_rng(5)
    theta, n, L = 0.5, 200_000, 4
    g = _ma(theta, n, rng)[:, None]
    g = g - g.mean()
    got = float(intervals._meat(g, g, L, bartlett=True)[0, 0]) / n
    want = (1 + theta**2) + 2 * (1 - 1 / (L + 1)) * theta
    # sampling sd of a lag-4 Bartlett long-run variance: sqrt(2 (2L+1) / n) times it, ~0.02
    sd = math.sqrt(2 * (2 * L + 1) / n) * want
    assert abs(got - want) < 4 * sd


def test_a_chain_takes_newey_wests_lags_however_small_its_autocorrelation():
    """A model with memory (structural lag unknown): the meat's lag is Newey and West's,
    with Bartlett's weights, even where no single lag passes the significance band."""
    rng = np.random.default_rng(6)
    n = 180
    G = rng.standard_normal((n, 2))
    dep = intervals._dependence(G, None, ["a", "b"], None)
    assert dep["lag"] == intervals.newey_west_lag(n) == 4 and dep["bartlett"]
    assert not intervals._dependence(G, None, ["a", "b"], 1)["bartlett"]
