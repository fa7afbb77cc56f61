"""Writing a study's results: `results.nc`, figures and `summary.md`, atomically.

Everything is written into a temporary directory beside the target (`.NAME.partial-PID`),
with the marker file `.stickslip-results` that lists the files and lets `--force` recognise
the folder later, and moved into place when complete. A run stopped midway leaves nothing
under the final name (the next run removes its temporary directory); an existing target
(replaced only with `--force`, and only if it holds nothing but what stickslip wrote) is
moved aside and deleted only after the new results are in place.
"""

from __future__ import annotations

import json
import os
import pathlib
import shutil
import time

import numpy as np
import xarray as xr

from .schema import Study

NETCDF = "results.nc"


def write_results(ds: xr.Dataset, study: Study, out: pathlib.Path, *, force, figures, say):
    from .._output import partial_dir

    out = pathlib.Path(out)
    tmp = partial_dir(out)
    timings = {}
    try:
        if figures:
            from .plots import make_figures

            t0 = time.perf_counter()
            names = make_figures(ds, study, tmp)
            timings["figures"] = time.perf_counter() - t0
            say(f"figures: {', '.join(names)}")
        t0 = time.perf_counter()
        save_netcdf(ds, tmp / NETCDF)
        timings["netcdf"] = time.perf_counter() - t0
        (tmp / "summary.md").write_text(summary(ds, study, timings), encoding="utf-8")
        (tmp / "study.yaml").write_text(ds.attrs["study"], encoding="utf-8")
        replace_file(tmp, out, force, "run")
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    say(f"wrote {out}/: {', '.join(sorted(p.name for p in out.iterdir()))}")


def replace_file(tmp: pathlib.Path, out: pathlib.Path, force: bool, contents: str | None = None):
    """Move the finished results `tmp` to `out`, with the marker that makes `out` a results
    folder (`contents`: 'run' or 'fit'; by default read from the files). The swap happens
    whole or not at all: an interrupt before it (or one a library swallowed earlier) leaves
    the earlier results as they were; one during it is raised once it is done."""
    from .._output import check_interrupted, check_replace_dir, no_interrupts, write_marker

    check_interrupted()
    if contents is None:
        contents = "fit" if (tmp / "fit.json").exists() else "run"
    write_marker(tmp, contents)
    old = None
    # (SIGINT is held back in this thread; a process's other threads may still take it, and
    # then the interrupt is raised here: the earlier results go back in place. A process
    # killed in between leaves them as `.NAME.old-PID`, which the next run puts back.)
    with no_interrupts() as held:
        if held.pending():
            raise KeyboardInterrupt
        try:
            if out.exists():
                if any(out.iterdir()):
                    check_replace_dir(out, force)  # checked before the run; it may have changed
                    old = out.parent / f".{out.name}.old-{os.getpid()}"
                    out.rename(old)
                else:
                    out.rmdir()
            tmp.rename(out)
        except BaseException:
            if old is not None and os.path.lexists(old) and not os.path.lexists(out):
                old.rename(out)
            raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def save_netcdf(ds: xr.Dataset, path: pathlib.Path):
    """netCDF-4 through h5netcdf; booleans as int8 (netCDF has no boolean type).

    The file is `ds.to_netcdf(path, engine="h5netcdf")`'s, byte for byte, written through
    its store with HDF5's lock given: `to_netcdf` asks Dask which scheduler is active (to
    choose a lock for Dask-backed variables, which a study's Dataset does not have), and
    that imports `distributed`, 0.2-0.4 s of every run's serial end. A Dataset with
    Dask-backed variables goes through `to_netcdf` (the store alone would not compute them)."""
    ds = ds.copy()
    for name, var in ds.variables.items():
        if var.dtype == bool:
            ds[name] = var.astype(np.int8)
    try:
        from xarray.backends import H5NetCDFStore
        from xarray.backends.locks import HDF5_LOCK
    except ImportError:  # pragma: no cover - another xarray: its own way
        H5NetCDFStore = None
    if H5NetCDFStore is None or any(v.chunks is not None for v in ds.variables.values()):
        ds.to_netcdf(path, engine="h5netcdf", invalid_netcdf=False)
        return
    store = H5NetCDFStore.open(path, mode="w", invalid_netcdf=False, lock=HDF5_LOCK)
    try:
        ds.dump_to_store(store)
    finally:
        store.close()


# -- summary ------------------------------------------------------------------------------
def summary(ds: xr.Dataset, study: Study, timings: dict) -> str:
    lines = [f"# {ds.attrs['title']}", ""]
    if study.description:
        lines += [study.description.strip(), ""]
    lines += [
        f"stickslip {ds.attrs['stickslip_version']}, {ds.attrs['created']}. "
        f"Model `{study.model.name}`: "
        + ", ".join(f"{k} = {v}" for k, v in study.model.instance.params().items()),
        "",
    ]
    sim = study.simulation
    if sim is not None:
        lines += [
            f"Simulation: {sim.n_paths} paths, dt = {sim.dt:g}, t_max = {sim.t_max:g}, "
            f"solver `{sim.solver}`, monitor `{sim.monitor}`, seed {sim.seed}.",
            "",
        ]
    if ds.attrs.get("method_choice"):
        lines += ["## Method (auto)", ""]
        for q, c in json.loads(ds.attrs["method_choice"]).items():
            lines += [f"**{q.replace('_', ' ')}**: " + c["reason"].replace("\n  ", "\n- "), ""]
    if "point" in ds.dims:
        lines += _sweep_table(ds, study)
    else:
        lines += _point_tables(ds)
    lines += ["## Wall time", "", "| part | seconds |", "|---|---|"]
    for name in sorted(ds.data_vars):
        if name.startswith("seconds_"):
            value = ds[name]
            if "method" in value.dims:
                axis = value.dims.index("method")
                for i, m in enumerate(value["method"].values):
                    total = float(np.take(value.values, i, axis=axis).sum())
                    lines.append(f"| {name.removeprefix('seconds_')} `{m}` | {total:.3g} |")
            else:
                lines.append(f"| {name.removeprefix('seconds_')} | {float(value.sum()):.3g} |")
    lines.append(
        f"| theory densities and histograms | {ds.attrs['seconds_theory_densities']:.3g} |"
    )
    for part, seconds in timings.items():
        lines.append(f"| writing {part} | {seconds:.3g} |")
    lines.append("")
    if ds.attrs.get("warnings"):
        lines += ["## Warnings of the approximations", ""]
        lines += [f"- {w}" for w in ds.attrs["warnings"].splitlines()]
        lines.append("")
    lines += ["## Files", "", "- `results.nc`: every number above and the curves (xarray/netCDF)"]
    lines += ["- `study.yaml`: the study as run", "- `*.png`: figures"]
    lines += ["- `.stickslip-results`: marks the folder as results (`--force` replaces it)", ""]
    return "\n".join(lines)


def _point_tables(ds) -> list[str]:
    lines = []
    if "fraction_stuck" in ds:
        lines += ["## Monte Carlo", "", "| quantity | value |", "|---|---|"]
        lines.append(f"| paths stuck before t_max | {float(ds.fraction_stuck):.4f} |")
        lines.append(f"| immediate re-sticks | {float(ds.fraction_immediate):.4f} |")
        for q in ("slip_time", "slip_distance", "stick_time", "period"):
            if f"mean_{q}" in ds:
                m, s = float(ds[f"mean_{q}"]), float(ds[f"mean_{q}_se"])
                lines.append(f"| mean {q.replace('_', ' ')} | {m:.4f} ± {s:.2g} |")
        lines.append("")
    if "n_events" in ds:
        lines += [
            "## Events",
            "",
            f"{int(ds.n_events)} events, rate {float(ds.event_rate):.4g} per time unit per chain.",
            "",
        ]
    for q in ("slip_time", "period", "slip_distance"):
        if f"theory_{q}" not in ds:
            continue
        floor = float(ds[f"l1_floor_{q}"]) if f"l1_floor_{q}" in ds else float("nan")
        lines += [
            f"## {q.replace('_', ' ')}: L1 error against the simulation",
            "",
            f"On {ds[q].size} cells over [{float(ds[f'{q}_edges'][0]):.4g}, "
            f"{float(ds[f'{q}_edges'][-1]):.4g}]; the histogram's own noise gives L1 about "
            f"{floor:.3g}. Seconds: the method's own cost here; a method listed later reuses "
            "crossing densities an earlier one computed.",
            "",
            "| method | L1 | seconds |",
            "|---|---|---|",
        ]
        for i, m in enumerate(ds["method"].values):
            label = str(ds["method_label"].values[i])
            lines.append(
                f"| `{m}` {label} | {float(ds[f'l1_{q}'][i]):.4f} | "
                f"{float(ds[f'seconds_theory_{q}'][i]):.3g} |"
            )
        lines.append("")
    if "l1_n1" in ds:
        lines += [
            "Upcrossing density n1: L1 of the exact theory against the simulated upcrossings "
            f"{float(ds.l1_n1):.4f} (the histogram's own noise gives about "
            f"{float(ds.l1_floor_n1):.3g}).",
            "",
        ]
    return lines


def _sweep_table(ds, study) -> list[str]:
    paths = list(study.sweep.parameters)
    cols = [c for c in ("fraction_stuck", "mean_slip_time", "mean_period") if c in ds]
    l1s = [v for v in ds.data_vars if v.startswith("l1_") and "method" in ds[v].dims]
    head = paths + cols + [f"{v} `{m}`" for v in l1s for m in ds["method"].values]
    lines = ["## Sweep", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for i in range(ds.sizes["point"]):
        row = [str(ds[p].values[i]) for p in paths]
        for c in cols:
            v = float(ds[c][i])
            se = f" ± {float(ds[c + '_se'][i]):.2g}" if c + "_se" in ds else ""
            row.append(f"{v:.4f}{se}")
        for v in l1s:
            row += [f"{float(x):.4f}" for x in ds[v][i].values]
        lines.append("| " + " | ".join(row) + " |")
    lines.append("")
    return lines
