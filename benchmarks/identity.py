"""Hashes of results that a change meant to keep every number must keep to the bit: run it
in two trees (the one before a restructuring and the one after) and compare the output.

- `sim ...`: ensembles of `simulate` (langevin white and coloured, random-threshold and its
  held variant) and a `Slider`'s SI cycles;
- `fit ...`: a fit of per-cycle values (one and two free parameters: estimate, intervals,
  log-likelihood, covariance, design values, noise report, warnings, p-values) and its
  goodness-of-fit replicates (refitted and linearised), and a fit through a position
  measurement;
- `extract ...`: cycles extracted from generated force traces and from position and
  velocity traces (table and settings);
- `measured ...`: the forward measurement's cycles of force (cut and whole, spikes, a
  line), position, velocity and both;
- with `--studies`: the example studies' `results.nc` (their timings apart; minutes).

    python benchmarks/identity.py [--studies] > after.json
    PYTHONPATH=OLD/src:OLD/plugins python benchmarks/identity.py [--studies] > before.json
    diff before.json after.json
"""

from __future__ import annotations

import hashlib
import json
import pathlib
import subprocess
import sys
import tempfile
import warnings

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
STUDIES = (
    "public_reference",
    "random_threshold",
    "burridge_knopoff",
    "fig4_left",
    "ou_exact_theory",
)


def digest(obj) -> str:
    """sha256 (16 hex digits) of nested dicts, lists and arrays, in order."""
    m = hashlib.sha256()

    def feed(o):
        if isinstance(o, dict):
            for k in o:
                m.update(str(k).encode())
                feed(o[k])
        elif isinstance(o, (list, tuple)):
            for x in o:
                feed(x)
        elif isinstance(o, np.ndarray) or hasattr(o, "shape"):
            a = np.asarray(o)
            m.update(str(a.dtype).encode())
            m.update(np.ascontiguousarray(a).tobytes())
        else:
            m.update(repr(o).encode())

    feed(obj)
    return m.hexdigest()[:16]


def simulations(ss, out):
    base = dict(omega0=1.0, v_b=0.1, D=0.05, zeta=0.1)
    law = dict(threshold="normal", threshold_params=dict(mean=1.0, sd=0.3))
    for name, kw in (
        ("langevin", dict(x0=1.0)),
        ("langevin", dict(x0=1.0, tau=0.3)),
        ("random-threshold", law),
        ("random-threshold-held", law),
    ):
        e = ss.simulate(
            ss.get_model(name)(**base, **kw), n_paths=2000, dt=0.01, t_max=200.0, seed=3
        )
        out[f"sim {name} {sorted(kw)}"] = digest(
            {k: getattr(e, k) for k in ("slip_time", "slip_distance", "stick_time", "period")}
        )
    slider = ss.Slider(
        mass=0.0307,
        stiffness=168.0,
        v_b=42e-6,
        static_friction=0.12,
        kinetic_friction=0.1,
        damping=1e-3,
        noise=1e-9,
        noise_time=1e-3,
    )
    out["sim slider"] = digest(slider.simulate(n_paths=2000, seed=5).table)


def fits(ss, out):
    from stickslip._inference.forward import simulate_values

    base = dict(omega0=1.0, zeta=0.1, v_b=1.0, x0=1.0, tau=0.1)
    d = simulate_values(ss.get_model("langevin")(**base, D=0.4), 900, 0.2, 200.0, 24)
    data = {k: d[k][:600] for k in ("slip_time", "stick_time")}
    for name, free in (("D", {"D": (0.05, 2.0)}), ("D+x0", {"D": (0.05, 2.0), "x0": (0.5, 2.0)})):
        fixed = {k: v for k, v in base.items() if k not in free}
        r = ss.fit("langevin", data, free, fixed, seed=7, n_sim=5000, check=(name == "D"))
        dd = r.diagnostics
        noise = {k: v for k, v in dd["mc_noise"].items() if k != "warning"}
        out[f"fit {name}"] = digest(
            json.dumps(
                [
                    r.estimate,
                    r.ci,
                    r.log_likelihood,
                    dd["covariance"],
                    dd["design"]["values"],
                    noise,
                    dd["warnings"],
                    r.method,
                    r.p_values,
                ],
                default=str,
                sort_keys=True,
            )
        )
        if name == "D":
            g = ss.goodness_of_fit(r, n_rep=3, seed=5, refit=True)
            out["fit refitted replicates"] = digest(g.replicates)
            g = ss.goodness_of_fit(r, n_rep=30, seed=6)
            out["fit linearised replicates"] = digest([g.replicates, g.p_values, g.statistics])


def extractions(ss, out):
    from _force_traces import Rig, make_trace

    for seed in (3, 4, 5):
        rig = Rig()
        t, f, _ = make_trace(seed, 60.0, rig)
        for window in (None, 31):
            c = ss.extract_cycles(t, force=f, stiffness=rig.stiffness, v_b=rig.v_b, window=window)
            out[f"extract force {seed} {window}"] = digest(
                [c.table, json.dumps(c.info, default=str, sort_keys=True)]
            )
    model = ss.get_model("langevin")(omega0=1.0, zeta=0.1, v_b=0.3, x0=1.0, D=0.02, tau=0.1)
    series = ss.simulate_cycles(model, 1, 0.01, 300.0, seed=3, record=True)
    t, X, _ = series.trajectory(0)
    t, X = np.asarray(t), np.asarray(X)
    grid = np.arange(0, t[-1], 0.05)
    x, v = np.interp(grid, t, X[:, 0]), np.interp(grid, t, X[:, 1])
    noisy = v + 0.01 * np.random.default_rng(1).standard_normal(v.size)
    for name, kw in (
        ("x", dict(x=x)),
        ("v", dict(v=v)),
        ("x and v", dict(x=x, v=v)),
        ("noisy v", dict(v=noisy)),
    ):
        c = ss.extract_cycles(grid, v_b=0.3, **kw)
        out[f"extract {name}"] = digest([c.table, json.dumps(c.info, default=str, sort_keys=True)])
    noisy_x = x + 1e-4 * np.random.default_rng(2).standard_normal(grid.size)
    cycles = ss.extract_cycles(grid, x=noisy_x, v_b=0.3)
    r = ss.fit(
        "langevin",
        cycles,
        {"D": (0.005, 0.1)},
        dict(omega0=1.0, zeta=0.1, v_b=0.3, x0=1.0, tau=0.1),
        seed=3,
        n_sim=1000,
    )
    out["fit through a position measurement"] = digest(
        json.dumps([r.estimate, r.ci, r.log_likelihood], default=str)
    )


def measurements(ss, out):
    from stickslip._inference.measurement import Measurement, measured_cycles

    slider = ss.get_model("langevin")(omega0=1.24, zeta=1e-3, v_b=0.02, tau=0.1, D=0.37, x0=1.0)
    force = Measurement(
        sampling_interval=0.037,
        signal="force",
        noise_sd=0.0375,
        window=29,
        spike_fraction=0.011,
        spike_height=0.52,
        lines=(0.676,),
        line_amplitude=0.0375,
        columns=("slip_time", "stick_time", "slip_distance", "peak_force"),
    )
    for sticks in ("cut", "whole"):
        out[f"measured force {sticks}"] = digest(
            measured_cycles(slider, force, 300, 5, sticks=sticks)
        )
    model = ss.get_model("langevin")(omega0=1.0, zeta=0.1, v_b=0.3, x0=1.0, D=0.02, tau=0.1)
    for signal, kw in (
        ("x", dict(noise_sd=1e-3)),
        ("v", dict(noise_sd=0.01)),
        ("x and v", dict(noise_sd=0.01, min_stick=3)),
        ("v", dict(tol=0.05, min_stick=2)),
    ):
        m = Measurement(sampling_interval=0.05, signal=signal, **kw)
        out[f"measured {signal} {sorted(kw.items())}"] = digest(measured_cycles(model, m, 300, 7))


def studies(out):
    import xarray as xr

    for name in STUDIES:
        with tempfile.TemporaryDirectory() as where:
            done = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "stickslip.cli",
                    "run",
                    str(ROOT / "examples" / f"{name}.yaml"),
                    "--out",
                    where,
                    "--quiet",
                    "--force",
                ],
                capture_output=True,
                text=True,
            )
            path = pathlib.Path(where) / "results.nc"
            if done.returncode or not path.exists():
                out[f"study {name}"] = f"failed: {done.stderr.strip()[-200:]}"
                continue
            ds = xr.load_dataset(path)
            values = {k: ds[k].values for k in ds.data_vars if not k.startswith("seconds")}
            out[f"study {name}"] = digest({**values, **{k: ds[k].values for k in ds.coords}})
            out[f"study {name} notes"] = digest(str(ds.attrs.get("warnings")))


def main():
    import stickslip as ss

    warnings.simplefilter("ignore")
    out: dict[str, str] = {}
    for part in (simulations, fits, extractions, measurements):
        part(ss, out)
    if "--studies" in sys.argv[1:]:
        studies(out)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
