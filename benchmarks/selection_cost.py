"""What `method: auto` costs before it runs anything: the selection's own wall time.

    python benchmarks/selection_cost.py

For a measured parameter set (a table lookup) and four sets the table never saw (near and
beyond the critical speed, short and long tau: a pilot of the model itself), each in a new
Python process (the compiled code on disk warm, as after a first run) and again in that
process: `MethodChoice.selection_seconds`, and the chosen run's predicted time beside it.
The target: at most 2 s, or 10 % of the chosen run.
"""

from __future__ import annotations

import json
import subprocess
import sys

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
SETS = {
    "public (measured)": {},
    "near critical": dict(D=0.05, v_b=1.2),
    "beyond critical": dict(v_b=1.3),
    "short tau": dict(tau=0.01),
    "long tau": dict(tau=2.0, D=0.2),
}
TOLERANCES = (0.1, 0.02)

CHILD = """
import json, sys, time
start = time.perf_counter()
import stickslip as ss
imported = time.perf_counter() - start
params, tols = json.loads(sys.argv[1]), json.loads(sys.argv[2])
model = ss.get_model("langevin")(**params)
out = []
for tol in tols:
    for rep in ("first", "again"):
        start = time.perf_counter()
        try:
            c = ss.select_method(model, tol)
        except ss.SelectionError as err:
            out.append(dict(tol=tol, rep=rep, selection=time.perf_counter() - start,
                            run=float("nan"), label="refused: " + str(err).split(": ", 1)[1]))
            continue
        out.append(dict(tol=tol, rep=rep, selection=c.selection_seconds, run=c.chosen.seconds,
                        label=c.chosen.label, promised=c.promised))
print(json.dumps(dict(imported=imported, rows=out)))
"""


def main():
    # Warm the on-disk compiled code once (every pilot shape), as a first run would.
    for kw in SETS.values():
        subprocess.run(
            [sys.executable, "-c", CHILD, json.dumps({**PUBLIC, **kw}), json.dumps([0.1])],
            check=True,
            capture_output=True,
        )
    print(f"{'set':18s} {'tol':>5s} {'call':6s} {'selection':>10s} {'chosen run':>11s}  choice")
    for name, kw in SETS.items():
        res = subprocess.run(
            [sys.executable, "-c", CHILD, json.dumps({**PUBLIC, **kw}), json.dumps(TOLERANCES)],
            check=True,
            capture_output=True,
            text=True,
        )
        data = json.loads(res.stdout.strip().splitlines()[-1])
        for r in data["rows"]:
            print(
                f"{name:18s} {r['tol']:5g} {r['rep']:6s} {r['selection']:9.3f}s "
                f"{r['run']:10.3f}s  {r['label']}"
            )


if __name__ == "__main__":
    main()
