"""The result of a one-cycle Monte Carlo run."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from .. import _histogram


@dataclasses.dataclass(frozen=True, eq=False)
class Ensemble:
    """One slip-stick cycle per path, from `simulate`.

    Arrays of shape `(n_paths,)`, `nan` where a path had not stuck by `t_max`:

    - `slip_time` $T_{sl}$: time from slip onset to the stick;
    - `stick_position` $x_{sl}$: position at the stick;
    - `slip_distance` $d = x_0 - x_{sl}$ (negative when a short slip ends beyond its start);
    - `stick_time` $T_{st} = \\max(0, (x_0' - x_{sl})/v_b)$, with $x_0'$ the next threshold;
    - `period` $T = T_{sl} + T_{st}$;
    - `immediate`: True where the slip had zero length (an immediate re-stick, $T_{sl} = 0$);
    - `stuck`: True where the path stuck before `t_max`;
    - `onset_state`, `stick_state`, `next_onset_state`: full states, shape `(n_paths, d)`.

    `upcrossings` (with `simulate(record_upcrossings=K)`): every upcrossing of the free
    slip-phase process, for the empirical crossing statistics (`Upcrossings`).

    `nonfinite`: True where the path's state left the finite numbers (a model's drift or
    diffusion that is `nan` or infinite somewhere): such a path is not `stuck` and its
    outputs are `nan`; `stats["nonfinite"]` counts them, `stats["nonfinite_where"]` says
    where one appeared, and `simulate` warns.

    `info` records how the run was made (model, solver, monitor, dt, t_max, seed, chunk size)
    and `stats` what it cost (wall and compile time, path-steps computed).
    """

    slip_time: np.ndarray
    stick_position: np.ndarray
    slip_distance: np.ndarray
    stick_time: np.ndarray
    period: np.ndarray
    immediate: np.ndarray
    stuck: np.ndarray
    onset_state: np.ndarray
    stick_state: np.ndarray
    next_onset_state: np.ndarray
    state_names: tuple[str, ...]
    info: dict[str, Any]
    stats: dict[str, Any]
    upcrossings: Any = None
    nonfinite: np.ndarray | None = None

    @property
    def n_paths(self) -> int:
        return int(self.slip_time.shape[0])

    def __len__(self) -> int:
        return self.n_paths

    @property
    def fraction_stuck(self) -> float:
        return float(np.mean(self.stuck))

    @property
    def fraction_immediate(self) -> float:
        return float(np.mean(self.immediate))

    def mean(self, name: str) -> tuple[float, float]:
        """Mean of an output over the paths that stuck, with its standard error."""
        x = np.asarray(getattr(self, name))[self.stuck]
        if x.size == 0:
            return float("nan"), float("nan")
        se = float(np.std(x, ddof=1) / np.sqrt(x.size)) if x.size > 1 else float("nan")
        return float(np.mean(x)), se

    def histogram(self, name: str, bins, *, density: bool = True, immediate: bool = True):
        """Histogram of an output over the paths that stuck, and its standard errors.

        With `density=True` the values integrate to the fraction of paths counted (of all
        paths), so that they compare directly with a (possibly defective) first-passage
        density. `immediate=False` leaves out the paths that stuck at once (slips of zero
        length): what a density's continuous part is compared with.

        **Returns:** `(values, standard_errors, edges)`.
        """
        keep = self.stuck if immediate else self.stuck & ~self.immediate
        x = np.asarray(getattr(self, name))[keep]
        if np.ndim(bins) == 1:  # given edges
            edges = np.asarray(bins, dtype=float)
            counts = _histogram.counts(x, edges)
        else:
            counts, edges = np.histogram(x, bins=bins)
        n = self.n_paths
        p = counts / n
        se = np.sqrt(p * (1 - p) / n)
        if density:
            width = np.diff(edges)
            return p / width, se / width, edges
        return counts.astype(float), se * n, edges

    def __repr__(self) -> str:
        m, se = self.mean("slip_time")
        return (
            f"Ensemble(n_paths={self.n_paths}, model={self.info.get('model')!r}, "
            f"solver={self.info.get('solver')!r}, dt={self.info.get('dt')}, "
            f"stuck={self.fraction_stuck:.4f}, immediate={self.fraction_immediate:.4f}, "
            f"mean slip_time={m:.4g} ± {se:.2g})"
        )
