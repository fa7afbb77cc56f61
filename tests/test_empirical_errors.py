"""Sampling errors of the empirical (simulated-upcrossing) estimator against the spread of
independent replicate ensembles, and their way into a study's dataset and figures."""

import math
import warnings

import numpy as np
import pytest
from scipy import stats

import stickslip as ss

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
MIN_COUNT = 10  # cells with fewer upcrossings per replicate: a normal band is too narrow there


def _replicates(Langevin, R, n_paths, h, seed0):
    """R independent ensembles (seeds seed0, seed0 + 1, ...; fixed before looking): per
    quantity, the estimates (R, cells) and their reported standard errors."""
    model = Langevin(**PUBLIC)
    edges = np.arange(0.0, 8.0 + 1e-9, h)
    t = 0.5 * (edges[1:] + edges[:-1])
    quantities = {
        "n1": lambda e, se: (e.n1_se if se else e.n1)(t),
        "n2_integral": lambda e, se: (e.n2_integral_se if se else e.n2_integral)(t),
        "Fg1_cells": lambda e, se: (e.first_passage_cells_se if se else e.first_passage_cells)(
            edges, "decoupling", 1
        ),
        "Fg2": lambda e, se: (e.first_passage_se if se else e.first_passage)(t, "decoupling", 2),
    }
    out = {k: ([], []) for k in quantities}
    for r in range(R):
        ens = ss.simulate(model, n_paths, 0.01, 8.0, seed=seed0 + r, record_upcrossings=12)
        est = ss.CrossingEstimator(model, ensemble=ens, dt=h)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ss.ApproximationWarning)
            for k, f in quantities.items():
                out[k][0].append(f(est, False))
                out[k][1].append(f(est, True))
    values = {k: (np.array(v), np.array(s)) for k, (v, s) in out.items()}
    # cells by their mean upcrossing count per replicate (independent of the errors)
    counts = values["n1"][0].mean(axis=0) * n_paths * h
    return values, counts >= MIN_COUNT, est.error_groups


def _variance_ratio(v, s):
    """Q = sum over cells of the replicate variance / sum of the mean reported se^2 (both
    unbiased for the variance of an estimate), and its standard error by a jackknife over
    the replicates (which holds for cells correlated through a common integral)."""
    R = v.shape[0]

    def q(keep):
        return v[keep].var(axis=0, ddof=1).sum() / (s[keep] ** 2).mean(axis=0).sum()

    full = q(np.ones(R, bool))
    loo = np.array([q(np.arange(R) != r) for r in range(R)])
    return full, math.sqrt((R - 1) / R * np.sum((loo - loo.mean()) ** 2))


def _coverage(v, s, groups):
    """Share of replicate values inside their own 95 % band (+- t_{0.975, B-1} se) around
    the mean of the other replicates (whose own error widens the band by sqrt(1 + 1/(R-1))),
    and its standard error (binomial, or from the replicates' shares if larger)."""
    R = v.shape[0]
    others = (v.sum(axis=0)[None] - v) / (R - 1)
    factor = stats.t.ppf(0.975, groups - 1) * math.sqrt(1 + 1 / (R - 1))
    inside = np.abs(v - others) <= factor * s
    share = inside.mean()
    binomial = math.sqrt(0.95 * 0.05 / inside.size)
    per_replicate = inside.mean(axis=1).std(ddof=1) / math.sqrt(R)
    return share, max(binomial, per_replicate)


def _check(values, cells, groups, name):
    v, s = values[name]
    v, s = v[:, cells], s[:, cells]
    Q, se_Q = _variance_ratio(v, s)
    share, se_share = _coverage(v, s, groups)
    print(
        f"{name}: mean se / replicate sd = {1 / math.sqrt(Q):.3f} (Q = {Q:.3f} +- {se_Q:.3f}), "
        f"95 % band coverage {share:.3f} +- {se_share:.3f} over {v.size} values"
    )
    assert abs(Q - 1) < 4 * se_Q
    assert abs(share - 0.95) < 4 * se_share


QUANTITIES = ["n1", "n2_integral", "Fg1_cells", "Fg2"]


@pytest.fixture(scope="module")
def replicates(Langevin):
    """20 ensembles of 1000 paths, cells of 0.2."""
    return _replicates(Langevin, 20, 1000, 0.2, seed0=1000)


@pytest.mark.parametrize("name", QUANTITIES)
def test_standard_errors_match_replicate_spread(replicates, name):
    values, cells, groups = replicates
    assert cells.sum() >= 20
    _check(values, cells, groups, name)


@pytest.mark.slow
@pytest.mark.parametrize("name", QUANTITIES)
def test_standard_errors_match_replicate_spread_full(Langevin, name):
    """40 ensembles of 4000 paths, cells of 0.1."""
    values, cells, groups = _replicates(Langevin, 40, 4000, 0.1, seed0=2000)
    _check(values, cells, groups, name)


def test_jackknife_of_n1_is_batch_means(Langevin):
    """n1 is linear in the paths: its jackknife error equals the batch-means error over the
    same groups (path i in group i mod B), computed here from the recorded times directly."""
    model = Langevin(**PUBLIC)
    ens = ss.simulate(model, 1000, 0.01, 8.0, seed=7, record_upcrossings=12)
    h, B = 0.2, 20
    est = ss.CrossingEstimator(model, ensemble=ens, dt=h, error_groups=B)
    assert est.error_groups == B
    up = ens.upcrossings
    t = np.arange(1, 40) * h  # grid times: n1 there is the count in [t - h/2, t + h/2)
    edges = np.append(t - h / 2, t[-1] + h / 2)
    group = np.arange(up.n_paths) % B
    means = []
    for b in range(B):
        mine = (group == b) & ~up.immediate
        times = up.times[mine]
        counts = np.histogram(times[np.isfinite(times)], bins=edges)[0]
        means.append(counts / (np.sum(group == b) * h))
    means = np.array(means)
    batch = means.std(axis=0, ddof=1) / math.sqrt(B)
    np.testing.assert_allclose(est.n1_se(t), batch, rtol=1e-9, atol=1e-12)


def test_exact_sources_have_no_sampling_error(Langevin):
    """The exact formulas report zero errors."""
    est = ss.CrossingEstimator(Langevin(**PUBLIC), dt=0.05)
    assert est.error_groups == 0
    t = np.array([0.5, 3.0, 6.0])
    np.testing.assert_array_equal(est.n1_se(t), 0.0)
    np.testing.assert_array_equal(est.first_passage_se(t), 0.0)


@pytest.mark.slow  # n2 on 3001 lags, twice: ~15 s from an empty cache
def test_exact_n2_integral_is_the_integral_of_n2(Langevin):
    """The exact source's n2_integral against the trapezoid rule on a fine row of n2."""
    est = ss.CrossingEstimator(Langevin(**PUBLIC), dt=0.05)
    for tt in (3.0, 6.0):
        s = np.linspace(0.0, tt, 3001)
        row = est.n2(np.array([tt]), s)[0]
        assert est.n2_integral(tt) == pytest.approx(np.trapezoid(row, s), rel=1e-4)


def test_study_carries_and_draws_the_band(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from stickslip.study import plots
    from stickslip.study.schema import Study

    spec = {
        "title": "band",
        "model": {"name": "langevin", "params": dict(PUBLIC)},
        "simulation": {"n_paths": 1000, "dt": 0.01, "t_max": 12.0, "seed": 3},
        "analytic": [
            {"method": "decoupling", "order": 1},
            {"method": "decoupling", "order": 1, "source": "empirical"},
        ],
        "outputs": ["slip_time"],
        "grid": {"slip_time": {"start": 0, "stop": 10, "bins": 40}},
    }
    ds = ss.run_study(spec, tmp_path / "out", progress=False)
    se = ds["theory_slip_time_se"].values
    assert np.isnan(se[0]).all()  # exact: no band
    assert np.isfinite(se[1]).all() and se[1].max() > 0
    groups = ds["theory_slip_time_se"].attrs["error_groups"]
    assert groups == 20
    assert ds["theory_slip_time_se"].attrs["band_factor"] == pytest.approx(
        stats.t.ppf(0.975, groups - 1)
    )
    assert (tmp_path / "out" / "slip_time.png").exists()
    study = Study.model_validate(spec)
    fig = plots._density(plt, ds, study, "slip_time", study.model.instance)
    bands = [c for a in fig.axes for c in a.collections if isinstance(c, PolyCollection)]
    assert len(bands) == len(fig.axes)  # the empirical method's band, in every panel
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert sum("sampling band" in label for label in labels) == 1
    plt.close(fig)
