"""Where a random threshold's intervals fail on the independent generator's traces: checks
on the kept fits (`fit_independent.py --case random --release stick --n-sim 4000 --keep
kept`). `--moments` and `--plain` rebuild the fit's rule from the kept design samples;
`--realised` makes the traces again, `--line` and `--seeds` simulate.

- `--realised`: the thresholds each trace drew (the generator's own, in the model's
  units) against the fit's estimate, both as the truncated law's own mean and sd (the
  plugin's `"normal"` law is an untruncated normal's mean and sd, truncated at zero): how
  far the estimates spread beyond what the trace itself drew, and whether they follow it.
- `--moments`: the fit's intervals carried to the truncated law's mean and sd (the delta
  method on the fit's covariance): covered, and z's sd, over the fits with an interval.
- `--line`: the bread's weakest direction followed on a line through the design's centre
  (1, 2, 4, 8 design steps each side, to the box, until both seeds' mean log-likelihood
  falls by 8): the curvature a quadratic through those points gives against the
  eigenvalue the design gave (per design step squared), and the coverage with it in the
  bread. Two simulations a point (~15 s a fit).
- `--plain`: the fit's rule with a plain quadratic (no cubic terms) through both seeds'
  mean values for the vertex as well as the bread, and for the jackknife's and each
  seed's vertices: how many fits then give an interval (a vertex within two steps,
  concave), and covered.
- `--seeds`: 2 (l(estimate) - l(truth)) at the fit's seed and n_sim, at two other seeds,
  and at those seeds with 4 x n_sim: whether the likelihood's preference for a point off
  the truth is the simulation's noise (run it on a few fits: ~30 s each).

    python benchmarks/ridge_checks.py "kept/random-stick-*.pkl" --realised --moments --line
    python benchmarks/ridge_checks.py "kept/random-stick-*.pkl" --plain
    python benchmarks/ridge_checks.py kept/random-stick-{0,8,9,21}.pkl --seeds
"""

from __future__ import annotations

import dataclasses
import glob
import importlib.util
import math
import pathlib
import pickle
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from interval_rules import pieces  # noqa: E402
from truncated_moments import moments as _moments  # noqa: E402

from stickslip._inference import intervals as iv  # noqa: E402
from stickslip._inference.likelihood import cycle_log_likelihood  # noqa: E402

MEAN, SD = "threshold_params.mean", "threshold_params.sd"
LINE_FALL, LINE_REACH = 8.0, 8.0


def truncated(mean, sd) -> np.ndarray:
    """The mean and sd of a normal (mean, sd) truncated to positive values."""
    return np.array([mean, 0.0] if sd <= 0 else _moments(mean, sd))


def _index(path) -> int:
    return int(pathlib.Path(path).stem.rsplit("-", 1)[1])


def _study():
    """`fit_independent.py`, the study whose kept fits these are (its generator, boxes)."""
    spec = importlib.util.spec_from_file_location("fit_independent", HERE / "fit_independent.py")
    fi = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fi)
    return fi


def realised(paths) -> None:
    fi = _study()
    rig = fi.rig_of("random")
    drawn, fitted = [], []
    for path in paths:
        with open(path, "rb") as f:
            kept = pickle.load(f)
        truth, e = kept["truth"], kept["fit"].estimate
        scale = rig.gap_sd / truth[SD]  # newtons per model unit of the threshold
        _, _, true = fi.gen.make_trace(30_000 + _index(path), fi.DURATION, rig)
        g = (np.asarray(true["threshold"]) - rig.kinetic_friction - rig.damping * rig.v_b) / scale
        drawn.append([g.mean(), g.std(ddof=1)])
        fitted.append(truncated(e[MEAN], e[SD]))
    drawn, fitted = np.array(drawn), np.array(fitted)
    law = truncated(truth[MEAN], truth[SD])
    for i, what in enumerate(("mean", "sd")):
        print(f"truncated law's {what}: truth {law[i]:.3f}; drawn {drawn[:, i].mean():.3f} "
              f"(sd over traces {drawn[:, i].std():.3f}); fitted {fitted[:, i].mean():.3f} "
              f"(sd {fitted[:, i].std():.3f}, {fitted[:, i].std() / drawn[:, i].std():.1f}x the "
              f"drawn's); correlation fitted-drawn "
              f"{np.corrcoef(fitted[:, i], drawn[:, i])[0, 1]:.2f}")  # fmt: skip


def moments(found, label="fit's intervals") -> None:
    law = truncated(found[0]["truth_model"][MEAN], found[0]["truth_model"][SD])
    names = found[0]["names"]
    i, j = names.index(MEAN), names.index(SD)
    z = []
    for f in found:
        if not f["interval"]:
            continue

        def g(u):
            return truncated(math.exp(u[i]), u[j])  # fit coordinates: log mean, linear sd

        J = np.zeros((2, len(names)))
        for k in (i, j):
            e = np.zeros(len(names))
            e[k] = 1e-5
            J[:, k] = (g(f["u"] + e) - g(f["u"] - e)) / 2e-5
        z.append((g(f["u"]) - law) / np.sqrt(np.diag(J @ f["fits"] @ J.T)))
    z = np.array(z)
    covered = np.sum(np.abs(z) < iv.Z95, axis=0)
    print(f"{label}, as the truncated law's mean and sd: covered {covered[0]} and {covered[1]} "
          f"of the {len(z)} fits with an interval ({len(found)} fits); z's sd {z[:, 0].std():.2f}, "
          f"{z[:, 1].std():.2f}")  # fmt: skip


def line(path, f) -> tuple[dict, float, float]:
    """The plain bread's rule (`fit`'s when this was measured, 2026-12-06; `fit` now takes
    the larger of it and the cubic bread's) with the bread's weakest eigenvalue replaced by
    the curvature along its line; (that fit's entry, the eigenvalue before, after)."""
    with open(path, "rb") as fh:
        r = pickle.load(fh)["fit"]
    d = r.diagnostics
    parts, names = f["parts"], f["names"]
    plain, surface = parts["plain"], parts["surface"]
    scales = d["scales"]
    seeds = (d["seed"], d["mc_noise"]["seed"])
    box = _study().problem("random", "stick")[1]  # the fits' free boxes
    lo, hi = (np.array([math.log(box[k][e]) if scales[k] == "log" else box[k][e] for k in names])
              for e in (0, 1))  # fmt: skip

    def mean_value(u):
        params = {k: math.exp(x) if scales[k] == "log" else float(x)
                  for k, x in zip(names, u, strict=True)}  # fmt: skip
        return float(np.mean([cycle_log_likelihood(r, params=params, seed=s).sum() for s in seeds]))

    steps = np.asarray(plain.steps, float)
    info = -(steps[:, None] * plain.hessian * steps[None, :])
    lam, vectors = np.linalg.eigh(0.5 * (info + info.T))
    v = vectors[:, 0]
    ts, values = [0.0], [0.5 * (parts["values"][0][0] + parts["values"][1][0])]
    for side in (-1.0, 1.0):
        direction = side * v * steps
        with np.errstate(divide="ignore", invalid="ignore"):
            ends = np.where(direction > 0, hi, lo)
            reach = np.where(direction != 0, (ends - plain.centre) / direction, np.inf)
        room, t = max(float(np.min(reach)), 0.0), 1.0
        while t <= LINE_REACH:
            t = min(t, room)
            if t < 0.25:
                break
            value = mean_value(plain.centre + t * direction)
            if not np.isfinite(value):
                break
            ts.append(side * t)
            values.append(value)
            if max(values) - value >= LINE_FALL or t == room:
                break
            t *= 2.0
    order = np.argsort(ts)
    print(
        f"{pathlib.Path(path).stem}: along the weakest direction (steps: fall from the "
        "best) " + ", ".join(f"{ts[k]:+.2g}: {max(values) - values[k]:.1f}" for k in order)
    )
    t = np.asarray(ts)
    X = np.stack([np.ones_like(t), t, 0.5 * t**2], axis=1)
    after = -float(np.linalg.lstsq(X, np.asarray(values), rcond=None)[0][2])
    entry = dict(f)
    if min(ts) >= 0 or max(ts) <= 0 or after <= 0:
        entry["interval"] = False
        return entry, float(lam[0]), after
    info = info + (after - lam[0]) * np.outer(v, v)
    bread = dataclasses.replace(plain, hessian=-info / np.outer(steps, steps))
    fits, _, _ = iv.sandwich_covariance(bread, names, parts["scores2"], parts["lag"])
    big = np.full(len(names), 1e9)
    u, cov, _ = iv.combine_seeds(surface, parts["shift2"], fits, parts["blocks"], -big, big)
    entry.update(u=u, fits=cov)
    return entry, float(lam[0]), after


def seeds(paths) -> None:
    for path in paths:
        with open(path, "rb") as f:
            kept = pickle.load(f)
        r, truth = kept["fit"], kept["truth"]
        estimate = {k: r.estimate[k] for k in truth}
        n = r.diagnostics["n_sim"]
        cells = []
        for n_sim, seed in ((n, None), (n, 11), (n, 12), (4 * n, 11), (4 * n, 12)):
            at = [cycle_log_likelihood(r, params=p, n_sim=n_sim, seed=seed).sum()
                  for p in (estimate, truth)]  # fmt: skip
            cells.append(f"{n_sim} {'fit' if seed is None else seed}: {2 * (at[0] - at[1]):.1f}")
        print(f"{pathlib.Path(path).stem}: 2 dlogL (estimate - truth) at n_sim, seed: "
              + "; ".join(cells))  # fmt: skip


def _plain_vertex(du, values, steps):
    """The vertex and Hessian of a plain quadratic fitted to `values` at `du` (`None` for
    the vertex where it is not concave or lies past two steps)."""
    from stickslip._inference.surface import _curvature, _pairs, polynomial_terms

    p = du.shape[1]
    ok = np.isfinite(values)
    X = polynomial_terms(du)[:, : 1 + p + len(_pairs(p))]
    coef = np.linalg.lstsq(X[ok], np.asarray(values, float)[ok], rcond=None)[0]
    Q = _curvature(p, coef)
    if not iv.concave(Q):
        return None, Q
    x = np.linalg.solve(Q, -coef[1 : 1 + p])
    return (None if np.any(np.abs(x) > 2 * steps) else x), Q


def plain(found) -> list[dict]:
    """`--plain`: each fit's rule rebuilt on plain quadratics."""
    out = []
    for f in found:
        parts, names = f["parts"], f["names"]
        surface = parts["surface"]
        du = surface.design - surface.centre
        v1, v2 = parts["values"]
        x, Q = _plain_vertex(du, 0.5 * (v1 + v2), surface.steps)
        seeds = [_plain_vertex(du, v, surface.steps)[0] for v in (v1, v2)]
        entry = dict(f, interval=False)
        jack = []
        for blocks in parts["blocks"]:
            shifts = [_plain_vertex(du, c, surface.steps)[0] for c in np.asarray(blocks).T]
            shifts = [s for s in shifts if s is not None]
            if len(shifts) < iv.JACK_LEAST * np.shape(blocks)[1]:
                break
            dev = np.array(shifts) - np.mean(shifts, axis=0)
            jack.append((np.shape(blocks)[1] - 1) / len(shifts) * (dev.T @ dev))
        if x is None or any(s is None for s in seeds) or len(jack) < 2:
            out.append(entry)
            continue
        bread = dataclasses.replace(surface, hessian=Q)
        cov, _, _ = iv.sandwich_covariance(bread, names, parts["scores2"], parts["lag"])
        mc = 0.25 * (jack[0] + jack[1])
        half = 0.5 * (seeds[0] - seeds[1])
        excess = np.sign(half) * np.sqrt(np.maximum(half**2 - np.diag(mc), 0.0))
        entry.update(u=surface.centre + x, fits=cov + mc + np.outer(excess, excess),
                     interval=True)  # fmt: skip
        out.append(entry)
    return out


def covered(found, label) -> None:
    names = found[0]["names"]
    se = [np.sqrt(np.diag(f["fits"])) for f in found]
    hits = [sum(f["interval"] and abs(f["u"][i] - f["truth"][i]) <= iv.Z95 * s[i]
                for f, s in zip(found, se, strict=True))
            for i in range(len(names))]  # fmt: skip
    cells = ", ".join(f"{k} {c}/{len(found)}" for k, c in zip(names, hits, strict=True))
    print(f"{label}: covered {cells}; {sum(not f['interval'] for f in found)} without an interval")


def main():
    patterns = [a for a in sys.argv[1:] if not a.startswith("--")]
    paths = sorted({p for a in patterns for p in glob.glob(a)}, key=_index)
    if not paths:
        sys.exit(f"no kept fits match {' '.join(patterns)}")
    flags = [a for a in sys.argv[1:] if a.startswith("--")]
    if "--realised" in flags:
        realised(paths)
    if "--seeds" in flags:
        seeds(paths)
    if not {"--moments", "--line", "--plain"} & set(flags):
        return
    found = []
    for path in paths:
        f = pieces(path)
        with open(path, "rb") as fh:
            f["truth_model"] = pickle.load(fh)["truth"]
        found.append(f)
    covered(found, "the fit's rule")
    if "--moments" in flags:
        moments(found)
    if "--plain" in flags:
        plained = plain(found)
        none = [f["parts"]["surface"] for f in found if f["parts"]["surface"].shift is None]
        best = sum(int(np.nanargmax(sf.values)) == 0 for sf in none)
        print(f"the first seed's polynomial has no vertex in {len(none)} fits; the design's "
              f"centre is its best point in {best} of them")  # fmt: skip
        covered(plained, "plain quadratics throughout")
        if "--moments" in flags:
            moments(plained, "plain quadratics throughout")
    if "--line" in flags:
        lined, ratios = [], []
        for path, f in zip(paths, found, strict=True):
            if "rules" not in f:  # no interval: the line cannot give one either
                lined.append(f)
                continue
            entry, before, after = line(path, f)
            lined.append(entry)
            ratios.append(after / before)
        ratios = np.array(ratios)
        print(f"weakest curvature on its line over the design's: median {np.median(ratios):.2f} "
              f"(range {ratios.min():.2f}-{ratios.max():.2f}; below 1 in {np.sum(ratios < 1)} "
              f"of {ratios.size})")  # fmt: skip
        covered(lined, "with the line's curvature")
        if "--moments" in flags:
            moments(lined, "with the line's curvature")


if __name__ == "__main__":
    main()
