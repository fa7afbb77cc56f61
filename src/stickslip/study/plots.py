"""Figures of a study, drawn from its Dataset (so they can be redrawn from `results.nc`).

- `<q>.png` for each density: Monte Carlo histogram (markers with standard-error bars, as
  in the paper's figs. 4-6) against each analytic method, in the histogram's frame (a curve
  that leaves it says so in the legend), with a detail panel where a narrow peak dwarfs the
  rest; an empirical method (from simulated upcrossings) with its 95 % sampling band;
- `n1.png` (fig. 4), `n2.png`;
- `time_series.png`: stick-slip motion of a path (fig. 2); `phase_portrait.png`: slips in
  the (x, v) plane, a fundamental orbit against multiple ones (fig. 7);
- chains: `event_size.png`, `event_duration.png`, `event_interval.png` (log-log) and
  `time_series.png`;
- sweeps: `sweep.png`, the regime plot (fraction stuck, means, L1 errors against the swept
  setting).
"""

from __future__ import annotations

import pathlib

import numpy as np

from ..quantities import QUANTITIES
from .dataset import LABELS, units_of
from .schema import Study

COLORS = ["tab:red", "tab:blue", "tab:green", "tab:orange", "tab:purple", "tab:brown"]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _axis_label(ds, coord, model) -> str:
    label, kind = LABELS[coord]
    return f"{label} [{units_of(model, kind)}]"


def _density_label(ds, coord, model) -> str:
    kind = LABELS[coord][1]
    unit = units_of(model, kind)
    s = QUANTITIES[coord].symbol if coord in QUANTITIES else None
    head = f"density $p({s})$" if s else "density"
    return f"{head} [1/{unit}]" if kind != "blocks" else head


def _subtitle(study: Study, width_inches: float = 7.0) -> str:
    """The model and its parameters (swept ones marked), wrapped to the figure's width."""
    import textwrap

    params = dict(study.model.instance.params())
    if "threshold_description" in params:  # e.g. lognormal(median=1, sigma=0.4)
        params["threshold"] = params.pop("threshold_description")
    swept = {p.split(".")[-1] for p in (study.sweep.parameters if study.sweep else ())}
    shown = [
        f"{k} swept" if k in swept else f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
        for k, v in params.items()
        if v is not None and not isinstance(v, dict)
    ]
    width = int(width_inches * 13)  # characters of 9-point text per inch, with a margin
    return "\n".join(textwrap.wrap(f"{study.model.name}: " + ", ".join(shown), width))


def _title(ax, ds, study):
    width = ax.figure.get_figwidth()
    ax.set_title(f"{ds.attrs['title']}\n{_subtitle(study, width)}", fontsize=9)


def make_figures(ds, study: Study, out: pathlib.Path) -> list[str]:
    plt = _plt()
    written = []
    sweep = "point" in ds.dims
    model = study.model.instance
    for q in ("slip_time", "period", "slip_distance", "stick_time"):
        if f"mc_{q}" in ds or f"theory_{q}" in ds:
            fig = (_density_sweep if sweep else _density)(plt, ds, study, q, model)
            written.append(_save(plt, fig, out / f"{q}.png"))
    if not sweep:
        if "theory_n1" in ds or "mc_n1" in ds:
            written.append(_save(plt, _n1(plt, ds, study, model), out / "n1.png"))
        if "theory_n2" in ds or "mc_n2" in ds:
            written.append(_save(plt, _n2(plt, ds, study, model), out / "n2.png"))
        if "series_t" in ds:
            outs = study.resolved_outputs()
            if "time_series" in outs:
                written.append(
                    _save(plt, _time_series(plt, ds, study, model), out / "time_series.png")
                )
            if "phase_portrait" in outs:
                written.append(
                    _save(plt, _phase(plt, ds, study, model), out / "phase_portrait.png")
                )
        if "chain_mean_velocity" in ds:
            written.append(_save(plt, _chain_series(plt, ds, study), out / "time_series.png"))
    for q in ("event_size", "event_duration", "event_interval"):
        if f"mc_{q}" in ds:
            written.append(_save(plt, _events(plt, ds, study, q, model), out / f"{q}.png"))
    if sweep:
        written.append(_save(plt, _sweep(plt, ds, study), out / "sweep.png"))
    return written


def _save(plt, fig, path) -> str:
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path.name


def _mc_label(study):
    sim = study.simulation
    return f"Monte Carlo ({sim.n_paths:,} paths, dt={sim.dt:g})"


# Frames of the density figures. The Monte Carlo histogram sets them, not the approximations:
# a truncation that diverges (the slip-distance F_n^(2) runs to -15 on the public set) would
# otherwise squash the histogram into a line. Headroom above the histogram's largest bar:
_HEADROOM = 1.15
# A peak "dwarfs" the rest when the rest stays below this fraction of its height while carrying
# at least _REST_MASS of the probability in the frame (the immediate re-sticks at T ~ 0 against
# the hump at T ~ 4 on the public set: 0.11 of the height, about 3/4 of the mass). A single
# broad hump leaves only its tails, with little mass, and gets one panel.
_SPIKE_RATIO = 0.35
_REST_MASS = 0.25
# Height of the detail panel, over the largest bar away from the peak (error bar included).
_DETAIL_HEADROOM = 1.3
# An approximation "stays near" the histogram, and widens the frame to fit, when it rises at
# most _NEAR times the histogram's top, dips at most _NEAR_BELOW of it below zero and is off
# by at most _NEAR_L1 of the histogram's mass in the frame (the decoupling F_g^(1) of fig. 6C,
# L1 0.1, stays near; the slip-distance F_n^(1) of the public set, L1 11, does not). One that
# goes further is cut by the frame and says so.
_NEAR = 1.5
_NEAR_BELOW = 0.1
_NEAR_L1 = 0.5


def _spike(y: np.ndarray) -> slice | None:
    """The bins of a narrow peak that dwarfs the rest of the histogram `y`, or None.

    The peak runs from its highest bar down both sides while the bars keep falling."""
    y = np.where(np.isfinite(y), y, 0.0)
    if y.size < 4 or y.max() <= 0:
        return None
    top = int(np.argmax(y))
    lo, hi = top, top
    while lo > 0 and y[lo - 1] < y[lo]:
        lo -= 1
    while hi < y.size - 1 and y[hi + 1] < y[hi]:
        hi += 1
    rest = np.r_[y[:lo], y[hi + 1 :]]
    if rest.size == 0 or rest.max() > _SPIKE_RATIO * y[top] or rest.sum() < _REST_MASS * y.sum():
        return None
    return slice(lo, hi + 1)


def _frame(values: np.ndarray, headroom: float, curves=()) -> tuple[float, float]:
    """The y-range for histogram bars up to `values`, widened to the `curves` near them."""
    top = float(np.nanmax(values))
    lo, hi = -0.06 * headroom * top, headroom * top
    mass = float(np.nansum(values))
    for y in curves:
        ok = np.isfinite(y) & np.isfinite(values)
        if not ok.any():
            continue
        off = float(np.sum(np.abs(y[ok] - values[ok])))
        near = y[ok].max() <= _NEAR * top and y[ok].min() >= -_NEAR_BELOW * top
        if near and off <= _NEAR_L1 * mass:
            hi, lo = max(hi, 1.05 * y[ok].max()), min(lo, 1.05 * y[ok].min())
    return lo, hi


def _leaves(y: np.ndarray, frame: tuple[float, float], keep: np.ndarray | None = None) -> bool:
    """Whether the curve `y` goes outside `frame` (only where `keep` is True, if given)."""
    y = y if keep is None else y[keep]
    y = y[np.isfinite(y)]
    return bool(y.size) and bool((y.max() > frame[1]) or (y.min() < frame[0]))


def _density(plt, ds, study, q, model):
    """One density: the Monte Carlo histogram against each approximation.

    The frame is the histogram's; a curve that leaves it is clipped by the axes and says so in
    its legend entry. Where a narrow peak (e.g. slips of almost zero length) dwarfs the rest,
    a second panel shows the rest at its own height, the peak cut."""
    x = ds[q].values
    mc = ds[f"mc_{q}"].values if f"mc_{q}" in ds else None
    has_mc = mc is not None and np.isfinite(mc).any() and np.nanmax(mc) > 0
    se = ds[f"mc_{q}_se"].values if has_mc else None
    spike = _spike(mc) if has_mc else None
    if spike is not None:
        fig, (ax, detail) = plt.subplots(
            2,
            1,
            figsize=(7, 6.8),
            sharex=True,
            height_ratios=[1, 1.3],
            layout="constrained",
        )
        axes = [ax, detail]
    else:
        fig, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")
        axes, detail = [ax], None
    frames = {}
    if has_mc:
        upper = mc + np.nan_to_num(se)
        curves = (
            [ds[f"theory_{q}"].values[i] for i in range(ds.sizes["method"])]
            if f"theory_{q}" in ds
            else []
        )
        frames[ax] = _frame(upper, _HEADROOM, curves)
        if detail is not None:
            away = np.ones(x.size, bool)
            away[spike] = False
            frames[detail] = _frame(upper[away], _DETAIL_HEADROOM, [y[away] for y in curves])
        for a in axes:
            a.errorbar(
                x,
                mc,
                yerr=se,
                fmt="x",
                color="k",
                ms=4,
                lw=0.8,
                label=_mc_label(study) if a is ax else None,
                zorder=3,
            )
    if f"theory_{q}" in ds:
        for i in range(ds.sizes["method"]):
            y = ds[f"theory_{q}"].values[i]
            label = str(ds["method_label"].values[i])
            notes = []
            if f"l1_{q}" in ds and np.isfinite(ds[f"l1_{q}"].values[i]):
                notes.append(f"L1 {float(ds[f'l1_{q}'].values[i]):.3f}")
            out = ax in frames and _leaves(y, frames[ax])
            if detail is not None:
                out = out or _leaves(y, frames[detail], away)
            if out:
                notes.append("leaves the range")
            band = _band(ds, q, i)
            if band is not None:
                notes.append("shaded: 95 % sampling band")
            if notes:
                label += f" ({'; '.join(notes)})"
            for a in axes:
                a.plot(x, y, color=COLORS[i % 6], lw=1.6, label=label if a is ax else None)
                if band is not None:
                    a.fill_between(x, y - band, y + band, color=COLORS[i % 6], alpha=0.25, lw=0)
    for a in axes:
        if a in frames:
            a.set_ylim(*frames[a])
        a.set_ylabel(_density_label(ds, q, model))
        a.axhline(0, color="0.7", lw=0.6)
    axes[-1].set_xlabel(_axis_label(ds, q, model))
    if detail is not None:
        detail.set_title(
            "detail: the rest of the histogram at its own height (the peak is cut)",
            fontsize=8,
            loc="right",
            color="0.3",
        )
    ax.legend(fontsize=8, loc="upper right")
    _title(ax, ds, study)
    return fig


def _band(ds, q, i, point=None):
    """Half-width of the 95 % sampling band of method `i` of `q` (empirical methods; None
    for the exact ones, which have none)."""
    name = f"theory_{q}_se"
    if name not in ds:
        return None
    se = ds[name].values[i] if point is None else ds[name].values[point, i]
    if not np.isfinite(se).any():
        return None
    return float(ds[name].attrs.get("band_factor", 1.96)) * np.nan_to_num(se)


def _density_sweep(plt, ds, study, q, model):
    fig, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")
    x = ds[q].values
    paths = list(study.sweep.parameters)
    cmap = plt.get_cmap("viridis")
    n = ds.sizes["point"]
    for i in range(n):
        color = cmap(i / max(n - 1, 1))
        name = ", ".join(f"{p.split('.')[-1]}={ds[p].values[i]}" for p in paths)
        if f"mc_{q}" in ds:
            ax.plot(x, ds[f"mc_{q}"].values[i], "x", color=color, ms=3, label=f"MC {name}")
        if f"theory_{q}" in ds:
            y = ds[f"theory_{q}"].values[i, 0]
            ax.plot(x, y, color=color, lw=1.2)
            band = _band(ds, q, 0, point=i)
            if band is not None:
                ax.fill_between(x, y - band, y + band, color=color, alpha=0.2, lw=0)
    label = f"lines: {ds['method_label'].values[0]}" if f"theory_{q}" in ds else None
    if label and _band(ds, q, 0, point=0) is not None:
        label += " (shaded: 95 % sampling band)"
    if f"mc_{q}" in ds and np.isfinite(ds[f"mc_{q}"].values).any():
        # the frame is the histograms' (see _density)
        # all points at once: the lines, one per point, against the histograms
        lines = [ds[f"theory_{q}"].values[:, 0].ravel()] if label else []
        frame = _frame(ds[f"mc_{q}"].values.ravel(), _HEADROOM, lines)
        ax.set_ylim(*frame)
        if any(_leaves(y, frame) for y in lines):
            label += " (some leave the range)"
    if label:
        ax.plot([], [], color="k", lw=1.2, label=label)
    ax.set_xlabel(_axis_label(ds, q, model))
    ax.set_ylabel(_density_label(ds, q, model))
    ax.legend(fontsize=7, ncol=2)
    _title(ax, ds, study)
    return fig


def _n1(plt, ds, study, model):
    fig, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")
    t = ds["n1_time"].values
    if "mc_n1" in ds:
        ax.errorbar(
            t,
            ds["mc_n1"].values,
            yerr=ds["mc_n1_se"].values,
            fmt="x",
            color="k",
            ms=4,
            lw=0.8,
            label=f"{_mc_label(study)}: recorded upcrossings",
            zorder=3,
        )
    if "theory_n1" in ds:
        label = "exact Rice $n_1(t)$, eq. (13)"
        if "l1_n1" in ds:
            label += f" (L1 {float(ds.l1_n1):.3f})"
        ax.plot(t, ds["theory_n1"].values, color="tab:red", lw=1.6, label=label)
    ax.set_xlabel(_axis_label(ds, "n1_time", model))
    ax.set_ylabel(f"upcrossing density $n_1(t)$ [1/{units_of(model, 'time')}]")
    ax.legend(fontsize=8)
    _title(ax, ds, study)
    return fig


def _n2(plt, ds, study, model):
    panels = [k for k in ("theory_n2", "mc_n2") if k in ds]
    fig, axes = plt.subplots(
        1, len(panels), figsize=(5.2 * len(panels), 4.5), layout="constrained", squeeze=False
    )
    e = ds["n2_edges"].values
    # the colour scale from the 99th percentile: a few steep cells near t = 0 would wash out
    # the rest
    vmax = max(float(np.nanpercentile(ds[k].values, 99)) for k in panels)
    titles = {"theory_n2": "exact $n_2(t_1, t_2)$", "mc_n2": "Monte Carlo $n_2(t_1, t_2)$"}
    for ax, k in zip(axes[0], panels, strict=True):
        im = ax.pcolormesh(e, e, ds[k].values.T, vmin=0, vmax=vmax, cmap="magma")
        ax.set_title(titles[k], fontsize=9)
        ax.set_xlabel(_axis_label(ds, "n2_t1", model))
        ax.set_ylabel(_axis_label(ds, "n2_t2", model))
        ax.set_title(titles[k], fontsize=9)
        ax.set_aspect("equal")
    fig.colorbar(im, ax=axes[0], label=f"$n_2$ [1/{units_of(model, 'time')}$^2$]")
    fig.suptitle(f"{ds.attrs['title']}\n{_subtitle(study, fig.get_figwidth())}", fontsize=9)
    return fig


def _time_series(plt, ds, study, model):
    names = [n for n in ("x", "v") if f"series_{n}" in ds]
    fig, axes = plt.subplots(
        len(names),
        1,
        figsize=(8, 2.4 * len(names) + 1),
        sharex=True,
        layout="constrained",
        squeeze=False,
    )
    t = ds["series_t"].values[0]
    ok = np.isfinite(t)
    t = t[ok]
    slipping = ds["series_slipping"].values[0][ok].astype(bool)
    ylabels = {
        "x": f"position $x$ [{units_of(model, 'length')}]",
        "v": f"velocity $v$ [{units_of(model, 'length')}/{units_of(model, 'time')}]",
    }
    for ax, n in zip(axes[:, 0], names, strict=True):
        y = ds[f"series_{n}"].values[0][ok]
        # a stick runs from a sample with slipping False to the next sample (the release)
        ax.plot(t, y, color="tab:blue", lw=0.9, label="slip" if n == names[0] else None)
        starts = np.flatnonzero(~slipping[:-1])
        segs = np.full((starts.size, 3, 2), np.nan)
        segs[:, 0] = np.c_[t[starts], y[starts]]
        segs[:, 1] = np.c_[t[starts + 1], y[starts + 1]]
        stick_t, stick_y = segs[:, :, 0].ravel(), segs[:, :, 1].ravel()
        ax.plot(stick_t, stick_y, color="tab:red", lw=2.0, label="stick" if n == names[0] else None)
        ax.set_ylabel(ylabels[n])
        if n == "v":
            level = float(np.asarray(model.stick_level))
            ax.axhline(level, color="k", ls="--", lw=0.8, label="$v = v_b$ (stick level)")
        ax.legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel(f"time $t$ [{units_of(model, 'time')}]")
    fig.suptitle(
        f"{ds.attrs['title']}: stick-slip motion of one path\n"
        + _subtitle(study, fig.get_figwidth()),
        fontsize=9,
    )
    return fig


def _phase(plt, ds, study, model):
    """The first slip of one, two and three orbits in the (x, v) plane, as in fig. 7."""
    fig, ax = plt.subplots(figsize=(6.5, 5.5), layout="constrained")
    styles = {1: ("--", "tab:blue"), 2: ("-", "tab:red"), 3: ("-.", "tab:green")}
    if "orbit_k" in ds:
        period = float(ds["orbit_period"])
        for i, k in enumerate(ds["orbit_k"].values):
            t = ds["orbit_t"].values[i]
            ok = np.isfinite(t)
            ls, c = styles[int(k)]
            name = "fundamental orbit" if k == 1 else f"{int(k)}-fold orbit"
            ax.plot(
                ds["orbit_x"].values[i][ok],
                ds["orbit_v"].values[i][ok],
                ls=ls,
                color=c,
                lw=1.2,
                label=f"{name}: $T_{{sl}}$ = {t[ok][-1]:.3g}",
            )
        ax.plot([], [], " ", label=f"(deterministic period $2\\pi/\\omega$ = {period:.3g})")
    else:
        ax.text(
            0.5,
            0.5,
            "no slip of one to three orbits in the cycle runs",
            transform=ax.transAxes,
            ha="center",
        )
    level = float(np.asarray(model.stick_level))
    ax.axhline(level, color="k", lw=0.8, ls=":", label="$v = v_b$ (stick)")
    ax.set_xlabel(f"position $x$ [{units_of(model, 'length')}]")
    ax.set_ylabel(f"velocity $v$ [{units_of(model, 'length')}/{units_of(model, 'time')}]")
    ax.legend(fontsize=8)
    _title(ax, ds, study)
    return fig


def _chain_series(plt, ds, study):
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True, layout="constrained")
    t = ds["chain_time"].values
    axes[0].plot(
        t,
        ds["chain_mean_velocity"].values[0],
        lw=0.7,
        color="tab:blue",
        label="mean sliding velocity",
    )
    axes[0].set_ylabel("$\\langle V_i \\rangle$ [velocity units]")
    axes[1].plot(
        t,
        ds["chain_slipping"].values[0],
        lw=0.7,
        color="tab:red",
        label="fraction of blocks slipping",
    )
    axes[1].set_ylabel("fraction slipping")
    axes[1].set_xlabel("time $t$ [time units]")
    for ax in axes:
        ax.legend(fontsize=8, loc="upper right")
    fig.suptitle(
        f"{ds.attrs['title']}: chain 0\n{_subtitle(study, fig.get_figwidth())}", fontsize=9
    )
    return fig


def _events(plt, ds, study, q, model):
    fig, ax = plt.subplots(figsize=(6.5, 4.5), layout="constrained")
    x, y, se = ds[q].values, ds[f"mc_{q}"].values, ds[f"mc_{q}_se"].values
    ok = y > 0
    label = f"{int(ds[f'n_{q}'])} events ({study.simulation.n_paths} chains)"
    ax.errorbar(x[ok], y[ok], yerr=se[ok], fmt="o", ms=3, color="k", lw=0.8, label=label)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(_axis_label(ds, q, model))
    head = {"event_size": "$P(s)$", "event_duration": "density", "event_interval": "density"}[q]
    unit = "" if q == "event_size" else f" [1/{units_of(model, 'time')}]"
    ax.set_ylabel(head + unit)
    ax.legend(fontsize=8)
    _title(ax, ds, study)
    return fig


def _sweep(plt, ds, study):
    path = list(study.sweep.parameters)[0]
    x = ds[path].values
    name = path.split(".")[-1]
    panels = [c for c in ("fraction_stuck", "mean_slip_time", "mean_period") if c in ds]
    l1s = [v for v in ds.data_vars if v.startswith("l1_") and "method" in ds[v].dims]
    if "event_rate" in ds:
        panels.append("event_rate")
    n = len(panels) + (1 if l1s else 0)
    fig, axes = plt.subplots(
        n, 1, figsize=(6.5, 2.2 * n + 0.8), sharex=True, layout="constrained", squeeze=False
    )
    axes = axes[:, 0]
    ylabels = {
        "fraction_stuck": "fraction stuck\nbefore $t_{max}$",
        "mean_slip_time": "mean $T_{sl}$ of paths\nstuck by $t_{max}$ [time units]",
        "mean_period": "mean $T$ of paths\nstuck by $t_{max}$ [time units]",
        "event_rate": "events per time unit",
    }
    for ax, c in zip(axes, panels, strict=False):
        err = ds[c + "_se"].values if c + "_se" in ds else None
        ax.errorbar(x, ds[c].values, yerr=err, fmt="o-", ms=4, color="k", lw=1, label="Monte Carlo")
        ax.set_ylabel(ylabels[c])
        ax.legend(fontsize=8)
    if l1s:
        ax = axes[-1]
        for v in l1s:
            for i in range(ds.sizes["method"]):
                ax.plot(
                    x,
                    ds[v].values[:, i],
                    "o",
                    ms=3,
                    color=COLORS[i % 6],
                    ls="-" if v == "l1_slip_time" else "--",
                    label=f"{ds['method_label'].values[i]}: {v.removeprefix('l1_')}",
                )
        ax.set_yscale("log")
        ax.set_ylabel("L1 error against\nthe simulation")
        ax.legend(fontsize=7)
    axes[-1].set_xlabel(f"{name}  ({path})")
    fig.suptitle(
        f"{ds.attrs['title']}: sweep over {path}\n{_subtitle(study, fig.get_figwidth())}",
        fontsize=9,
    )
    return fig
