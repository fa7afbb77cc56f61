"""Where a fit's intervals lose the estimator's spread, read from replicates of its data:
data sets of the data's size simulated at the estimate through the data's measurement (a
continuous trace, extracted as the data were: every dependence between rows, of any lag,
and whatever the extraction takes over the whole trace), scored at the kept fit's own
design points (its simulated cycles kept: `fit_independent.py --keep DIR`).

- `--meat`: the variance of the replicates' total score (the difference between the
  design's +-1 step points along each axis, the same secant the fit's per-cycle scores
  take) against the mean of their sandwich's J (lag 1, as the fit takes it for a random
  threshold): the eigenvalues of J^-1 var(score), about 1 where the meat holds the
  scores' whole variance (each a variance over `--replicates` draws: sd ~ sqrt(2 / B)).
- default: each replicate's vertex over the design (the fit's polynomial, both seeds,
  their mean, as the fit takes its estimate): how many replicates have one within the
  design's two steps, and how the interval from the sd of those that have one covers the
  truth.

    python benchmarks/interval_replicates.py "kept/random-stick-*.pkl" [--replicates 60]
    python benchmarks/interval_replicates.py "kept/random-stick-[0-2].pkl" --meat --replicates 100
"""

from __future__ import annotations

import argparse
import glob
import math
import pickle
import warnings

import numpy as np

from stickslip._inference import intervals as iv
from stickslip._inference.forward import simulate_values
from stickslip._inference.likelihood import scored_samples
from stickslip._inference.surface import polynomial_vertex, quadratic_design

SEED = 900_000  # the replicates' seeds: SEED + b, apart from any fit's


def _kept(path):
    with open(path, "rb") as f:
        kept = pickle.load(f)
    r, truth = kept["fit"], kept["truth"]
    d = r.diagnostics
    names, scales = list(r.estimate), d["scales"]

    def coords(values):
        return np.array([math.log(values[k]) if scales[k] == "log" else values[k]
                         for k in names])  # fmt: skip

    return r, d, names, coords(truth), coords(r.estimate)


def _replicate(r, d, b):
    """Replicate b: the data's size in cycles, simulated at the estimate and measured."""
    n = next(iter(r.data.values())).size
    rep = simulate_values(r.model, n, None, None, SEED + b, d["measurement"])
    return {k: np.asarray(rep[k], float)[:n] for k in r.data}


def _scores(data, d, seed_index):
    """Per design point, the per-cycle terms summed over the columns (None: refused)."""
    out = []
    for sim in d["design"]["samples"][seed_index]:
        t = scored_samples(data, sim, d["bandwidth"], d["measurement"])
        out.append(None if t is None else np.sum([t[k] for k in data], axis=0))
    return out


def _secants(nominal, design, centre, scores):
    """The total score's secant along each axis over the design's +-1 step points."""
    out = []
    for i in range(centre.size):
        plus, minus = iv.axis_ends(nominal, centre, i)
        out.append((np.sum(scores[plus]) - np.sum(scores[minus]))
                   / (design[plus, i] - design[minus, i]))  # fmt: skip
    return np.array(out)


def meat(path, replicates) -> None:
    r, d, names, _, _ = _kept(path)
    des = d["design"]
    points, centre, steps = (np.array(des[k]) for k in ("points", "centre", "steps"))
    nominal = quadratic_design(centre, steps)
    totals, Js = [], []
    for b in range(replicates):
        scores = _scores(_replicate(r, d, b), d, 0)
        if any(s is None for s in scores):
            continue
        G = iv._score_matrix(nominal, points, centre, scores)
        totals.append(_secants(nominal, points, centre, scores))
        Js.append(iv._meat(G, G, 1))
    V, J = np.cov(np.array(totals).T), np.mean(Js, axis=0)
    ratio = np.sort(np.linalg.eigvals(np.linalg.solve(J, V)).real)
    print(f"{path}: {len(totals)} replicates; eigenvalues of J^-1 var(score): "
          + ", ".join(f"{x:.2f}" for x in ratio)
          + "; diagonal ratios " + ", ".join(
              f"{k} {v:.2f}" for k, v in zip(names, np.diag(V) / np.diag(J), strict=True)),
          flush=True)  # fmt: skip


def vertices(path, replicates) -> dict:
    r, d, names, truth, estimate = _kept(path)
    des = d["design"]
    points, centre, steps = (np.array(des[k]) for k in ("points", "centre", "steps"))
    found = []
    for b in range(replicates):
        rep = _replicate(r, d, b)
        shifts = []
        for s in (0, 1):
            values = [-np.inf if sc is None else float(np.sum(sc)) for sc in _scores(rep, d, s)]
            shift, _ = polynomial_vertex(points - centre, np.array(values), steps)
            shifts.append(shift)
        if all(x is not None for x in shifts):
            found.append(centre + 0.5 * (shifts[0] + shifts[1]))
    sd = np.std(found, axis=0) if len(found) > 1 else np.full(len(names), np.nan)
    covered = np.abs(estimate - truth) <= iv.Z95 * sd
    print(
        f"{path}: {len(found)} of {replicates} replicates with a vertex; their sd "
        + ", ".join(f"{k} {v:.3f}" for k, v in zip(names, sd, strict=True)),
        flush=True,
    )
    return dict(names=names, found=len(found), covered=covered)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("kept", help="a glob of kept fits")
    parser.add_argument("--replicates", type=int, default=60)
    parser.add_argument("--meat", action="store_true")
    args = parser.parse_args()
    paths = sorted(glob.glob(args.kept))
    if not paths:
        raise SystemExit(f"no kept fits match {args.kept}")
    warnings.simplefilter("ignore")  # (the replicates' extraction notes)
    if args.meat:
        for p in paths:
            meat(p, args.replicates)
        return
    rows = [vertices(p, args.replicates) for p in paths]
    names = rows[0]["names"]
    covered = np.sum([row["covered"] for row in rows], axis=0)
    found = [row["found"] for row in rows]
    print(
        f"{len(rows)} fits: replicates with a vertex {min(found)}-{max(found)} of "
        f"{args.replicates} (median {int(np.median(found))}); covered by the vertices' sd: "
        + ", ".join(f"{k} {c}/{len(rows)}" for k, c in zip(names, covered, strict=True))
    )


if __name__ == "__main__":
    main()
