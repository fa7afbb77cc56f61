"""The two-parameter slider fit through the measurement: its time and estimates with the
forward measurement cut about the slips (the default), with every sample synthesised
(`sticks="whole"`), and with an earlier tree of the project, in the same run.

    python benchmarks/fit_forward.py [--base REV] [--n-sim 1000] [--json out.json]

The fit: the measured slider (`examples/data/slider_paper_on_paper/k168Nm_v42.mat`, 252
cycles, as `examples/slider_fit.py` reads it), the Langevin model with a fixed threshold
(x0 = 1 in the reference slider's units), `omega0` and `D` free in that example's boxes,
zeta and tau fixed as there, `n_sim` 1000, seed 1, `check=False` (estimate and intervals).

Each configuration first measures 1000 model cycles once (compiling what the fit runs),
then fits, timed by wall clock and CPU time. `--base REV` (default: the tree before the cut
forward measurement) runs the same fit from that commit's sources, checked out in a
temporary git worktree, in a subprocess of its own (the process is the only difference:
both warm alike). Ratios are the base's and the whole trace's times over the cut one's;
the estimates' differences are in units of the cut fit's interval half-widths.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time
import warnings

ROOT = pathlib.Path(__file__).resolve().parents[1]
BASE = "6c2a2da"  # the tree before the cut forward measurement


def slider_problem():
    """The fit's data and settings, `(cycles, slider, known, free)`, after measuring 1000
    model cycles once (compiling what the fit runs), with whichever `stickslip` this
    process imports."""
    sys.path.insert(0, str(ROOT / "examples"))
    from slider_fit import BOX, TAU, ZETA, reference_slider
    from slider_trace import extract, load

    import stickslip as ss
    from stickslip._inference import measurement as meas

    t, force = load("k168Nm_v42.mat")
    cycles, _ = extract(t, force)
    slider = reference_slider(cycles)
    known = dict(zeta=ZETA, v_b=slider.dimensionless()["v_b"], tau=TAU, x0=1.0)
    free = {"omega0": BOX["omega0"], "D": BOX["D"]}
    model = ss.get_model("langevin")(omega0=1.2, D=0.4, **known)
    meas.measured_cycles(model, ss.Measurement.from_cycles(cycles, scales=slider), 1000, 0)
    return cycles, slider, known, free


def fit_once(sticks: str, n_sim: int) -> dict:
    """Warm, then fit; the estimates, intervals and times (run in this process, with
    whichever `stickslip` it imports)."""
    import stickslip as ss
    from stickslip._inference import measurement as meas

    if sticks == "whole":  # every sample, in a tree that can cut
        import functools

        meas.measured_cycles = functools.partial(meas.measured_cycles, sticks="whole")
    cycles, slider, known, free = slider_problem()
    t0, c0 = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = ss.fit("langevin", cycles, free, known, n_sim=n_sim, seed=1, scales=slider,
                   check=False)  # fmt: skip
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return dict(
        sticks=sticks, wall=wall, cpu=cpu, evaluations=r.diagnostics.get("evaluations"),
        estimate={k: float(v) for k, v in r.estimate.items()},
        interval={k: [float(a), float(b)] for k, (a, b) in r.ci.items()},
    )  # fmt: skip


def run_base(rev: str, n_sim: int) -> dict:
    """`fit_once` from the sources of `rev`, in a subprocess."""
    with tempfile.TemporaryDirectory() as tmp:
        tree = pathlib.Path(tmp) / "base"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), rev],
                       check=True, capture_output=True)  # fmt: skip
        try:
            env = dict(os.environ, PYTHONPATH=str(tree / "src"))
            out = subprocess.run(
                [sys.executable, __file__, "--worker", "base", "--n-sim", str(n_sim)],
                env=env, check=True, capture_output=True, text=True,
            )  # fmt: skip
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)],
                           check=False, capture_output=True)  # fmt: skip
    row = json.loads(out.stdout.strip().splitlines()[-1])
    row["sticks"] = f"base {rev}"
    return row


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--base", default=BASE, help="an earlier commit to compare with")
    parser.add_argument("--n-sim", type=int, default=1000)
    parser.add_argument("--json", default=None)
    parser.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:  # "cut", "whole" or "base" (the earlier tree's own forward model)
        print(json.dumps(fit_once(args.worker, args.n_sim)))
        return
    rows = []
    for sticks in ("cut", "whole"):  # each in a process of its own, like the base
        command = [sys.executable, __file__, "--worker", sticks, "--n-sim", str(args.n_sim)]
        out = subprocess.run(command, check=True, capture_output=True, text=True)
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
    if args.base:
        rows.append(run_base(args.base, args.n_sim))
    cut = rows[0]
    half = {k: 0.5 * (b - a) for k, (a, b) in cut["interval"].items()}
    print(f"two-parameter slider fit, n_sim {args.n_sim}; times in s (wall, CPU)")
    for r in rows:
        est = r["estimate"]
        shift = ", ".join(f"{k} {est[k]:.4g} ({(est[k] - cut['estimate'][k]) / half[k]:+.2f} hw)"
                          for k in half)  # fmt: skip
        ratio = r["wall"] / cut["wall"]
        print(f"{r['sticks']:>14s}: {r['wall']:7.1f} {r['cpu']:7.1f}  x{ratio:5.2f}  "
              f"{r['evaluations']} points; {shift}")  # fmt: skip
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
