r"""`analyse_run`: what a measured force trace shows, whatever its regime.

A spring-pulled slider shows one of three regimes (Heslot et al. 1994 for paper on paper):

- **stick-slip**: the force rises slowly along a loading line and falls fast; its rate is
  strongly skewed (many small positive values, a few large negative ones). Its cycles come
  from `extract_cycles`.
- **oscillation**: the slider never sticks, the force oscillates about its mean (rising and
  falling alike: the rate is nearly symmetric) at a dominant frequency: half of its
  variance or more within 25 % of its spectral peak.
- **steady sliding**: neither: the force is its mean plus noise.

The rate's skewness decides between the first and the others (`_force.rate_skewness`: the
third standardised moment of the despiked force's Savitzky-Golay rate), the spectrum between
the last two. On the six public paper-on-paper runs the skewness is -2.2 to -9.7 for the
stick-slip runs (k = 168, 1002 N/m at 42 um/s; k = 168 at 1100 um/s, whose sticks are
rounded) and -0.6 to +0.03 for the three 4300 um/s runs, which oscillate at 15, 34 and
57 Hz.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from .._errors import DataError, ParameterError, check_positive
from ._cycles import Cycles
from ._input import OWNER, as_series, check_length, check_times, median

REGIMES = ("stick-slip", "oscillation", "steady sliding")
# An oscillation: at least half of the force's variance (above the drift) within 25 % of
# its spectral peak's frequency (0.77-0.93 on the three 4300 um/s runs; white noise puts a
# band's width over the spectrum's there, a few %), and an rms about the mean 3 times the
# sample noise or more.
_SHARE, _BAND, _RMS = 0.5, 1.25, 3.0
_SEGMENT = 8192  # Welch segments of up to this many samples (and half the trace)


@dataclasses.dataclass(frozen=True)
class Run:
    """One measured run, read whatever its regime (`analyse_run`).

    - `regime`: `"stick-slip"`, `"oscillation"` or `"steady sliding"`;
    - `evidence`: one line with the numbers that decided it;
    - `cycles`: the `Cycles` of a stick-slip run (`extract_cycles`), else None;
    - `frequency` (Hz) and `amplitude` (the force's rms about its mean, N) of an
      oscillation, else None;
    - `mean_force` (N) and `noise_sd` (the samples' noise, N): of every run;
    - `settings`: the run's stiffness (N/m), v_b (m/s), mass (kg or None), sampling
      interval (s), samples, duration (s), units, and the name it was given.
    """

    regime: str
    evidence: str
    cycles: Cycles | None
    frequency: float | None
    amplitude: float | None
    mean_force: float
    noise_sd: float
    settings: dict[str, Any]

    def __repr__(self) -> str:
        name = self.settings.get("name")
        head = f"Run({name!r}, " if name else "Run("
        if self.regime == "stick-slip":
            return f"{head}stick-slip, {len(self.cycles)} cycles)"
        if self.regime == "oscillation":
            return f"{head}oscillation at {self.frequency:.4g} Hz, rms {self.amplitude:.3g} N)"
        return f"{head}steady sliding at {self.mean_force:.4g} N)"

    def summary(self) -> str:
        """The regime, its evidence and the run's settings in a few lines."""
        s = self.settings
        lines = [repr(self), f"  {self.evidence}"]
        lines.append(
            f"  stiffness {s['stiffness']:.6g} N/m, v_b {s['v_b']:.6g} m/s"
            + (f", mass {s['mass']:.6g} kg" if s.get("mass") else "")
            + f"; {s['n_samples']} samples every {s['sampling_interval']:.4g} s "
            f"({s['duration']:.4g} s)"
        )
        if self.cycles is not None:
            med = {k: float(np.median(self.cycles[k])) for k in ("stick_time", "slip_time",
                                                                 "force_drop")}  # fmt: skip
            lines.append(
                f"  medians: stick {med['stick_time']:.4g} s, slip {med['slip_time']:.4g} s, "
                f"force drop {med['force_drop']:.4g} N"
            )
        return "\n".join(lines)


def analyse_run(
    t, force, *, stiffness: float, v_b: float, mass: float | None = None,
    name: str | None = None, **extract,
) -> Run:  # fmt: skip
    """Read a measured force trace in whichever regime it shows.

    **Arguments:**

    - `t` (s), `force` (N): the trace, evenly sampled (as `extract_cycles` takes it);
    - `stiffness` (N/m), `v_b` (m/s): the spring and the driving speed, both > 0;
    - `mass` (kg, > 0, optional): the slider's mass, kept in the settings (the frequency of
      an oscillation against $\\sqrt{k/m}/2\\pi$ in `evidence`);
    - `name`: a label kept in the settings (a file's name);
    - any further keyword (`window`, `thresholds`, `lines`) goes to `extract_cycles`.

    **Returns:** a `Run`: `regime`, `evidence`, `cycles` (stick-slip), `frequency` and
    `amplitude` (oscillation), `mean_force`, `noise_sd`, `settings`.

    **Raises:** `ParameterError` for bad arguments (as `extract_cycles`); `DataError` where
    the trace is stick-slip by its shape but its cycles cannot be timed (the reason, from
    `extract_cycles`, names the regime and its evidence).
    """
    from ._extract import extract_cycles
    from ._force import read_regime

    k = check_positive(OWNER, "stiffness", stiffness)
    v_b = check_positive(OWNER, "v_b", v_b)
    mass = check_positive(OWNER, "mass", mass, allow_none=True)
    t = as_series("t", t, required=True)
    f = as_series("force", force, required=True)
    check_times(t, minimum=64)
    check_length("force", f, t.size)
    h = median(np.diff(t))
    settings = dict(
        name=name, stiffness=k, v_b=v_b, mass=mass, sampling_interval=h,
        n_samples=int(t.size), duration=float(t[-1] - t[0]),
        units="force in N, time in s, stiffness in N/m, v_b in m/s, mass in kg",
    )  # fmt: skip
    shape = read_regime(t, f)
    if shape["stick_slip"]:
        try:
            cycles = extract_cycles(t, force=f, stiffness=k, v_b=v_b, **extract)
        except DataError as err:
            raise DataError(
                f"analyse_run: stick-slip by its shape ({shape['evidence']}), but no cycles "
                f"could be timed: {str(err).removeprefix('extract_cycles: ')}"
            ) from None
        evidence = f"{shape['evidence']}; {len(cycles)} cycles"
        return Run("stick-slip", evidence, cycles, None, None, shape["mean"], shape["noise"],
                   settings)  # fmt: skip
    if extract:
        unknown = sorted(set(extract) - {"window", "thresholds", "lines"})
        if unknown:
            raise ParameterError("analyse_run", unknown[0], "is not an argument")
    peak = _spectral_peak(shape["despiked"], h)
    rms = float(np.std(shape["despiked"]))
    natural = ""
    if mass is not None:
        natural = f"; sqrt(k/m)/2pi = {math.sqrt(k / mass) / (2 * math.pi):.4g} Hz"
    if peak["share"] >= _SHARE and rms >= _RMS * shape["noise"]:
        evidence = (
            f"{shape['evidence']}: no sticks; {100 * peak['share']:.0f} % of the force's "
            f"variance within 25 % of its spectral peak at {peak['frequency']:.4g} Hz, rms "
            f"{rms:.3g} N ({rms / shape['noise']:.3g} noise sd){natural}"
        )
        return Run("oscillation", evidence, None, peak["frequency"], rms, shape["mean"],
                   shape["noise"], settings)  # fmt: skip
    evidence = (
        f"{shape['evidence']}: no sticks, no dominant frequency ({100 * peak['share']:.0f} % "
        f"of the variance within 25 % of the spectral peak at {peak['frequency']:.4g} Hz; "
        f"rms {rms:.3g} N, {rms / shape['noise']:.3g} noise sd)"
    )
    return Run("steady sliding", evidence, None, None, None, shape["mean"], shape["noise"],
               settings)  # fmt: skip


def _spectral_peak(s, h) -> dict:
    """The force's dominant frequency: the power-weighted mean frequency of the Welch
    spectrum within `_BAND` of its strongest bin above the lowest ones (the drift), and the
    share of the variance there."""
    from scipy.signal import welch

    n = min(_SEGMENT, 1 << int(np.log2(max(s.size // 2, 16))))
    freq, power = welch(s - np.mean(s), fs=1.0 / h, nperseg=n)
    usable = freq > 4 * freq[1]
    j = int(np.argmax(np.where(usable, power, 0.0)))
    band = usable & (freq >= freq[j] / _BAND) & (freq <= freq[j] * _BAND)
    total = float(np.sum(power[usable]))
    share = float(np.sum(power[band]) / total) if total > 0 else 0.0
    f0 = float(np.sum(freq[band] * power[band]) / max(np.sum(power[band]), 1e-300))
    return dict(frequency=f0, share=share)
