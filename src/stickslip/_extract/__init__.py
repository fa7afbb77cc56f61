r"""`extract_cycles`: per-cycle stick-slip statistics from a measured trace.

A block driven at speed $v_b$ sticks when its velocity first returns to $v_b$ and then moves
with the belt, $x(t) = x_{sl} + v_b (t - t_{sl})$, until static friction gives way (docs/
simulator.md, "Semantics of one cycle"). In the drifting frame $y = x - v_b t$ a stick is a
flat stretch; during a slip $\dot y = v - v_b < 0$. With a force trace the spring's
extension $F/k$ plays the part of $x$.

- `_velocity`: position / velocity traces (`x=`, `v=`), transitions from the velocity;
- `_force`: force traces (`force=`, `stiffness=`): despiking, slips found from the force
  rate, each slip timed by fitting its damped half-oscillation;
- `_cycles`: the `Cycles` table and its CSV form (settings in a `#` header);
- `_regime`: `analyse_run`, a force trace read in whichever regime it shows.
"""

from __future__ import annotations

from ._cycles import COLUMNS as COLUMNS
from ._cycles import FORCE_COLUMNS as FORCE_COLUMNS
from ._cycles import Cycles as Cycles
from ._cycles import read_cycles as read_cycles
from ._extract import extract_cycles as extract_cycles
from ._regime import Run as Run
from ._regime import analyse_run as analyse_run
