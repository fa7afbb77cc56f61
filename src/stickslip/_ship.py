"""Traces shipped with the package: a first run on a new machine loads them, not traces.

    python -m stickslip._ship

Tracing the simulator's stepping loop and refinement takes about 2 s of a first run's
Python time (`jax.export`; the compilation that follows is the machine's own). The traces
are portable StableHLO, keyed (`_compile._trace_file`) by the sources of stickslip and of the
model's plugin, the versions of jax, jaxlib, diffrax and equinox, the device kind and the
static arguments, so a shipped trace is used exactly where it is the trace the run would
make, and ignored elsewhere (a new library version, an edited source: the run traces).

This command makes them: it runs the built-in Langevin model's usual configurations (OU
friction noise, the exact detector, with every buffer size; white noise, the Brownian-bridge
detector; Euler-Maruyama, the grid monitor and noise-free runs at a few steps; upcrossings
recorded for the empirical estimator), the friction block with each friction law, each
threshold law of the random threshold, the chain of the docs and the examples, the
rate-and-state slider's solves (each state law, with and without noise), and the
README's main job (`examples/public_reference.yaml`: its estimator kernels too) in a new
process with an empty cache directory, then replaces
`src/stickslip/_data/traces/` with the traces that process wrote. Run it after editing a
traced source (`tests/test_cold_start.py` says when the shipped ones are stale).
"""

from __future__ import annotations

import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

# The README's main job (its simulation, cycles and estimator kernels, at its shapes), when run
# from a checkout of the repository.
MAIN_JOB = pathlib.Path(__file__).resolve().parents[2] / "examples" / "public_reference.yaml"

RUNS = """
import pathlib, sys
import stickslip as ss
base = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)
ss.simulate(ss.get_model("langevin")(**base, tau=0.1), 100_000, 0.8, 50.0, seed=1)
ss.simulate(ss.get_model("langevin")(**base, tau=0.1), 2_000, 0.1, 50.0, seed=1)
ss.simulate(ss.get_model("langevin")(**base), 20_000, 0.1, 50.0, seed=1)
# Other usual configurations, small: Euler-Maruyama, the grid monitor of the reference
# convention, noise-free runs (the in-step location's node count follows dt: a few steps).
for tau in (None, 0.1):
    ss.simulate(ss.get_model("langevin")(**base, tau=tau), 500, 0.01, 20.0, solver="euler")
    for dt in (0.01, 0.05, 0.1):
        ss.simulate(ss.get_model("langevin")(**base | {"D": 0.0}, tau=tau), 8, dt, 30.0)
for dt in (0.005, 0.01, 0.05, 0.1, 0.2):
    ss.simulate(ss.get_model("langevin")(**base, tau=0.1), 500, dt, 20.0, monitor="grid")
# White noise on the grid monitor (its in-step location's node count, 2 to 64 here, follows
# dt), and Euler-Maruyama on it.
for dt in (0.005, 0.05, 0.2, 0.4, 0.8):
    ss.simulate(ss.get_model("langevin")(**base), 500, dt, 20.0, monitor="grid")
for tau in (None, 0.1):
    ss.simulate(ss.get_model("langevin")(**base, tau=tau), 500, 0.01, 20.0, solver="euler",
                monitor="grid")
# The other built-in models: the friction block with each friction law (Euler-Maruyama, its
# solver, with OU noise), and each threshold law's release and description (their slips run
# on the Langevin model's loops above).
block = dict(k=1.0, v_b=0.5, D=0.01, tau=0.1)
laws = {"coulomb": {"static": 1.0, "kinetic": 0.8},
        "viscous": {"static": 1.0, "viscosity": 0.5, "kinetic": 0.5},
        "velocity-weakening": {"F0": 1.0, "alpha": 1.0, "sigma": 0.2},
        "stribeck": {"static": 1.0, "coulomb": 0.8, "v_stribeck": 0.2}}
from stickslip.friction import FRICTION_LAWS
assert set(laws) == set(FRICTION_LAWS), f"friction laws to ship: {sorted(FRICTION_LAWS)}"
for law, params in laws.items():
    m = ss.get_model("friction-block")(**block, friction=law, friction_params=params)
    ss.simulate(m, 500, 0.01, 20.0, seed=1)
thresholds = {"lognormal": {"median": 1.0, "sigma": 0.4}, "normal": {"mean": 1.0, "sd": 0.2},
              "uniform": {"low": 0.8, "high": 1.2}, "weibull": {"shape": 5.0, "scale": 1.0}}
from stickslip_random_threshold import THRESHOLD_LAWS
assert set(thresholds) == set(THRESHOLD_LAWS), f"threshold laws to ship: {sorted(THRESHOLD_LAWS)}"
for law, params in thresholds.items():
    m = ss.get_model("random-threshold")(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, tau=0.1,
                                         threshold=law, threshold_params=params)
    ss.simulate(m, 500, 0.1, 20.0, seed=1)
# Upcrossings for the empirical estimator: K up to 16 (the docs' 12, the examples' 16) and 40
# (figs. 4 of the examples).
for K in (16, 40):
    ss.simulate(ss.get_model("langevin")(**base, tau=0.1), 500, 0.005, 8.0, record_upcrossings=K)
# The chain of the docs and of the example study (`BurridgeKnopoff.example()`, one chain; time
# series every 10 and every 500 steps: the docs' 200 time units, the study's 10^4).
for record_dt in (None, 10.0):
    chain = ss.get_model("burridge-knopoff").example()
    ss.simulate_chain(chain, 1, 0.02, 200.0, seed=1, record_dt=record_dt)
# The rate-and-state slider's solves, each state law: noise-free, a stick or a slip (its
# recorded series are traced in each process: diffrax checks their times with a host
# callback); with friction noise, the windows of steps and the events' placing (its recorded
# series are kept on disk by the number of samples, so not shipped).
rs = dict(mass=0.0307, stiffness=168.0, v_b=42e-6, normal_force=0.301, mu0=0.3, a=0.01,
          b=0.015, d_c=1e-6, v_ref=1e-6)
for law in ("aging", "slip"):
    ss.simulate_cycles(ss.get_model("rate-and-state")(**rs, law=law), 2, 1e-3, 1.0, seed=1)
    noisy = ss.get_model("rate-and-state")(**rs, law=law, D=1e-6, tau=2e-3)
    ss.simulate_cycles(noisy, 2, 2e-4, 0.2, seed=1, record=False)
if pathlib.Path(sys.argv[1]).exists():
    ss.run_study(sys.argv[1], progress=False, figures=False)
"""


def versions() -> dict[str, str]:
    """The library versions the traces' keys hold (`_compile._environment`)."""
    import importlib.metadata

    return {d: importlib.metadata.version(d) for d in ("jax", "jaxlib", "diffrax", "equinox")}


def main() -> int:
    from ._compile import SHIPPED

    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, STICKSLIP_CACHE_DIR=cache, STICKSLIP_COMPILE="eager")
        subprocess.run([sys.executable, "-c", RUNS, str(MAIN_JOB)], env=env, check=True)
        made = sorted((pathlib.Path(cache) / "stickslip-exported").glob("*.bin"))
        if SHIPPED.exists():
            shutil.rmtree(SHIPPED)
        SHIPPED.mkdir(parents=True)
        for file in made:
            shutil.copy2(file, SHIPPED / file.name)
    (SHIPPED / "versions.json").write_text(json.dumps(versions(), indent=1) + "\n")
    size = sum(f.stat().st_size for f in SHIPPED.glob("*.bin"))
    print(f"{len(made)} traces, {size / 1e3:.0f} kB, in {SHIPPED}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
