"""How the rate-and-state plugin's force drop and stick time move with the spring, over a
grid of its law's parameters: the noise-free limit cycle (the second half of 40 s of
cycles, their medians) at k = 168, 400 and 1002 N/m, 42 um/s, the rig's 30.7 g and
0.301 N. The public grid's measured drops rise with the spring (10.2 mN at 168 N/m, 23.5
mN at 1002 N/m); this says whether one parameter set of the law can make them do so.

    python benchmarks/rate_and_state_trend.py [--t-max 40]
"""

from __future__ import annotations

import argparse
import itertools
import time
import warnings

import numpy as np

import stickslip as ss

SPRINGS = (168.0, 400.0, 1002.0)  # N/m
RIG = dict(mass=0.0307, v_b=42e-6, normal_force=0.301, mu0=0.3, v_ref=1e-6, law="aging")


def limit_cycle(k: float, a: float, b: float, d_c: float, t_max: float):
    """(k_c, median drop, median stick time) of the noise-free cycles' second half; nan
    where the spring is past k_c (steady sliding) or no cycle ends."""
    m = ss.get_model("rate-and-state")(stiffness=k, a=a, b=b, d_c=d_c, D=0.0, **RIG)
    kc = m.critical_stiffness()
    if not k < kc:
        return kc, np.nan, np.nan
    c = ss.simulate_cycles(m, 1, 1e-3, t_max).cycles
    drop = np.asarray(c["force_drop"], float)
    stick = np.asarray(c["stick_time"], float)
    drop, stick = drop[np.isfinite(drop)], stick[np.isfinite(stick)]
    if drop.size < 2:
        return kc, np.nan, np.nan
    return kc, float(np.median(drop[drop.size // 2 :])), float(np.median(stick[stick.size // 2 :]))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--t-max", type=float, default=40.0, help="simulated seconds a run")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    print("| a | b/a | d_c (um) | " + " | ".join(f"drop, stick at {k:.0f} N/m" for k in SPRINGS)
          + " | the drop with k |")  # fmt: skip
    print("|---|---|---|" + "---|" * len(SPRINGS) + "---|")
    counts = {"falls": 0, "rises": 0, "neither": 0}
    for a, ratio, d_c in itertools.product((0.005, 0.01), (1.2, 1.5, 2.0), (0.3e-6, 1e-6)):
        cells, drops = [], []
        for k in SPRINGS:
            kc, drop, stick = limit_cycle(k, a, a * ratio, d_c, args.t_max)
            if np.isnan(drop):
                cells.append(f"steady (k_c {kc:.0f})" if k >= kc else "no cycle")
            else:
                cells.append(f"{drop * 1e3:.2f} mN, {stick:.3f} s")
                drops.append(drop)
        verdict = "-"
        if len(drops) >= 2:
            steps = np.diff(drops)
            verdict = "falls" if np.all(steps < 0) else "rises" if np.all(steps > 0) else "neither"
            counts[verdict] += 1
        print(f"| {a} | {ratio} | {d_c * 1e6:g} | " + " | ".join(cells) + f" | {verdict} |",
              flush=True)  # fmt: skip
    print("\nparameter sets with stick-slip at two springs or more: the drop "
          + ", ".join(f"{k} with k in {v}" for k, v in counts.items())
          + f"; {time.perf_counter() - t0:.0f} s")  # fmt: skip


if __name__ == "__main__":
    main()
