"""The regime of a creeping slider (friction with memory): steady sliding, oscillation or
stick-slip, from the linear stability of steady sliding and the noise-free limit cycle."""

from __future__ import annotations

import dataclasses
import math

import equinox as eqx
import numpy as np

from ._errors import check_int
from ._model import CreepingSlider
from ._simulate.creep import least_velocity, run_cycles

# A limit cycle whose slowest slider velocity stays above this fraction of the drive is an
# oscillation; below it the slider (nearly) stops and the force rises along the loading
# line at k v_b to within this fraction: a stick-slip, as a force trace shows one.
STICK_FRACTION = 0.1


@dataclasses.dataclass(frozen=True)
class SlidingRegime:
    """What a creeping slider does at its parameters (from `stability_report`).

    - `regime`: `"steady sliding"` (steady sliding at `v_b` is linearly stable, or the
      perturbation never made three cycles), `"oscillation"` (it is unstable and the
      noise-free motion settles on a limit cycle whose slider never slows below
      `STICK_FRACTION` of `v_b`) or `"stick-slip"` (it does);
    - `evidence`: one line with the numbers that decided it;
    - `eigenvalues`: of the motion linearised about steady sliding (`linear_rates`);
    - `min_velocity_ratio`, `period`, `force_drop`: of the noise-free limit cycle's last
      cycle (nan without one).
    """

    model: str
    regime: str
    evidence: str
    eigenvalues: np.ndarray
    min_velocity_ratio: float
    period: float
    force_drop: float

    def __str__(self) -> str:
        return f"SlidingRegime: {self.model}: {self.regime} ({self.evidence})"


def sliding_regime(model: CreepingSlider, *, cycles: int = 40) -> SlidingRegime:
    """The regime of a creeping slider: the linear stability of steady sliding and, where it
    is unstable, the noise-free motion from the model's onset for `cycles` cycles (the
    perturbation grows for 40 e-folds of the linear rate first), its last cycle judged."""
    owner = "stability_report"
    cycles = check_int(owner, "cycles", cycles, minimum=4)
    rates = model.linear_rates()
    name = type(model).__name__
    growth = float(np.max(rates.real))
    none = (rates, math.nan, math.nan, math.nan)
    if growth < 0:
        line = f"steady sliding at v_b is linearly stable (slowest decay {growth:.3g} /s)"
        return SlidingRegime(name, "steady sliding", line, *none)
    quiet = eqx.tree_at(lambda m: m.D, model, 0.0) if hasattr(model, "D") else model
    omega = float(np.max(np.abs(rates.imag))) or growth
    period = 2 * math.pi / omega
    # Until `cycles` cycles are done: a limit cycle far below k_c is many linear periods
    # long (84 s against 0.3 s at 200 N/m and 3 um/s for paper-like parameters), and a run
    # that settles to steady sliding (a subcritical perturbation) costs little once steady.
    t_max = 1e4 * (cycles + 4) * period + 40.0 / growth
    table, _, _ = run_cycles(owner, quiet, 1, period / 100, t_max, 0, cycles)
    done = np.nonzero(np.isfinite(table["period"]))[0]
    if done.size < 3:
        line = (
            f"steady sliding is linearly unstable (growth {growth:.3g} /s) but the "
            f"noise-free motion made {done.size} cycle(s) in {t_max:.3g} s"
        )
        return SlidingRegime(name, "steady sliding", line, *none)
    last = done[-1]
    ratio = least_velocity(quiet, table["stick"][last], table["stick_time"][last])
    ratio /= float(model.v_b)
    kind = "stick-slip" if ratio < STICK_FRACTION else "oscillation"
    drop, cycle = float(table["force_drop"][last]), float(table["period"][last])
    line = (
        f"steady sliding unstable (growth {growth:.3g} /s); noise-free limit cycle: period "
        f"{cycle:.4g} s, force drop {drop:.4g}, least slider velocity {ratio:.3g} v_b "
        f"({'below' if ratio < STICK_FRACTION else 'above'} {STICK_FRACTION} v_b)"
    )
    return SlidingRegime(name, kind, line, rates, ratio, cycle, drop)
