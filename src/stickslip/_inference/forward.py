"""The forward model: simulated cycles as the data see them (`simulate_values`).

Per-cycle values of the model are the slips of positive length that ended; the cycles of a
measured trace are the model's own trace passed through the data's measurement
(`measurement.measured_cycles`: sampled at the data's interval, with the data's noise,
through `extract_cycles` with the data's settings). The per-cycle simulation's settings
(`dt`, `t_max`) default from the model's slowest time scale and the data
(`simulation_settings`).
"""

from __future__ import annotations

import numpy as np

from .._errors import ParameterError
from .data import KINDS

MAX_STEPS = 2**30  # the simulator's limit on t_max / dt
# Model cycles per call of `measured_cycles`: its trace is recorded whole, so its memory
# grows with the cycles asked for times the samples a cycle spans (the measured slider's
# 1.4 s sticks at 2 kHz: ~2900; a bootstrap's 50 000 cycles asked 17.9 GB at once). A fit's
# default 4000 is one chunk (its numbers unchanged); more go in chunks of their own seeds.
MEASURED_CHUNK = 4000


def simulation_settings(centre, data, dt, t_max, owner: str = "fit") -> tuple[float, float]:
    """The simulation step and longest slip: given, or by default a fifth of the model's
    slowest time scale (at the box's centre) and three times the data's longest slip or
    period, at least 50 slow time scales; refused past the simulator's 2**30 steps."""
    given_dt, given_t_max = dt is not None, t_max is not None
    if dt is None:
        dt = 0.2 * _slow_scale(centre)
    if t_max is None:
        timed = [k for k in ("slip_time", "period") if k in data]
        longest = max(float(np.max(data[k])) for k in timed) if timed else 0.0
        t_max = max(3.0 * longest, 50.0 * _slow_scale(centre))
        origin = (
            f"3 x the data's longest {' or '.join(timed)}"
            if 3.0 * longest >= 50.0 * _slow_scale(centre)
            else "50 of the model's slowest time scales"
        )
    if t_max < dt:
        if given_t_max:
            raise ParameterError(owner, "t_max", f"must be >= dt = {dt:.4g}", t_max)
        raise ParameterError(owner, "dt", f"must be <= t_max = {t_max:.4g} ({origin})", dt)
    steps = t_max / dt
    if steps >= MAX_STEPS:
        if given_t_max:
            raise ParameterError(
                owner, "t_max", f"/ dt = {steps:.3g} steps: must be below 2**30 (dt = {dt:.4g})",
                t_max,
            )  # fmt: skip
        raise ParameterError(
            owner, "t_max", f"(by default {origin}, {t_max:.3g}) is {steps:.3g} steps of dt = "
            f"{dt:.3g}, past 2**30: "
            + ("check dt, or give t_max" if given_dt else "check the data's time unit"),
        )  # fmt: skip
    return dt, t_max


def _slow_scale(model) -> float:
    from .._model import time_scales

    scales = time_scales(model)
    return 1.0 if scales is None else scales[1]


def simulate_values(model, n, dt, t_max, seed, measurement=None) -> dict[str, np.ndarray]:
    """Simulated cycles as the data see them: `n` independent cycles, of which the slips of
    positive length that ended (per-cycle values, step `dt`, longest slip `t_max`), or, with
    a `measurement`, about `n` successive model cycles as that measurement shows them
    (`measured_cycles`, its own step unless `dt` is given; `t_max` unused). Raises
    `DataError` where the measured trace shows no cycles."""
    if measurement is not None:
        return _measured(model, measurement, n, seed, dt)
    from .._simulate import simulate

    e = simulate(model, n, dt, t_max, seed, progress=False)
    keep = e.stuck & ~e.immediate  # what a trace shows: slips of positive length that ended
    return {k: np.asarray(getattr(e, k))[keep] for k in KINDS}


def _measured(model, measurement, n, seed, dt) -> dict[str, np.ndarray]:
    """`measured_cycles` of about `n` model cycles, in chunks of at most `MEASURED_CHUNK`
    (the first with `seed` itself, so that up to a chunk nothing changes; the others with
    seeds drawn from `(seed, chunk)`), their cycles concatenated."""
    from .measurement import measured_cycles

    chunks = -(-int(n) // MEASURED_CHUNK)
    if chunks <= 1:
        return measured_cycles(model, measurement, n, seed, dt=dt)
    parts = []
    for i in range(chunks):
        size = min(MEASURED_CHUNK, int(n) - i * MEASURED_CHUNK)
        if size < 10:  # measured_cycles' least: the rest joins the chunk before
            break
        if i == chunks - 2 and int(n) - (i + 1) * MEASURED_CHUNK < 10:
            size = int(n) - i * MEASURED_CHUNK
        at = seed if i == 0 else int(np.random.SeedSequence([seed, i]).generate_state(1)[0])
        parts.append(measured_cycles(model, measurement, size, at, dt=dt))
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
