"""What a study compares: the quantities it knows, the densities of the theory (cell
averages on the output grids) and of the simulation (histograms with their standard
errors), and the L1 distance between them. `run` computes the points of a study; `dataset`
assembles them; both use this module."""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np

from .._notes import collecting_notes
from .schema import Study

# A random onset's quadrature error (L1, nodes doubled) above this is reported.
QUADRATURE_TOL = 1e-3
THEORY_DENSITIES = ("slip_time", "period", "slip_distance")  # stick_time: simulation only
EVENTS = ("event_size", "event_duration", "event_interval")


@dataclasses.dataclass
class Point:
    """Everything computed for one point of a study."""

    study: Study
    values: dict[str, Any]
    ensemble: Any = None
    cycles: Any = None
    chain: Any = None
    exact: Any = None
    empirical: Any = None
    choices: dict = dataclasses.field(default_factory=dict)
    timings: dict[str, float] = dataclasses.field(default_factory=dict)
    warnings: list[str] = dataclasses.field(default_factory=list)
    done: bool = False  # computed (here or on a Dask worker)
    # `theory_density`'s results computed ahead (`run._theory_ahead`), by (key, q, edges)
    theory: dict = dataclasses.field(default_factory=dict, repr=False)


def estimator_source(study: Study, analytic) -> str:
    """Which estimator an approximation uses: `"exact"` (linear-Gaussian models, by default)
    or `"empirical"` (from the simulated upcrossings)."""
    if analytic.source != "auto":
        return analytic.source
    return "exact" if study.model.instance.linear_gaussian() is not None else "empirical"


def theory_density(point: Point, analytic, q: str, edges: np.ndarray):
    """One approximation of one density on cell centres; `(values, seconds, warnings)`."""
    ahead = point.theory.pop((analytic.key, q, np.asarray(edges).tobytes()), None)
    if ahead is not None:
        return ahead
    est = point.exact if estimator_source(point.study, analytic) == "exact" else point.empirical
    centres = 0.5 * (edges[1:] + edges[:-1])
    t0 = time.perf_counter()
    with collecting_notes() as caught:  # (this thread's: the theory may run beside the
        # simulations, `run._theory_ahead`)
        args = (analytic.method, analytic.order, analytic.normalized)
        if q == "slip_time":
            values = est.first_passage_cells(edges, *args)
        elif q == "period":
            values = est.period_density(centres, *args)
        else:
            values = est.slip_distance_density(centres, *args)
    notes = [f"{analytic.key} {q}: {w.message}" for w in caught]
    if est is point.exact and est.n_components > 1:
        # A random onset is mixed by quadrature: its error, estimated with the nodes doubled.
        error = est.quadrature_error(q, edges if q == "slip_time" else centres, *args)
        if error > QUADRATURE_TOL:
            notes.append(
                f"{analytic.key} {q}: the onset quadrature ({est.quadrature_nodes} nodes) moves "
                f"the density by L1 {error:.2g} when its nodes are doubled"
            )
    seconds = time.perf_counter() - t0
    return np.asarray(values, float), seconds, notes


def cell_average_2d(f, edges, k: int = 2):
    """Cell averages of f(t1, t2) on a square grid (k x k midpoint rule per cell)."""
    u = (np.arange(k) + 0.5) / k
    x = (edges[:-1, None] + np.diff(edges)[:, None] * u[None, :]).ravel()
    n = edges.size - 1
    values = np.asarray(f(x, x), float).reshape(n, k, n, k)
    return values.mean(axis=(1, 3))


def mc_density(point: Point, q: str, edges: np.ndarray):
    """Histogram of the simulated slips of non-zero length, normalised by all paths (so it
    compares with the theory's continuous part), and its standard errors."""
    value, se, _ = point.ensemble.histogram(q, edges, immediate=False)
    return value, se


def mc_n1(point: Point, edges: np.ndarray):
    """Upcrossing density from the recorded upcrossings (`nan` beyond `t_complete`)."""
    up = point.ensemble.upcrossings
    t = up.times[~up.immediate]
    counts, _ = np.histogram(t[np.isfinite(t)], bins=edges)
    n = up.n_paths
    width = np.diff(edges)
    value, se = counts / (n * width), np.sqrt(counts) / (n * width)
    beyond = edges[1:] > up.t_complete
    value[beyond] = np.nan
    se[beyond] = np.nan
    return value, se


def mc_n2(point: Point, edges: np.ndarray):
    """Joint density of two upcrossings at t1 != t2 (ordered pairs of recorded upcrossings)."""
    up = point.ensemble.upcrossings
    t = up.times[~up.immediate]
    k = t.shape[1]
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    off = i != j
    a, b = t[:, i[off]].ravel(), t[:, j[off]].ravel()
    ok = np.isfinite(a) & np.isfinite(b)
    counts, _, _ = np.histogram2d(a[ok], b[ok], bins=[edges, edges])
    width = np.diff(edges)
    value = counts / (up.n_paths * width[:, None] * width[None, :])
    beyond = edges[1:] > up.t_complete
    value[beyond, :] = np.nan
    value[:, beyond] = np.nan
    return value


def l1(theory, mc, edges) -> float:
    """L1 distance on the cells where both are defined."""
    ok = np.isfinite(theory) & np.isfinite(mc)
    return float(np.sum(np.abs(theory - mc)[ok] * np.diff(edges)[ok]))


def l1_floor(se, edges) -> float:
    """Expected L1 of the histogram's own sampling noise, sum sqrt(2/pi) se dx: an L1 below
    it cannot be told from zero."""
    ok = np.isfinite(se)
    return float(math.sqrt(2 / math.pi) * np.sum(se[ok] * np.diff(edges)[ok]))
