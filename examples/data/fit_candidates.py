"""Write examples/data/fit_candidates.csv, the data of examples/fit_candidates.yaml:

    python examples/data/fit_candidates.py

120 cycles (slip and stick times) of the `langevin` model with Ornstein-Uhlenbeck friction
noise, tau = 0.3 (omega0 = 1, zeta = 0.1, D = 0.4, v_b = 1, x0 = 1), as `simulate` gives
them: the slips of positive length that ended, in the model's units, no measurement. The
example's candidates (white-limit noise, tau held at 0.03, against OU noise, tau free)
should choose OU noise on them.
"""

import pathlib

import numpy as np

import stickslip as ss

TRUTH = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.3)
N_CYCLES = 120
SEED = 2026
PATH = pathlib.Path(__file__).with_suffix(".csv")


def cycles() -> dict[str, np.ndarray]:
    e = ss.simulate(ss.get_model("langevin")(**TRUTH), 2 * N_CYCLES, 0.2, 60.0, seed=SEED)
    seen = e.stuck & ~e.immediate  # what a trace shows: slips of positive length that ended
    return {k: np.asarray(getattr(e, k))[seen][:N_CYCLES] for k in ("slip_time", "stick_time")}


def csv_text(table: dict[str, np.ndarray]) -> str:
    rows = zip(*table.values(), strict=True)
    return ",".join(table) + "\n" + "".join(",".join(f"{v:.6g}" for v in r) + "\n" for r in rows)


if __name__ == "__main__":
    table = cycles()
    assert table["slip_time"].size == N_CYCLES
    PATH.write_text(csv_text(table))
    print(f"wrote {PATH} ({N_CYCLES} cycles)")
