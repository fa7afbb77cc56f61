"""Running a study: simulation, theory and their comparison, gathered in one xarray Dataset.

`run_study` is what `stickslip run` calls. For each point of the study (one, or one per
sweep value) it simulates the model, evaluates every requested level-crossing
approximation, and histograms the simulation on grids shared with the theory; then it
assembles an `xarray.Dataset` and, given `out`, writes it with the figures and a summary.
The simulator is asked only for what the outputs need (upcrossings only for `n1`, `n2` or an
empirical estimate; successive cycles only for time series and phase portraits).
"""

from __future__ import annotations

import os
import pathlib
import time

import numpy as np

from .load import StudyError, load_study
from .measure import EVENTS, Point, estimator_source
from .schema import DENSITIES, Study


class _Progress:
    """Stage messages on stderr (one line each) unless quiet."""

    def __init__(self, enabled: bool):
        self.enabled = enabled

    def __call__(self, text: str):
        if self.enabled:
            import sys

            print(text, file=sys.stderr, flush=True)


def run_study(
    study: Study | str | os.PathLike | dict,
    out: str | os.PathLike | None = None,
    *,
    overrides=None,
    force: bool = False,
    progress: bool | str | None = None,
    figures: bool = True,
    client=None,
):
    """Run a study and return its results as an `xarray.Dataset`.

    **Arguments:**

    - `study`: a `Study`, a path to a YAML study, or the study as a dict.
    - `out`: directory to write `results.nc`, the figures (PNG) and `summary.md` to; None
      writes nothing. It may not be, or hold, the study file, nor be the current directory
      or one above it. An existing non-empty directory is replaced only with `force=True`,
      only if it is an earlier results folder (it holds the marker `.stickslip-results`),
      and only once everything is written: the files are made in a temporary directory
      beside it and moved into place at the end, so a run stopped midway leaves no
      half-written file under a final name.
    - `overrides`: `["key=value", ...]` applied to the study first (dotted keys, YAML values).
    - `progress`: progress messages and bars on stderr (default: when stderr is a terminal);
      `"lines"`: the messages alone, a line per stage or sweep point (for a log file).
    - `figures`: write the figures (with `out`).
    - `client`: a Dask cluster to run on (a `dask.distributed.Client`, a scheduler address or
      `"local"`): the points of a sweep run as tasks, a single point's simulations as blocks
      of paths. The Dataset is the one a local run writes (docs/distributed.md).

    **Raises:** `StudyError` for an invalid study, `OutputError` for an output directory
    that may not be written (both before any work).
    """
    import sys

    inputs = [study] if isinstance(study, (str, os.PathLike)) else []
    study = load_study(study, overrides)
    out_dir = None if out is None else check_out(out, force, inputs)
    # Bars on a terminal; elsewhere (a log file, a batch job's output) `"lines"` gives the
    # stage messages alone, one line each, which a file keeps readable.
    say = _Progress(
        progress is True or progress == "lines" or progress is None and sys.stderr.isatty()
    )
    progress = progress is True or progress is None and sys.stderr.isatty()
    points = [Point(s, values) for values, s in study.points()]
    from .. import _distributed

    with _distributed.connected("run_study", client) as client:
        if study.method == "auto":
            _choose(points[0], say)
            study = points[0].study
        if client is not None and len(points) > 1:
            points = _compute_on(client, points, progress, say)
        for i, point in enumerate(points):
            if point.done:
                continue
            label = ", ".join(f"{k}={v!r}" for k, v in point.values.items())
            if label:
                say(f"[{i + 1}/{len(points)}] {label}")
            _compute(point, progress, say, client, grid_of=study)
    t0 = time.perf_counter()
    grids = _grids(study, points)
    from .dataset import assemble

    ds = assemble(study, points, grids, progress=progress)
    ds.attrs["seconds_theory_densities"] = time.perf_counter() - t0
    if out_dir is not None:
        from .write import write_results

        write_results(ds, study, out_dir, force=force, figures=figures, say=say)
    return ds


def _choose(point: Point, say):
    """method: auto: choose per requested density, then run one simulation (the most
    demanding Monte Carlo choice) and/or the chosen level-crossing approximations."""
    from ..selection import SelectionError, select_method
    from .schema import Analytic

    s = point.study
    sim = (
        s.simulation
        if s.simulation is not None
        else type(s).model_fields["simulation"].default_factory()
    )
    model = s.model.instance
    choices = {}
    for q in s.resolved_outputs():
        try:
            choices[q] = select_method(model, s.tolerance, q, t_max=sim.t_max, seed=sim.seed)
        except SelectionError as err:
            raise StudyError(None, "tolerance", str(err).removeprefix("select_method: ")) from None
        say(f"method: auto ({q}): {choices[q].reason.splitlines()[0]}")
        if not choices[q].promised:
            point.warnings.append(f"method: auto ({q}): {choices[q].reason.splitlines()[0]}")
    mc = [c for c in choices.values() if c.kind == "simulation"]
    analytic = []
    for c in choices.values():
        if c.kind == "analytic":
            a = Analytic(**c.settings)
            if a.key not in [b.key for b in analytic]:
                analytic.append(a)
    update = dict(method="compare", tolerance=None, analytic=analytic)
    if mc:
        update["simulation"] = sim.model_copy(update=_common_run(mc, s.tolerance))
    else:
        update["simulation"] = None
    point.study = s.model_copy(update=update)
    point.choices = choices


def _common_run(mc, tolerance) -> dict:
    """One Monte Carlo run for every density that chose Monte Carlo: the cheapest run that
    meets the tolerance on all of them (else the most demanding of their choices)."""

    def meets(choice, settings):
        return any(
            o.kind == "simulation" and o.rejected is None and o.settings == settings
            and o.error <= tolerance
            for o in choice.candidates
        )  # fmt: skip

    common = [
        o
        for o in mc[0].candidates
        if o.kind == "simulation" and all(meets(c, o.settings) for c in mc)
    ]
    if common:
        return dict(min(common, key=lambda o: o.seconds).settings)
    return max(mc, key=lambda c: c.chosen.seconds).settings


def check_out(out, force: bool, inputs=()) -> pathlib.Path:
    """The output folder, checked before any work (`stickslip._output.check_output_dir`)."""
    from .._output import check_output_dir

    return check_output_dir(out, inputs=inputs, force=force, what="--out")


# -- simulation and estimators -----------------------------------------------------------
def _compute_on(client, points: list[Point], progress: bool, say) -> list[Point]:
    """The points of a sweep, each computed as a task on the cluster, in order."""
    from .._distributed import run_tasks

    say(f"{len(points)} points on the Dask cluster at {client.scheduler.address}")
    finished = []

    def done(i):
        finished.append(i)
        label = ", ".join(f"{k}={v!r}" for k, v in points[i].values.items())
        say(f"[{len(finished)}/{len(points)}] done: {label}")

    return run_tasks(client, _compute_task, [(p,) for p in points], done)


def _compute_task(point: Point) -> Point:
    """One point of a sweep, computed on a worker (quietly)."""
    _compute(point, False, lambda text: None)
    return point


def _compute(point: Point, progress: bool, say, client=None, grid_of: Study | None = None):
    """Simulate one point and set up its estimators; `grid_of`: the study whose grids the
    results use (`run_study`'s), to compute the theory on them while the point simulates
    (`_theory_ahead`)."""
    from .._model import ChainModel

    point.done = True
    s = point.study
    model = s.model.instance
    if isinstance(model, ChainModel):
        _compute_chain(point, say, client)
        return
    import stickslip as ss

    outs = s.resolved_outputs()
    sources = [estimator_source(s, a) for a in s.analytic]
    lg = model.linear_gaussian() is not None
    opts = s.estimator
    if lg and ("exact" in sources or "n1" in outs or "n2" in outs):
        t0 = time.perf_counter()
        point.exact = ss.CrossingEstimator(
            model, dt=opts.dt, horizon=opts.horizon, mixing=opts.mixing, progress=progress
        )
        point.timings["estimator_setup"] = time.perf_counter() - t0
    ahead = _theory_ahead(point, grid_of) if grid_of is not None else None
    _simulate(point, progress, say, client, outs, sources)
    if ahead is not None:  # (on an error it is left to finish alone: a daemon thread)
        ahead.join()
    if "empirical" in sources:
        mixing = None if opts.mixing == "components" else opts.mixing
        point.empirical = ss.CrossingEstimator(
            model, ensemble=point.ensemble, dt=opts.dt, horizon=opts.horizon, mixing=mixing
        )


def _simulate(point: Point, progress: bool, say, client, outs, sources):
    """The simulations of one point: the ensemble, and the cycles of the time series."""
    import stickslip as ss

    s = point.study
    model = s.model.instance
    sim = s.simulation
    cycles = sim is not None and ("time_series" in outs or "phase_portrait" in outs)
    ahead = None
    if cycles and client is None:
        # The cycles' stepping programs (another buffer size, at their own step) compile in
        # a thread while the ensemble compiles and runs, instead of after it.
        from .._simulate.cycles import prefetch_cycles

        ahead = prefetch_cycles(
            model, sim.cycles.n_paths, sim.cycles.dt or sim.dt, sim.cycles.t_max,
            solver=sim.solver, monitor=sim.monitor,
        )  # fmt: skip
    if sim is not None and any(q in outs for q in (*DENSITIES, "n1", "n2")):
        record = sim.upcrossings if ("n1" in outs or "n2" in outs or "empirical" in sources) else 0
        say(f"simulate: {sim.n_paths} paths, dt={sim.dt:g}, solver={sim.solver}")
        ens = ss.simulate(
            model,
            sim.n_paths,
            sim.dt,
            sim.t_max,
            sim.seed,
            solver=sim.solver,
            monitor=sim.monitor,
            chunk_size=sim.chunk_size,
            progress=progress,
            record_upcrossings=record,
            client=client,
        )
        point.ensemble = ens
        point.timings["simulation"] = ens.stats["wall_seconds"]
        point.timings["simulation_compile"] = ens.stats["compile_seconds"]
    if cycles:
        if ahead is not None:
            ahead.join()
        say(f"simulate_cycles: {sim.cycles.n_paths} paths to t={sim.cycles.t_max:g}")
        t0 = time.perf_counter()
        point.cycles = ss.simulate_cycles(
            model,
            sim.cycles.n_paths,
            sim.cycles.dt or sim.dt,
            sim.cycles.t_max,
            sim.seed,
            solver=sim.solver,
            monitor=sim.monitor,
            client=client,
        )
        point.timings["cycles"] = time.perf_counter() - t0


def _theory_ahead(point: Point, study: Study):
    """Start computing, in a thread, the exact estimator's densities that `dataset.assemble`
    will ask for (`theory_density`, kept in `point.theory`), while the point simulates: on a
    first run most of the theory's time is compiling its kernels, which XLA does without
    Python's lock, so on 2 cores it overlaps the simulations. The calls are `assemble`'s own,
    in its order, and the estimator computes the same numbers; so only where every grid is
    given (none waits for the simulated data). `None` where there is nothing to compute
    ahead; else the thread (an error is left for `assemble` to meet again and raise)."""
    import threading

    from .measure import THEORY_DENSITIES, theory_density

    s, outs, grid = point.study, study.resolved_outputs(), study.grid
    if point.exact is None or not s.analytic:
        return None
    # A grid left open may be read off the theory itself (`_theory_range`, before `assemble`):
    # the estimator would see its calls in another order.
    given = all(
        getattr(grid, q).start is not None and getattr(grid, q).stop is not None
        for q in DENSITIES
        if q in outs
    ) and all(
        getattr(grid, q).stop is not None or "slip_time" in outs for q in ("n1", "n2") if q in outs
    )
    if not given:
        return None
    calls = []
    for q in DENSITIES:  # (`dataset._one`'s order)
        if q in outs and q in THEORY_DENSITIES:
            edges = _edges(getattr(grid, q), q, [])
            calls += [(a, q, edges) for a in s.analytic if estimator_source(s, a) == "exact"]
    if not calls:
        return None

    def compute():
        for a, q, edges in calls:
            try:
                result = theory_density(point, a, q, edges)
            except Exception:  # (met again, and raised, where `assemble` asks for it)
                return
            point.theory[(a.key, q, edges.tobytes())] = result

    thread = threading.Thread(target=compute, name="stickslip-theory", daemon=True)
    thread.start()
    return thread


def _compute_chain(point: Point, say, client=None):
    import stickslip as ss

    sim = point.study.simulation
    say(f"simulate_chain: {sim.n_paths} chains to t={sim.t_max:g}, dt={sim.dt:g}")
    t0 = time.perf_counter()
    point.chain = ss.simulate_chain(
        point.study.model.instance,
        sim.n_paths,
        sim.dt,
        sim.t_max,
        seed=sim.seed,
        client=client,
    )
    point.timings["simulation"] = time.perf_counter() - t0


# -- grids ---------------------------------------------------------------------------------
def _grids(study: Study, points: list[Point]) -> dict[str, np.ndarray]:
    """Bin edges of every density output, shared by all points: given ends, else from the
    pooled simulated values (0.5% and 99.5% quantiles; times start at 0), else from theory."""
    outs = study.resolved_outputs()
    edges: dict[str, np.ndarray] = {}
    for q in DENSITIES:
        if q in outs:
            edges[q] = _edges(
                study.grid.slip_time if q == "slip_time" else getattr(study.grid, q), q, points
            )
    if "n1" in outs or "n2" in outs:
        stop = edges["slip_time"][-1] if "slip_time" in edges else None
        for q in ("n1", "n2"):
            if q in outs:
                r = getattr(study.grid, q)
                lo = 0.0 if r.start is None else r.start
                hi = r.stop if r.stop is not None else (stop or _auto_stop(points, "slip_time"))
                edges[q] = np.linspace(lo, hi, r.bins + 1)
    for q in EVENTS:
        if q in outs:
            edges[q] = _event_edges(getattr(study.grid, q), q, points)
    return edges


def _edges(r, q, points):
    lo, hi = r.start, r.stop
    if lo is None or hi is None:
        a, b = _auto_range(q, points)
        lo = a if lo is None else lo
        hi = b if hi is None else hi
        if not hi > lo:
            hi = lo + 1.0
    return np.linspace(lo, hi, r.bins + 1)


def _auto_stop(points, q):
    return _auto_range(q, points)[1]


def _auto_range(q, points) -> tuple[float, float]:
    values = []
    for p in points:
        if p.ensemble is not None:
            x = np.asarray(getattr(p.ensemble, q))
            keep = p.ensemble.stuck & ~p.ensemble.immediate & np.isfinite(x)
            values.append(x[keep])
    data = np.concatenate(values) if values else np.array([])
    if data.size >= 20:
        lo, hi = np.quantile(data, [0.005, 0.995])
    else:
        lo, hi = _theory_range(q, points)
    if q != "slip_distance":
        return 0.0, float(hi)
    pad = 0.05 * (hi - lo)
    return float(lo - pad), float(hi + pad)


def _theory_range(q, points) -> tuple[float, float]:
    """Quantile range of a density from the theory's point masses (no simulation)."""
    lows, highs = [], []
    for p in points:
        est = p.exact or p.empirical
        if est is None:
            continue
        a = p.study.analytic[0]
        T, X, W, mass, X0 = est._points(a.method, a.order, a.normalized)
        T = np.broadcast_to(T, X.shape).ravel()
        X0 = np.broadcast_to(X0, X.shape).ravel()
        X, w = X.ravel(), np.abs(mass.ravel())
        level = float(np.asarray(p.study.model.instance.stick_level))
        value = {
            "slip_time": T,
            "slip_distance": X0 - X,
            "period": T + np.maximum(X0 - X, 0.0) / level,
            "stick_time": np.maximum(X0 - X, 0.0) / level,
        }[q]
        order = np.argsort(value)
        c = np.cumsum(w[order])
        if c.size == 0 or c[-1] <= 0:
            continue
        c /= c[-1]
        lows.append(value[order][np.searchsorted(c, 0.005)])
        highs.append(value[order][min(np.searchsorted(c, 0.995), c.size - 1)])
    if not highs:
        return 0.0, 10.0
    return float(min(lows)), float(max(highs))


def _event_edges(r, q, points):
    values = np.concatenate([p.chain.events(q.removeprefix("event_")) for p in points])
    values = values[np.isfinite(values) & (values > 0)]
    lo = r.start if r.start is not None else (values.min() if values.size else 1.0)
    hi = r.stop if r.stop is not None else (values.max() if values.size else 10.0)
    if q == "event_size":  # integer sizes: log-spaced cells with integer edges (+ 1/2)
        ints = np.unique(np.round(np.geomspace(max(lo, 1.0), hi + 1.0, r.bins + 1)))
        if ints.size < 2:
            ints = np.array([ints[0], ints[0] + 1.0])
        return ints - 0.5
    lo = max(lo, 1e-12)
    if not hi > lo:
        hi = lo * 10
    return np.geomspace(lo, hi, r.bins + 1)
