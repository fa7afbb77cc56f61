"""What a study compares: the quantities it knows, the densities of the theory (cell
averages on the output grids) and of the simulation (histograms with their standard
errors), and the L1 distance between them. `run` computes the points of a study; `dataset`
assembles them; both use this module."""

from __future__ import annotations

import contextlib
import dataclasses
import math
import pathlib
import threading
import time
import warnings
from typing import Any

import numpy as np

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
    with _recorded() as caught:
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


# `_recorded` sorts warnings by thread through `warnings`' private display hook (CPython
# 3.11-3.13 have it). Where a Python lacks it, a capture is a plain `catch_warnings` and a
# study computes its theory after its simulations, not beside them (`run._theory_ahead`):
# the same numbers and notes, only later.
_HOOKS = ("_showwarnmsg_impl", "_filters_mutated", "_showwarning_orig")
PER_THREAD = all(hasattr(warnings, name) for name in _HOOKS)
# the warnings caught per thread, and what the first capture replaced
_SHOW = getattr(warnings, "_showwarnmsg_impl", None)
_capture_lock = threading.Lock()
_captured: dict[int, list] = {}
_replaced: list = []


def _dispatch(message) -> None:
    """`warnings`' display hook while a capture is open: a capturing thread's warnings go
    to its list, the others' are shown as before."""
    caught = _captured.get(threading.get_ident())
    if caught is not None:
        caught.append(message)
        return
    if not _replaced:  # (left installed by a `catch_warnings` entered during a capture)
        _SHOW(message)
        return
    filters, impl, show = _replaced[0]
    action = _action(message, filters)
    if action == "ignore":
        return
    if action == "error":
        raise message.message
    if show is not warnings._showwarning_orig:  # (a hook of the user's, as `warnings` calls it)
        m = message
        show(m.message, m.category, m.filename, m.lineno, m.file, m.line)
    else:
        impl(message)


def _action(message, filters) -> str:
    """What `filters` (the ones a capture replaced) do with another thread's warning: the
    first that matches its text, category, module (read off its file name) and line.
    ("default" and "once" show it each time: the registries of shown warnings are not
    kept for these few warnings of a capture's time.)"""
    text = str(message.message)
    module = pathlib.Path(message.filename or "").stem
    for action, msg, category, mod, lineno in filters:
        if (
            (msg is None or msg.match(text))
            and issubclass(message.category, category)
            and (mod is None or mod.match(module))
            and (not lineno or lineno == message.lineno)
        ):
            return action
    return warnings.defaultaction


@contextlib.contextmanager
def _recorded():
    """`warnings.catch_warnings(record=True)` with every warning recorded ("always"), for
    this thread's warnings only: the theory of a point is computed in a thread while the
    simulations run (`run._theory_ahead`), and `catch_warnings` would record their
    warnings too, and, entered from two threads, restore the wrong filters. (Without the
    hook, `PER_THREAD` false: `catch_warnings` itself; no theory thread runs then.)"""
    if not PER_THREAD:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield caught
        return
    caught: list = []
    with _capture_lock:
        if not _replaced:
            _replaced.append(
                (warnings.filters[:], warnings._showwarnmsg_impl, warnings.showwarning)
            )
            warnings.filters.insert(0, ("always", None, Warning, None, 0))
            warnings._filters_mutated()
            warnings._showwarnmsg_impl = _dispatch
            warnings.showwarning = warnings._showwarning_orig
        outer = _captured.get(threading.get_ident())  # (a capture inside a capture)
        _captured[threading.get_ident()] = caught
    try:
        yield caught
    finally:
        with _capture_lock:
            if outer is not None:
                _captured[threading.get_ident()] = outer
            else:
                del _captured[threading.get_ident()]
            if not _captured:
                filters, impl, show = _replaced.pop()
                warnings.filters[:] = filters
                warnings._filters_mutated()
                warnings._showwarnmsg_impl, warnings.showwarning = impl, show


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
