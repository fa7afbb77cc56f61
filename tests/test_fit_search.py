"""Where `fit`'s search starts: from three free parameters on, Nelder-Mead runs from up to
three of the coarse grid's best points, a quarter of the box apart, and the best run is
kept; with one or two, from the best point alone."""

import numpy as np

from stickslip._inference import surface


def test_starts_are_the_best_points_far_enough_apart():
    lo, hi = np.zeros(3), np.ones(3)
    points = np.array([[0.5, 0.5, 0.5], [0.55, 0.5, 0.5], [0.9, 0.1, 0.5], [0.1, 0.9, 0.9],
                       [0.2, 0.2, 0.2]])  # fmt: skip
    values = np.array([-10.0, -10.5, -12.0, -13.0, np.nan])
    starts = surface._starts(points, values, lo, hi)
    # the second best lies 0.05 from the best: skipped for the next ones apart
    assert [p.tolist() for p in starts] == [points[0].tolist(), points[2].tolist(),
                                            points[3].tolist()]  # fmt: skip
    assert len(surface._starts(points[:, :2], values, lo[:2], hi[:2])) == 1


def test_the_best_run_wins_on_a_surface_with_two_maxima(monkeypatch):
    """A broad, lower maximum (a ridge) holding the grid's best point and a narrow, higher
    one off the grid: Nelder-Mead from the best grid point ends on the ridge, the runs from
    three starts find the higher maximum."""
    lo, hi = np.zeros(3), np.ones(3)
    ridge_at = np.array([0.15, 0.85, 0.5])
    peak_at = np.clip(surface._design(lo, hi)[0] + 0.1, 0.02, 0.98)

    def loglik(u):
        ridge = -3.0 * np.sum((u - ridge_at) ** 2)
        peak = -30.0 * np.sum((u - peak_at) ** 2) + 0.5
        return max(ridge, peak), None

    free = {"a": 0, "b": 0, "c": 0}
    u, record, _ = surface.search(loglik, lo, hi, free)
    assert record["starts"] == 3
    assert np.allclose(u, peak_at, atol=0.03), u
    monkeypatch.setattr(surface, "STARTS", 1)
    one, record, _ = surface.search(loglik, lo, hi, free)
    assert record["starts"] == 1 and np.allclose(one, ridge_at, atol=0.03), one
