"""A campaign of measured runs: every run read in its regime (`analyse_run`), one table of
runs, a regime map in the (stiffness, driving speed) plane.

A campaign file lists the runs, each a force trace with its rig's settings:

```yaml
runs:
  - file: k168Nm_v42.mat        # relative to the campaign file
    time: t                     # the time column, s (default "t")
    force: Fnorm                # the force column (default "force")
    scale: 0.301167             # multiplies the column to give newtons (default 1)
    stiffness: 168              # N/m
    v_b: 42.0e-6                # m/s
    mass: 0.0307                # kg (optional)
```

`Campaign.from_yaml(path)` (or `stickslip campaign FILE --out DIR`) reads every run;
`table()` gives one row a run; `write(out)` writes `runs.csv`, `runs.nc` (with the settings
as attributes), `regime_map.png` and `runs.png`. An optional `model: {name:, params:}` block
names a model with a `critical_stiffness()` whose predicted regions the map shades.
"""

from __future__ import annotations

import dataclasses
import math
import os
import pathlib
import warnings
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from .load import StudyError

MARKERS = {"stick-slip": ("^", "tab:red"), "oscillation": ("o", "tab:blue"),
           "steady sliding": ("s", "tab:green")}  # fmt: skip
# the per-cycle quantities the table summarises (median and 10-90 % range)
QUANTITIES = ("stick_time", "slip_time", "force_drop")


class _Base(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)


class RunEntry(_Base):
    file: str = Field(description="the trace: a CSV with a header, or a MATLAB .mat file")
    time: str = Field("t", description="the time column (s)")
    force: str = Field("force", description="the force column")
    scale: float = Field(1.0, gt=0, description="multiplies the force column to give N")
    stiffness: float = Field(gt=0, description="the spring's stiffness (N/m)")
    v_b: float = Field(gt=0, description="the driving speed (m/s)")
    mass: float | None = Field(None, gt=0, description="the slider's mass (kg)")
    name: str | None = Field(None, description="a label (default: the file's name)")


class ModelEntry(_Base):
    name: str = Field(description="a registered model with a critical_stiffness() method")
    params: dict[str, Any] = Field(default_factory=dict, description="its parameters")


class CampaignFile(_Base):
    runs: list[RunEntry] = Field(min_length=1, description="the runs")
    model: ModelEntry | None = Field(
        None, description="a model whose predicted regions the regime map shades"
    )


@dataclasses.dataclass(frozen=True)
class Campaign:
    """Runs read in their regimes (`analyse_run`), with their traces.

    - `runs`: the `Run` of each, in the file's order;
    - `traces`: each run's `(t, force)` in s and N;
    - `source`: the campaign file (or None);
    - `model`: the file's model (or None), whose predicted regions `regime_map` shades.
    """

    runs: list
    traces: list = dataclasses.field(repr=False)
    source: str | None = None
    model: Any = None

    @classmethod
    def from_yaml(cls, path) -> Campaign:
        """Read a campaign file and every run it lists; a bad entry is one `StudyError`
        naming the file, the entry's field and the reason."""
        from .load import read_yaml

        name = str(path)
        try:
            text = pathlib.Path(path).read_text(encoding="utf-8-sig")
        except FileNotFoundError:
            raise StudyError(name, None, "no such file") from None
        except (IsADirectoryError, UnicodeDecodeError, OSError) as err:
            raise StudyError(name, None, f"cannot be read as a campaign file ({err})") from None
        return cls.from_dict(read_yaml(text, name), source=name)

    @classmethod
    def from_dict(cls, data: dict, source: str | None = None) -> Campaign:
        from ..extract import analyse_run
        from .traces import read_trace

        try:
            spec = CampaignFile.model_validate(data)
        except ValidationError as err:
            from .schema import first_error

            e = first_error(err)  # an unknown key first: the typo is the news
            loc = ".".join(str(p) for p in e["loc"])
            raise StudyError(source, loc, _reason(e)) from None
        base = pathlib.Path(source).parent if source else pathlib.Path(".")
        model = None
        if spec.model is not None:
            from .._errors import StickSlipError
            from .._registry import get_model

            try:
                model = get_model(spec.model.name)(**spec.model.params)
            except (StickSlipError, TypeError, ValueError) as err:
                raise StudyError(source, "model", str(err)) from None
        runs, traces = [], []
        for i, entry in enumerate(spec.runs):
            path = entry.file if os.path.isabs(entry.file) else str(base / entry.file)
            try:
                columns = read_trace(path, (entry.time, entry.force))
            except StudyError as err:  # the file's problem, said at the entry that names it
                raise StudyError(source, f"runs.{i}.file", f"{entry.file}: {err.reason}") from None
            for key, column in (("time", entry.time), ("force", entry.force)):
                if column not in columns:
                    raise StudyError(source, f"runs.{i}.{key}",
                                     f"no column {column!r} in {entry.file}")  # fmt: skip
            t, force = columns[entry.time], columns[entry.force] * entry.scale
            label = entry.name or pathlib.Path(entry.file).name
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # the loading slope's: in the run's cycles
                    run = analyse_run(t, force, stiffness=entry.stiffness, v_b=entry.v_b,
                                      mass=entry.mass, name=label)  # fmt: skip
            except Exception as err:  # one line naming the run, whatever analyse_run said
                from .._errors import StickSlipError

                if not isinstance(err, StickSlipError):
                    raise
                raise StudyError(source, f"runs.{i} ({label})", str(err)) from None
            runs.append(run)
            traces.append((t, force))
        return cls(runs, traces, source, model)

    def table(self) -> list[dict[str, Any]]:
        """One row a run: name, stiffness, v_b, mass, regime, cycles, the median and the 10
        and 90 % quantiles of stick time, slip time and force drop (stick-slip), frequency
        and amplitude (oscillation), mean force and noise sd (every run), evidence."""
        rows = []
        for run in self.runs:
            s = run.settings
            row: dict[str, Any] = dict(
                name=s["name"], stiffness=s["stiffness"], v_b=s["v_b"], mass=s["mass"],
                regime=run.regime, cycles=0 if run.cycles is None else len(run.cycles),
            )  # fmt: skip
            for q in QUANTITIES:
                values = None if run.cycles is None else np.asarray(run.cycles[q], float)
                for tag, p in (("median", 50), ("p10", 10), ("p90", 90)):
                    row[f"{q}_{tag}"] = (
                        math.nan if values is None or values.size == 0
                        else float(np.percentile(values, p))
                    )  # fmt: skip
            row["frequency"] = math.nan if run.frequency is None else run.frequency
            row["amplitude"] = math.nan if run.amplitude is None else run.amplitude
            row.update(mean_force=run.mean_force, noise_sd=run.noise_sd, evidence=run.evidence)
            rows.append(row)
        return rows

    def write(self, out, model=None, force: bool = False) -> list[str]:
        """`runs.csv`, `runs.nc`, `regime_map.png` (with `model`'s predicted regions, by
        default the file's model, if any) and `runs.png` in the folder `out`, made whole in
        a scratch folder and put in place at once (an existing results folder of stickslip's
        is replaced with `force`, never a folder of other files); returns the paths."""
        from .._output import check_output_dir, partial_dir
        from .write import replace_file

        out = check_output_dir(out, inputs=[self.source] if self.source else [], force=force,
                               what="--out")  # fmt: skip
        names = ["runs.csv", "runs.nc", "regime_map.png", "runs.png"]
        tmp = partial_dir(out)
        try:
            _write_csv(self.table(), tmp / names[0], self.source)
            self.to_dataset().to_netcdf(tmp / names[1])
            self.regime_map(tmp / names[2], model=model if model is not None else self.model)
            self.panels(tmp / names[3])
            replace_file(tmp, out, force, "campaign")
        finally:
            if tmp.exists():
                import shutil

                shutil.rmtree(tmp, ignore_errors=True)
        return [str(out / n) for n in names]

    def to_dataset(self):
        """The table as an `xarray.Dataset` over the runs, the settings in its attributes."""
        import xarray as xr

        rows = self.table()
        names = [r["name"] for r in rows]
        data = {}
        for key in rows[0]:
            if key == "name":
                continue
            values = [np.nan if r[key] is None else r[key] for r in rows]
            data[key] = ("run", np.asarray(values, dtype=object if key in ("regime", "evidence")
                                           else float))  # fmt: skip
        ds = xr.Dataset(data, coords={"run": names})
        for key in ("regime", "evidence"):
            ds[key] = ds[key].astype(str)
        ds.attrs.update(source=self.source or "", units="stiffness N/m, v_b m/s, mass kg, "
                        "times s, forces N, frequency Hz")  # fmt: skip
        return ds

    def regime_map(self, path, model=None):
        """The runs in the (stiffness, v_b) plane, one marker per regime; with a `model`
        that has `critical_stiffness()` (the rate-and-state plugin), its predicted regions
        shaded behind them: steady sliding above its critical stiffness at each speed,
        unstable (stick-slip or oscillation) below."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6.4, 4.8))
        k = np.array([r.settings["stiffness"] for r in self.runs])
        v = np.array([r.settings["v_b"] for r in self.runs])
        k_lo, k_hi = k.min() / 3, k.max() * 3
        v_lo, v_hi = v.min() / 3, v.max() * 3
        said = "no model: measured regimes only"
        if model is not None:
            speeds = np.geomspace(v_lo, v_hi, 120)
            k_c = np.array([_critical(model, s) for s in speeds])
            if np.any(np.isfinite(k_c)):
                kc = np.where(np.isfinite(k_c), k_c, k_hi)
                unstable = "model: unstable (stick-slip or oscillation)"
                ax.fill_betweenx(speeds, k_lo, np.clip(kc, k_lo, k_hi), color="tab:red",
                                 alpha=0.12, label=unstable)  # fmt: skip
                ax.fill_betweenx(speeds, np.clip(kc, k_lo, k_hi), k_hi, color="tab:green",
                                 alpha=0.12, label="model: steady sliding")  # fmt: skip
                ax.plot(kc, speeds, color="0.3", lw=1, label="model's critical stiffness")
                said = f"{type(model).__name__}'s critical stiffness"
            else:
                said = "the model is stable at every speed shown"
        for regime, (marker, colour) in MARKERS.items():
            sel = [i for i, r in enumerate(self.runs) if r.regime == regime]
            if sel:
                ax.scatter(k[sel], v[sel], marker=marker, s=80, color=colour,
                           edgecolor="k", zorder=3, label=f"measured: {regime}")  # fmt: skip
        for i, r in enumerate(self.runs):
            ax.annotate(r.settings["name"], (k[i], v[i]), fontsize=7, xytext=(5, 5),
                        textcoords="offset points")  # fmt: skip
        ax.set(xscale="log", yscale="log", xlim=(k_lo, k_hi), ylim=(v_lo, v_hi),
               xlabel="spring stiffness k (N/m)", ylabel="driving speed V (m/s)",
               title=f"Regime map ({said})")  # fmt: skip
        ax.legend(fontsize=7, loc="best")
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)

    def panels(self, path, seconds: float = 1.0):
        """A panel a run: the first `seconds` of its force, with its regime and evidence."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        n = len(self.runs)
        cols = min(3, n)
        rows = -(-n // cols)
        fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 2.8 * rows), squeeze=False)
        for ax, run, (t, f) in zip(axes.flat, self.runs, self.traces, strict=False):
            keep = t <= t[0] + seconds
            ax.plot(t[keep] - t[0], f[keep], lw=0.7, color=MARKERS[run.regime][1])
            extra = (f", {len(run.cycles)} cycles" if run.cycles is not None
                     else f", {run.frequency:.3g} Hz" if run.frequency else "")  # fmt: skip
            ax.set_title(f"{run.settings['name']}: {run.regime}{extra}", fontsize=8)
            ax.set_xlabel("t (s)", fontsize=8)
            ax.set_ylabel("force (N)", fontsize=8)
        for ax in list(axes.flat)[n:]:
            ax.axis("off")
        fig.tight_layout()
        fig.savefig(path, dpi=100)
        plt.close(fig)


def _critical(model, speed) -> float:
    """The model's critical stiffness at `speed` (nan where it has none)."""
    from .._inference.params import model_kwargs

    try:
        m = type(model)(**{**model_kwargs(model), "v_b": float(speed)})
        return float(m.critical_stiffness())
    except (AttributeError, TypeError, ValueError, ArithmeticError):
        return math.nan


def _write_csv(rows, path, source) -> None:
    import csv

    keys = list(rows[0])
    with open(path, "w", newline="") as fh:
        fh.write(f"# stickslip campaign{': ' + source if source else ''}\n")
        writer = csv.DictWriter(fh, fieldnames=keys)
        writer.writeheader()
        for r in rows:
            writer.writerow({k: "" if r[k] is None else r[k] for k in keys})


def _reason(e: dict) -> str:
    if e["type"] == "extra_forbidden":
        return "is not a known key"
    if e["type"] == "missing":
        return "is required"
    return f"{e['msg'].lower()} (got {str(e.get('input'))[:40]!r})"
