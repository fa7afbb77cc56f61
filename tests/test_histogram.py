"""The fast histogram counts against NumPy's own `np.histogram` (an independent
implementation: it sorts the values and searches the edges)."""

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
