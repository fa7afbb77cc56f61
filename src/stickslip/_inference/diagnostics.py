"""What a fit records of itself (`FitResult.diagnostics`), as typed records.

`FitDiagnostics` and its `Design` are dataclasses: goodness of fit, model choice,
prediction and saving read their fields by name, so a field that a fit does not fill is a
default seen in one place, not a key silently missing. Both also read as mappings
(`d["n_sim"]`, `d.get("runs")`, `dict(d)`), as they did when they were dicts, every field a
key (`None` where a fit has nothing to put there), and a fit's measurement also as the keys
`observe`, `trace` and `sampling` it had.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
from typing import Any


class _Record(Mapping):
    """A dataclass that also reads as a mapping of its fields, and takes
    `record[field] = value`."""

    def _names(self) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(self))

    def __getitem__(self, key: str) -> Any:
        if key in self._names() or key in getattr(self, "_DERIVED", ()):
            return getattr(self, key)
        raise KeyError(key)

    def __setitem__(self, key: str, value: Any) -> None:
        if key not in self._names():
            raise KeyError(f"{type(self).__name__} has no field {key!r}")
        setattr(self, key, value)

    def __iter__(self) -> Iterator[str]:
        return iter(self._names() + tuple(getattr(self, "_DERIVED", ())))

    def __len__(self) -> int:
        return len(self._names()) + len(getattr(self, "_DERIVED", ()))

    @classmethod
    def from_mapping(cls, values: Mapping):
        """From a mapping with these fields (a saved fit's JSON, an older dict); other keys
        are left out."""
        if isinstance(values, cls):
            return values
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in values.items() if k in names})


@dataclasses.dataclass(eq=False)
class Design(_Record):
    """The local surface's design (fit coordinates): whether an axis was `clipped` at the
    box, whether the polynomial had a `vertex`, its `centre`, `steps` and `points`, their
    log-likelihood `values` at both `seeds`, and (where small enough; `None` in a saved fit)
    the cycles simulated there, per seed and point (`samples`, reused by `compare_fits`)."""

    clipped: Any = None
    vertex: bool | None = None
    centre: list | None = None
    steps: list | None = None
    points: list | None = None
    values: list | None = None
    seeds: list | None = None
    samples: Any = None

    def __repr__(self) -> str:
        return f"Design({len(self.points or ())} points, seeds {self.seeds})"


@dataclasses.dataclass(eq=False)
class FitDiagnostics(_Record):
    """What a fit records of itself.

    - settings: `n_sim`, `dt`, `t_max`, `seed`; `measurement` (the data's `Measurement`,
      `None` for per-cycle values); `bandwidth` (per column; a list of those, per run, for a
      joint fit); `scales` (`"log"` or `"linear"` per free parameter) and `to_fit` (values to
      fit coordinates); `box` (each free parameter's search box, as given);
    - the data: `n_data`, `zero_fraction` (of each duration column);
    - the surface: `covariance` and `hessian` (fit coordinates; the curvature the
      covariance divides by: a plain quadratic's through both seeds' values where it is
      concave, else the fit's polynomial's at its vertex, or its quadratic part where it
      has none), `points` (every evaluated
      point and its log-likelihood), `evaluations`, `optimizer` (Nelder-Mead's evaluations
      and cap), `design` (a `Design`);
    - the noise and the rows: `mc_noise` (the second seed's estimate against the first),
      `dependence` (the lags of the sandwich's rows);
    - `seconds`, `warnings` (each also issued as a one-line `UserWarning`);
    - `units`: the SI mapping given (`scales=` of `fit`); for a joint fit, `runs` (each run's
      spring, speed, cycles, fitted model and checks) and `joint` (the map to each run's
      model);
    - `profile`: with `fit(..., intervals="profile")`, per free parameter what its profile
      interval evaluated (`profile.profile_intervals`: the values of the parameter tried
      and the statistic there, in fit coordinates, the threshold and its adjustment, the
      ends, whether an end is the box's, and the Wald interval, `wald`); else `None`.
    """

    n_sim: int | None = None
    dt: float | None = None
    t_max: float | None = None
    seed: int | None = None
    measurement: Any = None
    n_data: dict = dataclasses.field(default_factory=dict)
    zero_fraction: dict = dataclasses.field(default_factory=dict)
    bandwidth: Any = None
    scales: dict = dataclasses.field(default_factory=dict)
    box: dict | None = None
    covariance: list | None = None
    hessian: list | None = None
    evaluations: int | None = None
    points: list = dataclasses.field(default_factory=list)
    seconds: float | None = None
    warnings: list = dataclasses.field(default_factory=list)
    to_fit: Any = None
    optimizer: dict | None = None
    design: Design | None = None
    mc_noise: dict | None = None
    dependence: dict | None = None
    units: Any = None
    runs: list | None = None
    joint: Any = None
    profile: dict | None = None

    # read as keys too, as the dict had them: the measurement as `observe`, whether there
    # was one (`trace`) and its sampling interval (`sampling`)
    _DERIVED = ("observe", "trace", "sampling")

    def __setattr__(self, name: str, value: Any) -> None:
        if name == "design" and isinstance(value, Mapping) and not isinstance(value, Design):
            value = Design.from_mapping(value)  # (a dict of its fields, as before)
        super().__setattr__(name, value)

    @property
    def observe(self):
        return self.measurement

    @property
    def trace(self) -> bool:
        return self.measurement is not None

    @property
    def sampling(self) -> float | None:
        return None if self.measurement is None else self.measurement.sampling_interval

    def __repr__(self) -> str:
        shown = ", ".join(f"{k}={getattr(self, k)!r}" for k in ("n_sim", "seed", "evaluations"))
        return f"FitDiagnostics({shown}, {len(self.warnings)} warnings)"
