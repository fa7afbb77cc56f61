"""The fast histogram counts against NumPy's own `np.histogram` (an independent
implementation: it sorts the values and searches the edges)."""

import dataclasses

import numpy as np
import pytest

from stickslip._histogram import counts


@pytest.mark.parametrize(
    "lo, hi, n", [(0.0, 12.5, 150), (0.0, 1.0, 1), (-3.7, 41.3, 97), (1e-3, 2e-3, 64)]
)
def test_counts_match_numpy_on_equal_cells(lo, hi, n):
    rng = np.random.default_rng(n)
    edges = np.linspace(lo, hi, n + 1)
    span = hi - lo
    values = np.concatenate([
        rng.uniform(lo - 0.1 * span, hi + 0.1 * span, 20000),  # some outside
        edges,  # every edge exactly
        np.nextafter(edges, np.inf), np.nextafter(edges, -np.inf),  # one ulp either side
        [np.nan, np.inf, -np.inf],
    ])  # fmt: skip
    expected = np.histogram(values[np.isfinite(values)], bins=edges)[0]
    got = counts(values, edges)
    np.testing.assert_array_equal(got, expected)
    assert got.dtype == expected.dtype


def test_unequal_cells_and_few_values_fall_back_to_numpy():
    rng = np.random.default_rng(1)
    values = rng.lognormal(size=5000)
    edges = np.geomspace(0.05, 20.0, 31)  # unequal cells
    np.testing.assert_array_equal(counts(values, edges), np.histogram(values, bins=edges)[0])
    np.testing.assert_array_equal(counts([], np.linspace(0, 1, 5)), np.zeros(4, int))


def test_an_ensembles_histogram_with_and_without_immediate_sticks():
    """`Ensemble.histogram` over every stuck path, or without those that stuck at once: a
    density of all paths whose mass over edges spanning every value is the fraction of
    paths it counts, and NumPy's counts over the same paths."""
    import stickslip as ss

    model = ss.get_model("langevin")(omega0=1.0, zeta=0.1, v_b=1.0, x0=1.0, D=0.4, tau=0.1)
    ens = ss.simulate(model, 2000, 0.2, 200.0, seed=3, progress=False)
    # (coloured noise sticks at once on no path: a random tenth flagged so, for the count)
    flag = np.random.default_rng(4).random(ens.n_paths) < 0.1
    ens = dataclasses.replace(ens, immediate=flag)
    x = np.asarray(ens.slip_time)
    edges = np.linspace(0.0, np.nanmax(x[ens.stuck]) * 1.001, 41)
    for immediate, counted in ((True, ens.stuck), (False, ens.stuck & ~ens.immediate)):
        value, se, got = ens.histogram("slip_time", edges, immediate=immediate)
        np.testing.assert_array_equal(got, edges)
        assert np.sum(value * np.diff(edges)) == pytest.approx(np.mean(counted), rel=1e-12)
        n = np.histogram(x[counted], bins=edges)[0]
        np.testing.assert_allclose(value, n / ens.n_paths / np.diff(edges), rtol=1e-12)
        p = n / ens.n_paths
        np.testing.assert_allclose(se, np.sqrt(p * (1 - p) / ens.n_paths) / np.diff(edges))
