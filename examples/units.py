"""A real slider in SI units: its model in the paper's variables, and results in s, m, N.

    python examples/units.py [--paths 2000]

The rig of the measured traces (shared data `slider_paper_on_paper`, README): a 30.7 g
paper slider pulled at 42 um/s through a 168 N/m spring, peak force about 0.32 m g and
force drop about 0.035 m g, varying from cycle to cycle. The damping and the friction
noise below are *illustrative* (the data do not state them; a fit would estimate them):
a viscous 0.1 kg/s and a friction force of 1 mN rms correlated over 1 ms.
"""

from __future__ import annotations

import argparse

import numpy as np

from stickslip.units import Slider

M, K, V, G = 0.0307, 168.0, 42e-6, 9.81  # kg, N/m, m/s, m/s^2
PEAK, DROP = 0.32 * M * G, 0.035 * M * G  # N
RMS, TAU = 1e-3, 1e-3  # friction noise: rms force (N) and correlation time (s)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--paths", type=int, default=2000, help="simulated cycles")
    args = parser.parse_args(argv)

    slider = Slider(
        mass=M, stiffness=K, v_b=V, static_friction=None,
        kinetic_friction=PEAK - DROP / 2,  # undamped, the drop is 2 (F_s - F_k)
        damping=0.1, noise=RMS**2 * TAU, noise_time=TAU,  # S = rms^2 tau_c (N^2 s)
        threshold=("normal", {"mean": PEAK, "sd": 0.1 * DROP}),
    )  # fmt: skip
    print(slider.describe())

    run = slider.simulate(args.paths, seed=0)
    print(f"\n{len(run)} simulated cycles ({np.isfinite(run['slip_time']).mean():.1%} stuck):")
    for name in ("slip_time", "stick_time", "period", "peak_force", "force_drop"):
        x = run[name][np.isfinite(run[name])]
        q = np.percentile(x, [10, 50, 90])
        unit = run.units[name]
        print(f"  {name:<12} median {q[1]:.4g} {unit}  (10-90 %: {q[0]:.4g} - {q[2]:.4g})")


if __name__ == "__main__":
    main()
