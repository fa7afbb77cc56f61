r"""The kinds of measured trace: what `extract_cycles` reads and a fit's measurement makes.

A kind of trace is one class, a subclass of `TraceKind`, registered under the entry-point
group `stickslip.trace_kinds`; the two built-in kinds are registered there like any
plugin:

- `MotionTrace` (`"position-velocity"`): a position and/or velocity trace (`x=`, `v=`),
  in the model's units; the stick phases found from the velocity;
- `ForceTrace` (`"force"`): the spring force (`force=`, `stiffness=`) in newtons and
  seconds, despiked, its mains lines notched, each slip timed by fitting its damped
  half-oscillation.

A new kind (another sensor, another signal) is a subclass in the user's own package and its
entry point: the reader, what its `Measurement` records of a simulated cycle, and the
noise it adds. See the manual's "How the code is laid out".
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ._errors import ParameterError
from ._trace_kind import (
    OWNER,
    SimulatedPath,
    TraceKind,
    get_trace_kind,
    info_number,
    list_trace_kinds,
    register_trace_kind,
)

__all__ = [
    "ForceTrace",
    "MotionTrace",
    "SimulatedPath",
    "TraceKind",
    "get_trace_kind",
    "list_trace_kinds",
    "register_trace_kind",
]

# A spike `extract_cycles` found is replaced by the running median whatever its height
# beyond the threshold (the height is not reported): simulated spikes are twice it.
_SPIKE_HEIGHT = 2.0


def _noise(measurement, unit_noise):
    """The noise of a sample: `unit_noise` (standard normals) times the measurement's sd."""
    if measurement.noise_sd > 0 and unit_noise is not None:
        return measurement.noise_sd * unit_noise
    return 0.0


class MotionTrace(TraceKind):
    """A position and/or velocity trace in the model's units (`extract_cycles(t, x, v,
    v_b=...)`): the sticks are the runs where the velocity holds at the driving speed."""

    name = "x/v"
    signals = ("x", "v", "x and v")
    inputs = ("x", "v")
    options = ("tol", "min_stick")
    fields = ("tol", "min_stick")
    info_keys = ("min_stick", "tol_rule", "tol")
    default = True

    def extract(self, t, given, v_b, options):
        from ._extract._velocity import extract_velocity

        self.refuse_options(options)
        if v_b is None:
            raise ParameterError(OWNER, "v_b", "is required with x/v (the driving speed, > 0)")
        return extract_velocity(t, given["x"], given["v"], v_b, options.get("tol"),
                                options.get("min_stick"))  # fmt: skip

    def measurement(self, info, columns, scales):
        if scales is not None:
            raise ParameterError(
                "Measurement", "scales", "applies to force traces only: position and "
                "velocity traces are taken in the model's units",
            )  # fmt: skip
        h, noise = info_number(info, "sampling_interval"), info_number(info, "noise_sd")
        if info["input"] == "x":
            # the extraction measures the noise of the interval velocities
            # (x_{k+1} - x_k) / h: sqrt(2) times the position noise over h
            noise = noise * h / math.sqrt(2.0)
        given = info["tol_rule"] == "given"
        return dict(
            sampling_interval=h, signal=info["input"], noise_sd=noise,
            tol=info_number(info, "tol") if given else None,
            min_stick=int(info["min_stick"]), columns=columns,
        )  # fmt: skip

    def settings(self, measurement, v_b):
        return dict(v_b=v_b, tol=measurement.tol, min_stick=measurement.min_stick)

    def record(self, measurement, t, x, v, noise, rng):
        noise = _noise(measurement, noise)
        if measurement.signal == "x":
            return dict(t=t, x=x + noise)
        if measurement.signal == "v":
            return dict(t=t, v=v + noise)
        return dict(t=t, x=x, v=v + noise)


class ForceTrace(TraceKind):
    """The spring force of a slider in newtons at times in seconds (`extract_cycles(t,
    force=F, stiffness=k)`); the extension `F / k` plays the part of the position. Its
    measurement adds white noise, spikes and mains lines as the extraction reported them,
    on one uniform grid (the extraction refuses an uneven force trace)."""

    name = "force"
    signals = ("force",)
    inputs = ("force", "stiffness")
    options = ("window", "thresholds", "lines")
    fields = ("window", "thresholds", "spike_fraction", "spike_height", "line_amplitude",
              "lines")  # fmt: skip
    info_keys = ("window", "thresholds", "n_spikes", "n_samples", "spike_threshold",
                 "lines_removed")  # fmt: skip
    quantities = "force"
    in_si = True

    def extract(self, t, given, v_b, options):
        from ._extract._force import extract_force

        if given["force"] is None:
            raise ParameterError(OWNER, "force", "is required with stiffness")
        if given["stiffness"] is None:
            raise ParameterError(OWNER, "stiffness", "is required with force (N/m)")
        for key in ("tol", "min_stick"):
            if key in options:
                raise ParameterError(
                    OWNER, key, "applies to x/v only: a force trace's thresholds come from "
                    "its noise (see window)",
                )  # fmt: skip
        self.refuse_options(options)
        return extract_force(t, given["force"], given["stiffness"], v_b, options.get("window"),
                             options.get("thresholds"), options.get("lines"))  # fmt: skip

    def measurement(self, info, columns, scales):
        if scales is None:
            raise ParameterError(
                "Measurement", "scales", "is required for a force trace: its cycles are in "
                "seconds and newtons; give Slider(...).scales (or the Slider) for the model's "
                "units",
            )  # fmt: skip
        h, noise = info_number(info, "sampling_interval"), info_number(info, "noise_sd")
        scales = getattr(scales, "scales", scales)  # a Slider gives its Scales
        time, force = getattr(scales, "time", None), getattr(scales, "force", None)
        if not (isinstance(time, float) and isinstance(force, float)):
            raise ParameterError("Measurement", "scales",
                                 "must be a stickslip.units.Scales or a Slider")  # fmt: skip
        n_samples = max(int(info["n_samples"]), 1)
        return dict(
            sampling_interval=h / time, signal="force", noise_sd=noise / force,
            window=int(info["window"]), thresholds=dict(info["thresholds"]),
            spike_fraction=int(info["n_spikes"]) / n_samples,
            spike_height=_SPIKE_HEIGHT * info_number(info, "spike_threshold") / force,
            lines=tuple(float(f) * time for f in info["lines_removed"]),
            line_amplitude=noise / force if info["lines_removed"] else 0.0,
            columns=columns,
        )  # fmt: skip

    def settings(self, measurement, v_b):
        """In the model's units: the force in units of $k x_0$, stiffness 1."""
        m = measurement
        return dict(
            stiffness=1.0, v_b=v_b, window=m.window,
            thresholds=None if m.thresholds is None else dict(m.thresholds),
            # the data's lines, notched as on the data (a search would look near the
            # mains frequencies in Hz, not in the model's time unit)
            lines=m.lines,
        )  # fmt: skip

    def prepare(self, measurement, seed):
        """Nothing: a force trace's noise is hashed per sample, not read from a pool."""

    def synthesise(self, measurement, path: SimulatedPath):
        """One uniform grid from 0 (its noise and spikes keyed by cycle, `keyed_samples`);
        with `path.cut` and a given `window`, only the stretches about the slips
        (`cut_grid`), the data's lines notched out of the whole trace first (`notched`)
        and the cut stretches' rise taken out (the sticks' line continues across a cut)."""
        from ._inference.measurement import cut_grid, keyed_samples, notched

        m, h = measurement, measurement.sampling_interval
        cycles = (path.release, path.slip, path.stick)
        n = int(np.floor(path.t[-1] / h)) + 1
        kept = cut_grid(*cycles, n, h, m.window) if path.cut and m.window is not None else None
        at = None if kept is None else kept.index
        grid = h * (np.arange(n) if at is None else at)
        noise, uniforms = keyed_samples(*cycles, n, h, path.seed, path.path, m.noise_sd > 0,
                                        m.spike_fraction > 0, at)  # fmt: skip
        # linear between samples: exact along a stick (x grows at v_b from the stick
        # state to the next onset, v = v_b), the slips as the simulator's steps give them
        x = np.interp(grid, path.t, path.x)
        v = np.interp(grid, path.t, path.v)
        if kept is None:
            return self.record(m, grid, x, v, noise, path.rng, uniforms)
        if m.lines:
            # the data's lines notched out of the whole trace, as the extraction does: the
            # slips ring; the cut trace is extracted without a notch
            x = notched(x, kept.index, path.v_b * h, m.lines, h)
        kept = dataclasses.replace(
            kept, shift=path.v_b * h * (kept.index - np.arange(kept.index.size))
        )
        signals = self.record(m, grid, x - kept.shift, v, noise, path.rng, uniforms, lines=False)
        signals["cut"] = kept
        return signals

    def record(self, measurement, t, x, v, noise, rng, uniforms=None, lines=True):
        """The force `x` (units of $k x_0$) plus the noise, the lines (if `lines`) with
        phases drawn from `rng`, and spikes where `uniforms` (one a sample) fall below the
        spike fraction, upwards below half of it."""
        m = measurement
        force = x + _noise(m, noise)
        for f in m.lines if lines else ():
            force = force + m.line_amplitude * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
        if m.spike_fraction > 0:
            at = np.flatnonzero(uniforms < m.spike_fraction)
            force[at] += m.spike_height * np.where(uniforms[at] < 0.5 * m.spike_fraction, 1.0, -1.0)
        return dict(t=t, force=force)

    def extracted(self, signals, measurement, v_b):
        """A cut trace (`"cut"` in `signals`) is extracted on its kept samples, without the
        notch its making applied already."""
        if "cut" not in signals:
            return super().extracted(signals, measurement, v_b)
        from ._extract._force import check_thresholds, extract_slips

        settings = self.settings(measurement, v_b)
        return extract_slips(
            signals["t"], signals["force"], measurement.sampling_interval, 1.0, v_b,
            measurement.window, check_thresholds(settings["thresholds"]), (),
            cut=signals["cut"],
        )[0]  # fmt: skip

    def to_model_units(self, table, scales, info: Mapping) -> dict[str, np.ndarray]:
        """The columns of a force trace's cycles (s, m, N) in the model's units, as
        `Slider.to_model` gives them: times over `scales.time`, force drops over
        `scales.force` ($k x_0$), slip distances (drop / k) over $x_0$ (`scales.length`,
        or `force` over the trace's `stiffness`: what the study's scales give), the peak
        force as the threshold `(F - force_offset) / force` (left out without a
        `force_offset`: it is not fitted)."""
        from .quantities import get, names

        stiffness = info.get("stiffness")
        scales = getattr(scales, "scales", scales)  # a Slider gives its Scales
        time, force = float(scales.time), float(scales.force)
        length = getattr(scales, "length", None)
        if length is None and stiffness is not None:
            length = force / float(stiffness)
        unit = {"time": time, "length": length, "force": force}
        per = {name: unit[get(name).dimension] for name in names("measurement")}
        offset = getattr(scales, "force_offset", None)
        out: dict[str, Any] = {}
        for name, values in table.items():
            values = np.asarray(values, float)
            if name == "peak_force":
                if offset is not None:
                    out[name] = (values - float(offset)) / force
            elif per.get(name, 1.0) is None:
                raise ParameterError(
                    "fit", "scales", "needs a length (or the trace's stiffness in the cycles' "
                    "info) to put the slip distances in the model's units",
                )  # fmt: skip
            elif name in per:
                out[name] = values / per[name]
            else:
                out[name] = values
        return out
