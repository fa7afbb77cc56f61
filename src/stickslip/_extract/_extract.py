"""The entry point: `extract_cycles` picks the kind of trace given (`stickslip.trace_kinds`)
and reads it."""

from __future__ import annotations

from collections.abc import Mapping

from .._errors import ParameterError
from .._trace_kind import default_kind, trace_kinds
from ._cycles import Cycles
from ._input import OWNER


def extract_cycles(
    t,
    x=None,
    v=None,
    *,
    force=None,
    stiffness: float | None = None,
    v_b: float | None = None,
    tol: float | None = None,
    min_stick: int | None = None,
    window: int | None = None,
    thresholds: Mapping[str, float] | None = None,
    lines=None,
    **more,
) -> Cycles:
    r"""Find the stick-slip cycles in a measured trace and time each one.

    **Arguments:**

    - `t`: sample times, 1-D, strictly increasing (the spacing may vary for `x`/`v`; a
      force trace must be evenly sampled, within 1%). Negative times are fine.
    - `x`, `v`: position and/or velocity at those times, in model units. With `v` the stick
      phases are found from `v`; with only `x`, from the mean velocity of each sampling
      interval, $(x_{k+1} - x_k)/(t_{k+1} - t_k)$, which is exactly $v_b$ on an interval
      inside a stick. With only `v`, the position is its cumulative trapezoid integral.
    - `force`, `stiffness`: instead of `x`/`v`, the spring force $F$ (N) and the spring's
      stiffness $k$ (N/m); the extension $F/k$ plays the part of $x$. Robust to spikes,
      white noise, offset drift and creep; see "Force traces" below.
    - `v_b`: the driving speed ($> 0$). Required with `x`/`v`; with `force` it may be
      `None`: it is then estimated from the sticks' loading slope, $g / k$. Either way the
      speed the sticks actually move at is measured, used, and recorded in `info`; a given
      `v_b` that disagrees by more than 2% gives a one-line warning (by more than a factor
      2, with force, a `DataError`: units). With `x`/`v` the sticks' speed is first found
      without `v_b` (the peak of the velocities that hold, on the trace smoothed where it is
      noisy): a `v_b` more than 25% from it is a `ParameterError`, sticks that move
      backwards (a flipped sign) a `DataError`, and a `v_b` 10-25% off is replaced by it
      (with the warning). A slip distance below $-v_b T_{sl}$, which no slip can have (the
      velocity stays below $v_b$), is a `DataError`.
    - `tol` (`x`/`v`): a velocity value is *stuck* when $|v - v_{st}| \le$ `tol`, with
      $v_{st}$ the sticks' speed (the robust centre of the values near `v_b`). Default: 5
      robust sd of the stuck values' noise, $5 \times 1.4826\,\mathrm{MAD}$, and at least
      $10^{-9}$ times the spread (rounding of differenced positions). A noisy trace
      (5 sd beyond 5% of the velocity spread) is flagged and timed on a Savitzky-Golay
      smoothing of $v - v_b$ (quadratic, the smallest odd window from 5 that brings 5 sd
      within that 5%), `tol` is 5 sd of the smoothed values, and a stick must hold at least
      a window of samples (`info`: `filter`, `smoothing_window`, `noise_sd_smoothed`,
      `tol_raw`).
    - `min_stick` (`x`/`v`): the fewest consecutive stuck values that make a stick
      (default 2). Shorter runs are part of a slip.
    - `window` (`force`): the samples of the Savitzky-Golay force rate (odd, >= 5). Default:
      half the median slip's length from a first pass with 11, between 5 and 101.
    - `lines` (`force`): the spectral lines to notch out, as frequencies in the inverse of
      `t`'s unit (the model's own when a fit simulates the data's measurement); `()` for
      none. Default `None`: found on the trace near the mains frequencies, 50 and 60 Hz
      and their harmonics (within 2 %; `t` in seconds), where a Welch bin stands 10 times
      above the spectrum's level about it. Only there: a regular stick-slip's own
      spectrum is a comb of lines at the multiples of its rate, which is signal.
    - `thresholds` (`force`): some of `spike`, `slip`, `extent`, `drop`, `split` (numbers
      > 0) to replace their defaults 5, 5, 2, 5, 25 (in noise sd, `split` in chi^2); see
      "Force traces". For a sensitivity check; the defaults are what the tests hold to.

    **Locating the transitions (`x`/`v`).** The stick lies between the last slipping value
    before a stuck run and the run; within that bracket it is placed by the slip's trend
    ($v_b - v$ linear in time near the stick), so the error is at most one sampling
    interval, and $O(h^2)$ for a smooth velocity. A release is located the same way in
    reversed time. Within a stick $x - v_b t$ is constant; its median over the stick gives
    the positions at the stick and the release, and $d = x(t_0) - x(t_{sl})$.

    **Force traces.** Spikes (samples 5 sd from a running median) are replaced by it,
    spectral lines (a mains hum) are notched out (`info["lines_removed"]`; see `lines`), the
    noise sd $\sigma$ is measured from the despiked differences, slips are the stretches where the
    force rate lies 2 sd below the loading rate and reaches 5 sd below (the rate's sd
    measured on the trace: coloured noise widens it), kept where the force drops across
    them by more than 5 sd of that drop's estimate (also measured), and each slip is timed
    by fitting the model's damped half-oscillation from the loading line to the stick
    (which locates both ends to about a sample; `info["release_sd_median"]`,
    `info["stick_sd_median"]` give the fit's standard errors for white noise). A trace
    whose force rate scatters more than 5.5 times what its sample noise explains never
    follows a loading line (continuous sliding) and is refused. The table gains
    `peak_force` (the force at the release) and `force_drop` (release less stick, N);
    `slip_distance` is `force_drop / k`. A slip that re-slips at once is a row with
    `stick_time = 0`. Every threshold is in `info`.

    **Cycles that a trace cannot show (`x`/`v`).** A stick holding fewer than `min_stick`
    values runs on into the next slip: the trace shows one longer slip. An immediate
    re-stick ($T_{sl} = 0$) is invisible: the stick continues.

    **Other kinds of trace.** The trace's kind is decided by the inputs given: `force`
    and `stiffness` make a force trace, `x` and `v` a position/velocity one (the default).
    A trace kind from a plugin (`stickslip.trace_kinds`, or `register_trace_kind`) takes
    its own inputs and settings as further keyword arguments (`**more`).

    **Returns:** a `Cycles`, one row per complete cycle. The incomplete first and last
    cycles are dropped. `Cycles.to_csv` writes `info` into a `#` header;
    `Cycles.from_csv` reads it back.

    **Raises:** `ParameterError` for non-numeric, non-finite or mismatched inputs, `t` not
    strictly increasing, no trace given, `v_b <= 0`, a trace without a complete cycle, and
    sampling too coarse to time the slips (a median slip shorter than 3 intervals);
    `DataError` for a trace without stick-slip structure (noise, continuous sliding, a
    constant), with the evidence in one line.
    """
    given = {"x": x, "v": v, "force": force, "stiffness": stiffness}
    options = dict(tol=tol, min_stick=min_stick, window=window, thresholds=thresholds,
                   lines=lines)  # fmt: skip
    kinds = trace_kinds()
    for key, value in more.items():  # a registered kind's own inputs and settings
        if any(key in k.inputs for k in kinds):
            given[key] = value
        elif any(key in k.options for k in kinds):
            options[key] = value
        else:
            known = ", ".join(f"{k.name} ({', '.join(k.inputs + k.options)})" for k in kinds)
            raise ParameterError(OWNER, key, f"is not an input or setting of any trace kind "
                                 f"(known kinds: {known})")  # fmt: skip
    named = [k for k in kinds if any(given.get(i) is not None for i in k.inputs)]
    if len(named) > 1:
        raise ParameterError(
            OWNER,
            named[0].inputs[0],
            f"goes alone: give {named[0].name} or {named[1].name}, not both",
        )
    kind = named[0] if named else default_kind()
    return kind.extract(t, {i: given.get(i) for i in kind.inputs}, v_b,
                        {k: v for k, v in options.items() if v is not None})  # fmt: skip
