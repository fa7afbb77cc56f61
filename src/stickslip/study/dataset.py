"""The results of a study as one `xarray.Dataset`.

Layout (a sweep adds a leading `point` dimension, with one coordinate per swept setting):

- a coordinate per density output (`slip_time`, `period`, `slip_distance`, `stick_time`,
  `n1_time`, `n2_t1`/`n2_t2`, the event quantities of a chain) holding the cell centres, and
  `<q>_edges` the cell edges;
- `mc_<q>`, `mc_<q>_se`: Monte Carlo histogram and standard errors;
- `theory_<q>` over `method` (keys such as `Fg1`, `Fn2_norm`; `method_label` names them):
  the level-crossing approximations on the same cells; `l1_<q>` their L1 distance to the
  histogram and `l1_floor_<q>` the histogram's own noise level; `theory_<q>_se` (when a
  method is empirical) the sampling error of the empirical ones (jackknife over the paths,
  `nan` for the exact formulas; its attribute `band_factor` makes it a 95 % band);
- `theory_n1`, `mc_n1`, `theory_n2`, `mc_n2`: upcrossing densities;
- scalars: `fraction_stuck`, `fraction_immediate`, `mean_<q>` with `mean_<q>_se`;
- `seconds_<part>` (and `seconds_theory` over `method`): wall time of each part;
- `series_*`: time series of a few paths through successive cycles (padded with nan);
- attributes: the study (YAML), the package version, the model and the creation time.
"""

from __future__ import annotations

import datetime
import json

import numpy as np
import xarray as xr

from .._estimate.estimator import cell_average
from ..quantities import get as quantity
from .measure import (
    EVENTS,
    THEORY_DENSITIES,
    cell_average_2d,
    estimator_source,
    l1,
    l1_floor,
    mc_density,
    mc_n1,
    mc_n2,
    theory_density,
)
from .schema import DENSITIES, Study

# An axis's label and the dimension of its unit: the per-cycle quantities' from the
# registry, then the crossing counts' and the chain's coordinates.
LABELS = {
    **{q: (quantity(q).label, quantity(q).dimension) for q in DENSITIES},
    "n1_time": ("time since slip onset $t$", "time"),
    "n2_t1": ("first time $t_1$", "time"),
    "n2_t2": ("second time $t_2$", "time"),
    "event_size": ("event size $s$", "blocks"),
    "event_duration": ("event duration", "time"),
    "event_interval": ("time between events", "time"),
}


def units_of(model, kind: str) -> str:
    units = getattr(type(model), "units", None) or {}
    return units.get(kind, kind if kind == "blocks" else f"{kind} units")


def assemble(study: Study, points, edges, progress: bool = False) -> xr.Dataset:
    """The Dataset of a study's points; `progress`: a bar over the theory evaluations."""
    import stickslip

    model = study.model.instance
    with _TheoryBar(study, points, progress) as bar:
        per_point = [_one(study, p, edges, bar) for p in points]
    ds = xr.concat(per_point, dim="point", data_vars="all", coords="minimal", join="outer")
    for name in list(ds.data_vars):  # grids and labels are shared, not per point
        if name.endswith("_edges") or name == "method_label":
            ds[name] = ds[name].isel(point=0, drop=True)
    if study.sweep is None:
        ds = ds.isel(point=0, drop=True)
    else:
        for path in study.sweep.parameters:
            ds = ds.assign_coords({path: ("point", [p.values[path] for p in points])})
    for coord, (label, kind) in LABELS.items():
        if coord in ds.coords:
            ds[coord].attrs.update(long_name=label, units=units_of(model, kind))
    ds.attrs.update(
        title=study.title or f"{study.model.name} study",
        study=study_yaml(study),
        stickslip_version=stickslip.__version__,
        model=study.model.name,
        model_params=json.dumps(_plain(study.model.instance.params()), default=str),
        created=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        warnings="\n".join(w for p in points for w in p.warnings),
    )
    choices = {q: c for p in points for q, c in p.choices.items()}
    if choices:
        ds.attrs["method_choice"] = json.dumps(
            {
                q: dict(
                    settings=c.settings,
                    error=c.chosen.error,
                    promised=c.promised,
                    seconds=c.chosen.seconds,
                    selection_seconds=c.selection_seconds,
                    reason=c.reason,
                )
                for q, c in choices.items()
            }
        )
    return ds


def study_yaml(study: Study) -> str:
    import yaml

    return yaml.safe_dump(
        _plain(study.model_dump(exclude_unset=True)), sort_keys=False, default_flow_style=None
    )


def _plain(obj):
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, (str, int, float, bool)) or obj is None:
        return obj
    if hasattr(obj, "shape") and getattr(obj, "shape", None) == ():
        return float(obj)
    return repr(obj)


class _TheoryBar:
    """A progress bar over the level-crossing evaluations of a study (one step per density
    and method), naming the one under way; nothing unless enabled."""

    def __init__(self, study: Study, points, enabled: bool):
        outs = study.resolved_outputs()
        total = 0
        for p in points:
            methods = len(p.study.analytic)
            total += methods * sum(q in outs for q in THEORY_DENSITIES)
            if p.exact is not None:
                total += ("n1" in outs) + ("n2" in outs)
        self.bar = None
        if enabled and total:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, desc="theory", unit="density", leave=False)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()

    def start(self, name: str):
        if self.bar is not None:
            self.bar.set_postfix_str(name, refresh=True)

    def done(self):
        if self.bar is not None:
            self.bar.update()


def _one(study: Study, point, edges, bar) -> xr.Dataset:
    outs = study.resolved_outputs()
    data: dict = {}
    coords: dict = {}
    methods = [a.key for a in point.study.analytic]
    if methods:
        coords["method"] = methods
        data["method_label"] = ("method", [a.title for a in point.study.analytic])
    ens = point.ensemble
    for q in DENSITIES:
        if q not in outs:
            continue
        e = edges[q]
        coords[q] = 0.5 * (e[1:] + e[:-1])
        data[f"{q}_edges"] = (f"{q}_edge", e)
        mc = se = None
        if ens is not None:
            mc, se = mc_density(point, q, e)
            data[f"mc_{q}"] = (q, mc)
            data[f"mc_{q}_se"] = (q, se)
            data[f"l1_floor_{q}"] = ((), l1_floor(se, e))
        if q in THEORY_DENSITIES and methods:
            rows, errs, secs = [], [], []
            for a in point.study.analytic:
                bar.start(f"{q} {a.key}")
                values, seconds, notes = theory_density(point, a, q, e)
                bar.done()
                point.warnings.extend(notes)
                rows.append(values)
                secs.append(seconds)
                errs.append(l1(values, mc, e) if mc is not None else np.nan)
            data[f"theory_{q}"] = (("method", q), np.array(rows))
            if point.empirical is not None:
                data[f"theory_{q}_se"] = _theory_se(point, q, e)
            data[f"l1_{q}"] = ("method", np.array(errs))
            data[f"seconds_theory_{q}"] = ("method", np.array(secs))
    if ens is not None:
        data["n_paths"] = ((), ens.n_paths)
        data["fraction_stuck"] = ((), ens.fraction_stuck)
        data["fraction_immediate"] = ((), ens.fraction_immediate)
        for q in DENSITIES:
            m, s = ens.mean(q)
            data[f"mean_{q}"] = ((), m)
            data[f"mean_{q}_se"] = ((), s)
    for q, dims in (("n1", ("n1_time",)), ("n2", ("n2_t1", "n2_t2"))):
        if q not in outs:
            continue
        e = edges[q]
        c = 0.5 * (e[1:] + e[:-1])
        for d in dims:
            coords[d] = c
        data[f"{q}_edges"] = (f"{q}_edge", e)
        if point.exact is not None:
            import time

            bar.start(q)
            t0 = time.perf_counter()
            if q == "n1":
                value = cell_average(point.exact.n1, e, point.exact.dt / 4)
            else:
                value = cell_average_2d(point.exact.n2, e)
            data[f"seconds_theory_{q}"] = ((), time.perf_counter() - t0)
            bar.done()
            data[f"theory_{q}"] = (dims, np.asarray(value, float))
        if ens is not None and ens.upcrossings is not None:
            if q == "n1":
                value, se = mc_n1(point, e)
                data["mc_n1"] = (dims, value)
                data["mc_n1_se"] = (dims, se)
                data["l1_floor_n1"] = ((), l1_floor(se, e))
                if point.exact is not None:
                    data["l1_n1"] = ((), l1(data["theory_n1"][1], value, e))
            else:
                data["mc_n2"] = (dims, mc_n2(point, e))
    if point.cycles is not None:
        data.update(_series(point))
    if point.chain is not None:
        data.update(_chain(point, outs, edges, coords))
    for part, seconds in point.timings.items():
        data[f"seconds_{part}"] = ((), seconds)
    return xr.Dataset(data, coords=coords)


def _theory_se(point, q: str, edges):
    """The sampling errors of the empirical approximations of `q` on its cells (`nan` rows
    for the exact ones), as a Dataset variable with its 95 % band factor."""
    from scipy import stats

    est = point.empirical
    centres = 0.5 * (edges[1:] + edges[:-1])
    rows = []
    for a in point.study.analytic:
        if estimator_source(point.study, a) != "empirical":
            rows.append(np.full(centres.size, np.nan))
            continue
        args = (a.method, a.order, a.normalized)
        if q == "slip_time":
            rows.append(est.first_passage_cells_se(edges, *args))
        elif q == "period":
            rows.append(est.period_density_se(centres, *args))
        else:
            rows.append(est.slip_distance_density_se(centres, *args))
    groups = est.error_groups
    attrs = dict(
        long_name=f"standard error of the empirical theory_{q} (jackknife over the paths)",
        error_groups=groups,
        # t quantile: the standard error is estimated from groups - 1 degrees of freedom
        band_factor=float(stats.t.ppf(0.975, groups - 1)),
    )
    return (("method", q), np.array(rows), attrs)


SERIES_PATHS = 2  # paths whose time series are kept
SERIES_SAMPLES = 20_000  # samples kept per path (every k-th step beyond that)


def _series(point) -> dict:
    """Time series of the first paths of the cycle runs (fig. 2), thinned to at most
    `SERIES_SAMPLES` samples (every stick sample kept), and the phase-space orbits (fig. 7)."""
    cyc = point.cycles
    traces = []
    for i in range(min(cyc.n_paths, SERIES_PATHS)):
        t, s, sl = cyc.trajectory(i)
        stride = max(1, -(-t.size // SERIES_SAMPLES))
        keep = np.zeros(t.size, dtype=bool)
        keep[::stride] = True
        keep[~sl] = True  # a stick and the release after it
        keep[1:][~sl[:-1]] = True
        keep[-1] = True
        traces.append((t[keep], s[keep], sl[keep]))
    n = max(t.size for t, _, _ in traces)
    names = cyc.state_names
    out: dict = _orbits(point)
    t_arr = np.full((len(traces), n), np.nan)
    slip = np.zeros((len(traces), n), dtype=bool)
    states = np.full((len(traces), n, len(names)), np.nan)
    for i, (t, s, sl) in enumerate(traces):
        t_arr[i, : t.size] = t
        slip[i, : t.size] = sl
        states[i, : t.size] = s
    dims = ("series_path", "series_sample")
    out["series_t"] = (dims, t_arr)
    out["series_slipping"] = (dims, slip.astype(np.int8))
    for k, name in enumerate(names):
        out[f"series_{name}"] = (dims, states[:, :, k])
    table = cyc.cycles
    cdims = ("cycle",)
    for key in ("path", "release_time", "slip_time", "slip_distance", "stick_time", "period"):
        out[f"cycle_{key}"] = (cdims, np.asarray(table[key]))
    return out


def fundamental_period(model):
    """2 pi / omega of the slowest-decaying oscillation of a linear slip phase (the
    deterministic period, near which n1 peaks); None if the model is not linear or does
    not oscillate."""
    lg = model.linear_gaussian()
    if lg is None:
        return None
    eig = np.linalg.eigvals(np.asarray(lg.A, float))
    osc = eig[np.abs(eig.imag) > 1e-12]
    if osc.size == 0:
        return None
    slowest = osc[np.argmax(osc.real)]
    return float(2 * np.pi / abs(slowest.imag))


def _orbits(point, most: int = 3) -> dict:
    """The first slip of each kind in the cycle runs, for the phase portrait (fig. 7): a slip
    of k orbits has a slip time near k deterministic periods (the median slip time if the
    model has none); slips shorter than half a period are left out."""
    cyc = point.cycles
    model = point.study.model.instance
    period = fundamental_period(model)
    if period is None:
        long = cyc.cycles["slip_time"][cyc.cycles["slip_time"] > 0]
        period = float(np.median(long)) if long.size else 1.0
    found: dict[int, tuple] = {}
    for p in range(cyc.n_paths):
        t, s, sl = cyc.trajectory(p)
        bounds = np.flatnonzero(np.diff(np.r_[0, sl.astype(int), 0]))
        for a, b in zip(bounds[::2], bounds[1::2], strict=True):
            b = min(b + 1, t.size)  # include the stick sample that ends the slip
            k = int(round((t[b - 1] - t[a]) / period))
            if 1 <= k <= most and k not in found:
                found[k] = (t[a:b] - t[a], s[a:b])
        if len(found) == most:
            break
    if not found:
        return {}
    ks = sorted(found)
    n = max(found[k][0].size for k in ks)
    names = cyc.state_names
    arr = np.full((len(ks), n, len(names)), np.nan)
    tt = np.full((len(ks), n), np.nan)
    for i, k in enumerate(ks):
        tt[i, : found[k][0].size] = found[k][0]
        arr[i, : found[k][0].size] = found[k][1]
    dims = ("orbit", "orbit_sample")
    out = {"orbit_k": ("orbit", np.array(ks)), "orbit_t": (dims, tt)}
    out["orbit_period"] = ((), period)
    for j, name in enumerate(names):
        out[f"orbit_{name}"] = (dims, arr[:, :, j])
    return out


def _chain(point, outs, edges, coords) -> dict:
    run = point.chain
    out: dict = {}
    for q in EVENTS:
        if q not in outs:
            continue
        e = edges[q]
        if q == "event_size":  # cells of whole sizes a..b: their geometric middle
            coords[q] = np.sqrt((e[:-1] + 0.5) * (e[1:] - 0.5))
        else:
            coords[q] = np.sqrt(e[1:] * e[:-1])
        values = run.events(q.removeprefix("event_"))
        counts, _ = np.histogram(values, bins=e)
        total = max(values.size, 1)
        width = np.diff(e)
        out[f"{q}_edges"] = (f"{q}_edge", e)
        out[f"mc_{q}"] = (q, counts / (total * width))
        out[f"mc_{q}_se"] = (q, np.sqrt(counts) / (total * width))
        out[f"n_{q}"] = ((), values.size)
    if "time_series" in outs:
        k = min(run.mean_velocity.shape[0], 4)
        coords["chain_time"] = run.t
        dims = ("chain_path", "chain_time")
        out["chain_mean_velocity"] = (dims, run.mean_velocity[:k])
        out["chain_slipping"] = (dims, run.slipping[:k])
        out["chain_mean_force"] = (dims, run.mean_force[:k])
    out["n_events"] = ((), int(np.sum(run.n_events)))
    out["event_rate"] = ((), float(np.sum(run.n_events)) / (run.t_max * len(run.start)))
    return out
