"""Where a fit through the measurement spends its time, stage by stage, in this tree and an
earlier one (the same fit as `fit_forward.py`: the measured slider, omega0 and D free,
n_sim 1000).

    python benchmarks/fit_stages.py [--base REV] [--json out.json]

Each tree's fit runs once warm under cProfile (in a process of its own; the earlier tree
from a temporary git worktree); its cumulative times are read per stage:

- simulation: `simulate_cycles` / `counted_cycles` (the successive cycles, their recorded
  slips) and, in earlier trees, the pilot `simulate` that set the paths' duration;
- synthesis: the rest of `measured_trace` (the sampling grid, the noise and spikes, the
  interpolation; the cut trace's notch);
- extraction: `extract_cycles` / the cut trace's `extract_slips`, of which the slips'
  shape fits (`_lm`, batched; now the compiled `_shape_fit.fit_windows`) apart;
- density and likelihood: the rest of each point's log-likelihood;
- the rest of the fit (search, design, intervals).

Seconds per evaluated point, and each stage's share. cProfile adds its own overhead to
every Python call (more to the many small ones), so the shares, not the totals, are the
result; the totals are `fit_forward.py`'s. The fit runs in one thread here (cProfile sees
only its own: the paths and shape fits a second thread takes would count as the wait).
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pathlib
import pstats
import subprocess
import sys
import tempfile
import warnings

ROOT = pathlib.Path(__file__).resolve().parents[1]
BASE = "6c2a2da"  # the tree before the cut forward measurement
STAGES = {  # stage: (file suffix, function) whose cumulative time it is
    "simulate_cycles": [("_simulate/cycles.py", "simulate_cycles"),
                        ("_simulate/cycles.py", "counted_cycles")],
    "pilot": [("_simulate/driver.py", "simulate"), ("_simulate/__init__.py", "simulate")],
    "measured_trace": [("_inference/measurement.py", "measured_trace")],
    "extraction": [("_extract/_extract.py", "extract_cycles"),
                   ("_extract/_force.py", "extract_slips")],
    "shape fits": [("_extract/_force.py", "_lm"), ("_extract/_shape_fit.py", "fit_windows")],
    "measured_cycles": [("_inference/measurement.py", "measured_cycles")],
    "loglik": [("_inference/estimator.py", "_loglik")],
    "fit": [("_inference/fit.py", "fit")],
}


def profiled() -> dict:
    """The fit of `fit_forward.py` under cProfile: cumulative seconds per entry of STAGES
    (the outermost call's) and the points evaluated."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from fit_forward import slider_problem

    import stickslip as ss

    cycles, slider, known, free = slider_problem()
    # one thread: cProfile sees only the thread it runs in (a path or a half of the shape
    # fits in a second thread would count as the wait for it)
    import importlib

    for name in ("stickslip._cpu", "stickslip._extract._shape_fit"):
        try:
            module = importlib.import_module(name)
        except ImportError:  # (an earlier tree)
            continue
        if hasattr(module, "usable_cores"):
            module.usable_cores = lambda: 1
    profile = cProfile.Profile()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        profile.enable()
        r = ss.fit("langevin", cycles, free, known, n_sim=1000, seed=1, scales=slider,
                   check=False)  # fmt: skip
        profile.disable()
    stats = pstats.Stats(profile).stats
    out = {}
    for stage, keys in STAGES.items():
        total = 0.0
        for (file, _line, name), (_, _, _, cum, _) in stats.items():
            if any(file.endswith(f) and name == n for f, n in keys):
                total = max(total, cum)  # (the outermost: recursion counts once)
        out[stage] = total
    out["points"] = int(r.diagnostics.get("evaluations"))
    return out


def table(row: dict) -> dict:
    """Stages per point: the nested ones taken apart."""
    n = row["points"]
    sim = row["simulate_cycles"] + row["pilot"]
    synthesis = max(row["measured_trace"] - sim, 0.0)
    shape = row["shape fits"]
    extraction = row["extraction"] - shape
    density = row["loglik"] - row["measured_cycles"]
    rest = row["fit"] - row["loglik"]
    return {"simulation": sim / n, "synthesis": synthesis / n, "extraction less shape fits":
            extraction / n, "shape fits": shape / n, "density and likelihood": density / n,
            "rest of the fit": rest / n, "total": row["fit"] / n}  # fmt: skip


def in_subprocess(src: pathlib.Path | None) -> dict:
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = str(src)
    out = subprocess.run([sys.executable, __file__, "--worker"], env=env, check=True,
                         capture_output=True, text=True)  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--base", default=BASE)
    parser.add_argument("--json", default=None)
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(profiled()))
        return
    rows = {"this tree": in_subprocess(None)}
    with tempfile.TemporaryDirectory() as tmp:
        tree = pathlib.Path(tmp) / "base"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree),
                        args.base], check=True, capture_output=True)  # fmt: skip
        try:
            rows[f"base {args.base}"] = in_subprocess(tree / "src")
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)],
                           check=False, capture_output=True)  # fmt: skip
    tables = {k: table(v) for k, v in rows.items()}
    names = list(tables)
    points = ", ".join(f"{k} {rows[k]['points']}" for k in names)
    print(f"seconds per point under cProfile (points: {points}); share of the total")
    print(f"{'stage':28s}" + "".join(f"{k:>22s}" for k in names))
    for stage in next(iter(tables.values())):
        cells = "".join(
            f"{tables[k][stage]:10.3f} s ({100 * tables[k][stage] / tables[k]['total']:3.0f} %)"
            .rjust(22) for k in names
        )  # fmt: skip
        print(f"{stage:28s}{cells}")
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps({"rows": rows, "tables": tables}, indent=1))


if __name__ == "__main__":
    main()
