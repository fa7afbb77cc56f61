r"""Model no more than a scene needs: choose the cheapest method that meets a tolerance.

`select_method(model, tolerance)` picks, among the level-crossing approximations and Monte
Carlo runs (exact stepping or Euler-Maruyama, at some step and number of paths), the one
with the smallest run time whose error is known to meet `tolerance`, and says which and why
-- or that it cannot promise the tolerance, and what error it can state instead.

**The error** is the L1 distance of the density (of slip times or of periods) to the exact
one, on 150 cells (100 for periods) spanning its 99.9% range: the measure of
`benchmarks/accuracy_cost.py`, whose measured table ships with the package
(`stickslip/_data/accuracy_cost.csv`). A candidate's error is an *upper bound* that holds
with a stated confidence (`Z` standard deviations, one-sided: 97.7%), never a mean:

- **On a measured set** (the model's parameters are one of the table's sets): a
  level-crossing approximation's measured L1 plus the reference's own noise floor (the
  triangle inequality: the reference is a histogram); a Monte Carlo row's mean L1 over the
  repeated seeds plus `Z` times the larger of its measured spread and the spread of an
  N-path histogram's L1 (`SPREAD / sqrt(N)`); more paths than measured by the fitted
  $\sqrt{A^2/N + B^2}$ with the same margin.
- **Off the measured sets** nothing measured elsewhere is borrowed, so no choice carries an
  error across the critical speed or a change of regime. A small pilot run of the model
  itself (exact stepping where the slip is linear-Gaussian) gives the density's noise
  constant $A$ (an N-path histogram's L1 noise is $A/\sqrt N$), the time per path, and the
  fraction of slips still running at `t_max`. Exact stepping is exact in law at any step
  (its miss bound, from the pilot, is the only bias besides the slips cut at `t_max`), so
  its error bound is $(A + Z\,\mathrm{SPREAD})/\sqrt N + B$ and N follows from the
  tolerance. A level-crossing approximation is a candidate only when it would be cheaper
  than that run and costs more than checking it: its L1 to the pilot's histogram plus the
  pilot's own noise bound (triangle inequality again), plus its mass past the pilot's range
  up to twice it and the pilot's mass there (the range is the pilot's estimate of the
  density's), must meet the tolerance.
- **Models with no linear-Gaussian slip** have no exact stepping and no level-crossing
  approximation: Monte Carlo with Euler-Maruyama, whose step bias is not measured for the
  model. The choice then says it cannot promise the tolerance (`promised=False`) and states
  the sampling error it does promise; `first_passage_density` warns and runs it.

**Costs** are the table's measured seconds (level-crossing approximations: per call;
Monte Carlo: per path-step, times the predicted path-steps) scaled to the running machine
by a short calibration (`calibration_seconds()`, a fixed NumPy workload timed here and on
the machine that measured the table). The selection's own wall time is counted
(`MethodChoice.selection_seconds`): a table lookup on a measured set; the pilot (about
0.1 s once compiled) off them.

**The stability rules** (`stickslip.stability`) refuse white noise entering the crossing
variable (no method converges: the slip time is degenerate, see the theory page), and a
level-crossing density that goes negative is never chosen.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import json
import math
import os
import pathlib
import time
import warnings
from importlib import resources

import numpy as np

from . import _histogram
from ._errors import ParameterError, StickSlipError, check_int, check_positive
from ._model import FrictionModel, time_scales
from .stability import ANALYTIC_METHODS as ANALYTIC
from .stability import stability_report

OUTPUTS = ("slip_time", "period")
BINS = {"slip_time": 150, "period": 100}  # cells of the L1 measure (as the benchmark's)
# One-sided confidence of every error bound: Z standard deviations (97.7 %).
Z = 2.0
# Standard deviation of |N(0, s^2)| over s: with sum p (1 - p) <= 1 over the cells, an
# N-path histogram's L1 has a standard deviation of at most SPREAD / sqrt(N).
SPREAD = math.sqrt(1.0 - 2.0 / math.pi)
PILOT_PATHS = 4000
# Pilot step, in units of the slow time scale 1/min|eig(A)| (exact stepping is exact in law
# at any step; this one keeps the pilot near its cheapest, tests/test_exact_detection.py).
PILOT_STEP = 0.2
# A level-crossing approximation is checked off the measured sets only when the Monte Carlo
# choice takes longer than this (seconds, here): the check itself (compiling the kernels on
# a first call) costs about that much.
CHECK_WORTH = 1.0
# A level-crossing approximation is checked on the pilot's range and past it, up to this
# many times it in TAIL_CELLS cells: the pilot's 99.9% quantile (the 4th largest of 4000
# slips) can fall short of the density's own, and a truncation's spurious mass grows with
# the range (seen: a bound of 3.18 against a true error of 3.60 on a converged run's range).
TAIL_REACH = 2.0
TAIL_CELLS = 50
# Euler-Maruyama step for a model without a linear-Gaussian slip (no exact stepping, and no
# time scale to measure it in): the table's smallest.
EULER_STEP = 0.002
# The exact solver's measured miss bound is a quadrature, not a strict bound: at most 3.1x
# the exact count was seen (docs/simulator.md); it is counted 4x, and a moved path moves
# its mass twice in L1.
MISS_FACTOR = 8.0
# A density whose most negative value is below this fraction of its largest is not a density.
NEGATIVE = 1e-3


class SelectionError(StickSlipError):
    """No method meets the tolerance (or none may be used for this model)."""


class SelectionWarning(UserWarning):
    """The method run cannot promise the tolerance (see `MethodChoice.promised`)."""


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One method with its error bound and run time on this machine.

    `settings` are the arguments that run it: `method`, `order`, `normalized` for a
    level-crossing approximation; `solver`, `dt`, `n_paths` for Monte Carlo. `error` is an
    upper bound on the L1 error (`basis` says how it is known); `seconds` the predicted run
    time here; `rejected` why it may not be used (None if it may)."""

    key: str
    kind: str  # "analytic" | "simulation"
    settings: dict
    error: float
    seconds: float
    basis: str
    rejected: str | None = None

    @property
    def label(self) -> str:
        if self.kind == "analytic":
            return self.key
        s = self.settings
        name = "exact stepping" if s["solver"] == "exact" else "Euler-Maruyama"
        return f"Monte Carlo, {name}, dt={s['dt']:g}, {s['n_paths']} paths"


@dataclasses.dataclass(frozen=True)
class MethodChoice:
    """The method chosen for a tolerance, the candidates weighed, and why.

    `promised`: whether `chosen.error` bounds the whole error (False: only the sampling
    error is bounded, see the module docs). `reference_set`: the measured set whose rows
    decided (None off the measured sets). `selection_seconds`: the selection's own wall
    time. `speed`: this machine's calibration time over the table's (costs are scaled by
    it)."""

    tolerance: float
    output: str
    chosen: Candidate
    candidates: tuple[Candidate, ...]
    reference_set: str | None
    promised: bool = True
    selection_seconds: float = 0.0
    speed: float = 1.0
    pilot: dict | None = None

    @property
    def kind(self) -> str:
        return self.chosen.kind

    @property
    def settings(self) -> dict:
        return dict(self.chosen.settings)

    @property
    def reason(self) -> str:
        c = self.chosen
        q = self.output.replace("_", " ")
        if self.reference_set:
            where = f"measured set '{self.reference_set}'"
        else:
            p = self.pilot or {}
            where = "no measured set: a pilot of " + (
                f"{p['n_paths']} paths (noise constant {p['noise_constant']:.3g}, "
                f"{p['seconds']:.2g} s)"
                if p
                else "the model"
            )
        if self.promised:
            head = (
                f"{c.label}: L1 error <= {c.error:.3g} <= {self.tolerance:g} ({c.basis}), "
                f"run time {_seconds(c.seconds)}; the cheapest of the methods that meet the "
                f"tolerance for the {q} density ({where})."
            )
        else:
            head = (
                f"{c.label}: cannot promise L1 <= {self.tolerance:g} for the {q} density: "
                f"{c.basis}; its sampling error is <= {c.error:.3g} "
                f"({Z:g} standard deviations), run time {_seconds(c.seconds)} ({where})."
            )
        lines = [head]
        cheaper = [o for o in self.candidates if o.seconds < c.seconds and o.key != c.key]
        seen = set()
        for o in sorted(cheaper, key=lambda o: o.seconds):
            why = o.rejected or f"L1 bound {o.error:.3g} > {self.tolerance:g}"
            if (o.key, why) in seen or o.kind == "simulation" and not o.rejected:
                continue
            seen.add((o.key, why))
            lines.append(f"  cheaper, not chosen: {o.label} ({_seconds(o.seconds)}): {why}")
        lines.append(
            f"  selection: {_seconds(self.selection_seconds)}; costs scaled to this machine "
            f"by a calibration ({self.speed:.2g}x the table's machine)"
        )
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.reason


@dataclasses.dataclass(frozen=True)
class DensityResult:
    """A density computed by the chosen method: values at `t`, their standard errors
    (Monte Carlo; None for a level-crossing approximation), the choice and the wall time."""

    t: np.ndarray
    density: np.ndarray
    standard_error: np.ndarray | None
    choice: MethodChoice
    seconds: float


# -- the measured table and this machine ----------------------------------------------------
def _table_path():
    return resources.files("stickslip") / "_data" / "accuracy_cost.csv"


@functools.lru_cache(maxsize=4)
def load_table(path: str | None = None) -> tuple[dict, ...]:
    """Rows of a measured accuracy-cost table (`benchmarks/accuracy_cost.py` output; the
    packaged one by default), with numbers parsed."""
    source = pathlib.Path(path) if path is not None else _table_path()
    with source.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    num = (
        "l1", "l1_sd", "ref_floor", "noise_constant", "run_seconds", "compile_seconds",
        "calibration_seconds",
    )  # fmt: skip
    out = []
    for r in rows:
        r = dict(r)
        for k in num:
            r[k] = float(r[k]) if r.get(k) not in (None, "") else math.nan
        r["dt"] = float(r["dt"]) if r["dt"] else None
        r["n_paths"] = int(r["n_paths"]) if r["n_paths"] else None
        r["path_steps"] = float(r["path_steps"]) if r.get("path_steps") else None
        r["params"] = json.loads(r["params"])
        r["note"] = r.get("note") or ""
        out.append(r)
    return tuple(out)


# The columns `select_method` reads from a table.
_COLUMNS = (
    "set", "output", "method", "family", "solver", "dt", "n_paths", "l1", "l1_sd",
    "ref_floor", "run_seconds", "params",
)  # fmt: skip


def _read_table(owner: str, table) -> tuple[dict, ...]:
    """`load_table(table)` with one-line errors naming `table` (never its contents)."""
    if table is not None and not isinstance(table, (str, os.PathLike)):
        raise ParameterError(owner, "table", "must be the path of a CSV file or None", None)
    shown = str(table) if table is not None and len(str(table)) <= 200 else None
    if table is not None and str(table) == "":
        raise ParameterError(owner, "table", "must be the path of a CSV file, not ''", "")
    try:
        rows = load_table(None if table is None else str(table))
    except FileNotFoundError:
        raise ParameterError(owner, "table", "names no file", shown) from None
    except IsADirectoryError:
        raise ParameterError(owner, "table", "is a folder, not a CSV file", shown) from None
    except UnicodeDecodeError:
        raise ParameterError(owner, "table", "is not a UTF-8 text (CSV) file", shown) from None
    except OSError as err:
        why = err.strerror or type(err).__name__
        raise ParameterError(owner, "table", f"cannot be read ({why})", shown) from None
    except (KeyError, ValueError, TypeError, AttributeError, csv.Error):
        raise ParameterError(
            owner, "table", "is not an accuracy-cost table (benchmarks/accuracy_cost.py "
            "output): a column is missing or holds a value of the wrong kind", shown,
        ) from None  # fmt: skip
    if not rows:
        raise ParameterError(owner, "table", "holds no rows", shown)
    missing = [c for c in _COLUMNS if c not in rows[0]]
    if missing or not all(isinstance(r["params"], dict) for r in rows):
        what = f"lacks the column(s) {', '.join(missing)}" if missing else "has params not a dict"
        raise ParameterError(
            owner, "table", f"is not an accuracy-cost table (benchmarks/accuracy_cost.py "
            f"output): it {what}", shown,
        )  # fmt: skip
    return rows


def _workload(x: np.ndarray) -> float:
    y = np.exp(-0.5 * x * x) * np.cos(x)
    s = np.sort(y)
    c = np.cumsum(s)
    m = x[:65536].reshape(256, 256)
    return float(c[-1] + np.sum(m @ m.T))


@functools.lru_cache(maxsize=1)
def calibration_seconds() -> float:
    """Wall time of a fixed NumPy workload on this machine (best of 7, about 0.1 s in all):
    the table stores the one of the machine that measured it, and costs are scaled by the
    ratio."""
    x = np.random.default_rng(0).standard_normal(400_000)
    _workload(x)
    best = math.inf
    for _ in range(7):
        start = time.perf_counter()
        _workload(x)
        best = min(best, time.perf_counter() - start)
    return best


def _speed(rows) -> float:
    """This machine's calibration time over the table's (1 where the table has none)."""
    table = [r["calibration_seconds"] for r in rows if math.isfinite(r["calibration_seconds"])]
    if not table:
        return 1.0
    return calibration_seconds() / float(np.median(table))


def _numeric_params(model) -> dict:
    return {
        k: (v if v is None or isinstance(v, str) else float(v)) for k, v in model.params().items()
    }


def _same_params(model, measured: dict) -> bool:
    """Whether `model` has exactly the parameters of a measured set (defaults filled in)."""
    try:
        other = _numeric_params(type(model)(**measured))
    except Exception:
        return False
    mine = _numeric_params(model)
    if set(mine) != set(other):
        return False
    for k, v in mine.items():
        w = other[k]
        if isinstance(v, float) and isinstance(w, float):
            if not math.isclose(v, w, rel_tol=1e-12, abs_tol=0.0):
                return False
        elif v != w:
            return False
    return True


def _paths_for(tolerance: float, A: float, B: float) -> int | None:
    """Fewest paths (2 significant digits, rounded up) with (A + Z SPREAD)/sqrt(N) + B <=
    tolerance; None if the bias alone reaches it."""
    room = tolerance - B
    if room <= 0:
        return None
    n = ((A + Z * SPREAD) / room) ** 2
    n = max(n, 100.0)
    scale = 10 ** max(0, math.floor(math.log10(n)) - 1)
    return int(math.ceil(n / scale) * scale)


def _mc_bound(A: float, B: float, n: int) -> float:
    return (A + Z * SPREAD) / math.sqrt(n) + B


# -- selection -------------------------------------------------------------------------------
def select_method(
    model: FrictionModel,
    tolerance: float,
    output: str = "slip_time",
    *,
    table: str | None = None,
    t_max: float = 100.0,
    seed: int = 0,
) -> MethodChoice:
    """Choose the cheapest method whose L1 error on the `output` density (`"slip_time"` or
    `"period"`) is known to meet `tolerance` (see the module docs for how errors and costs
    are known).

    `table`: a measured table to use instead of the packaged one. `t_max`, `seed`: of the
    small pilot run made for parameters that were not measured.

    **Returns:** a `MethodChoice`; `str(choice)` says what was chosen and why, and
    `choice.promised` whether its error bound covers the whole error.

    **Raises:** `SelectionError` if no method meets the tolerance or none may be used."""
    start = time.perf_counter()
    owner = "select_method"
    if not isinstance(model, FrictionModel):
        raise ParameterError(owner, "model", f"must be a FrictionModel instance, got {model!r}")
    tolerance = check_positive(owner, "tolerance", tolerance)
    if output not in OUTPUTS:
        raise ParameterError(owner, "output", f"must be one of {', '.join(OUTPUTS)}", output)
    t_max = check_positive(owner, "t_max", t_max)
    seed = check_int(owner, "seed", seed, minimum=0)
    if seed >= 2**64:
        raise ParameterError(owner, "seed", "must be < 2**64", seed)
    table_rows = _read_table(owner, table)
    _check_white_noise(model)
    rows = [r for r in table_rows if r["output"] == output]
    speed = _speed(table_rows)
    sets = {r["set"]: r["params"] for r in rows}
    measured = next((name for name, p in sets.items() if _same_params(model, p)), None)
    pilot = None
    if measured is not None:
        candidates = _measured([r for r in rows if r["set"] == measured], tolerance, speed)
    else:
        pilot = _pilot(model, output, t_max, seed)
        candidates = _unmeasured(model, rows, tolerance, speed, pilot, output)
    candidates.sort(key=lambda c: c.seconds)
    meeting = [c for c in candidates if c.rejected is None and c.error <= tolerance]
    chosen = meeting[0] if meeting else None
    promised = True
    if chosen is None:
        unpromised = [c for c in candidates if c.rejected == _UNPROMISED]
        if unpromised:
            chosen, promised = unpromised[0], False
    if chosen is None:
        usable = [c for c in candidates if c.rejected is None]
        best = min(usable, key=lambda c: c.error, default=None)
        why = sorted({c.rejected for c in candidates if c.rejected and c.rejected != _UNPROMISED})
        text = (
            f"; the smallest error bound available is {best.error:.3g} ({best.label})"
            if best
            else ""
        )
        raise SelectionError(
            f"select_method: no method meets L1 <= {tolerance:g} for the "
            f"{output.replace('_', ' ')} density{text}" + (f" ({'; '.join(why)})" if why else "")
        )
    if not promised:
        chosen = dataclasses.replace(chosen, rejected=None, basis=_UNPROMISED_WHY)
    public_pilot = None
    if pilot is not None:
        public_pilot = {
            k: pilot[k] for k in ("n_paths", "noise_constant", "seconds", "unfinished", "mean_time")
        }
    return MethodChoice(
        tolerance, output, chosen, tuple(candidates), measured, promised,
        time.perf_counter() - start, speed, public_pilot,
    )  # fmt: skip


_UNPROMISED = "unpromised"
_UNPROMISED_WHY = (
    "the model has no linear-Gaussian slip, so no exact stepping, and the step bias of "
    "Euler-Maruyama is not measured for it"
)


def _seconds(s: float) -> str:
    return f"{s * 1e3:.3g} ms" if s < 1 else f"{s:.3g} s"


def _check_white_noise(model):
    """White noise entering the crossing variable: no method converges (fact 1)."""
    if model.crossing_is_smooth:
        return
    if model.linear_gaussian() is None:
        reasons = [
            "noise enters the crossing variable directly, so its slip time has no dt -> 0 limit"
        ]
    else:
        report = stability_report(model, methods=())
        reasons = [] if report.ok("mc_exact") else list(report.failures["mc_exact"])
    if reasons:
        raise SelectionError(
            "select_method: no method can meet a tolerance for this model: "
            + "; ".join(reasons)
            + " (use a smooth, e.g. Ornstein-Uhlenbeck, friction noise)"
        )


# -- a measured set --------------------------------------------------------------------------
def _measured(mine, tolerance, speed) -> list[Candidate]:
    out = []
    for r in mine:
        if r["family"] != "analytic":
            continue
        key = r["method"]
        m, o, n = ANALYTIC[key]
        floor = r["ref_floor"] if math.isfinite(r["ref_floor"]) else 0.0
        rejected = None
        if "negative" in r["note"]:
            rejected = "stability: " + r["note"].split(";")[-1].strip()
        out.append(
            Candidate(
                key, "analytic", dict(method=m, order=o, normalized=n),
                r["l1"] + floor, r["run_seconds"] * speed,
                f"measured L1 {r['l1']:.3g} + the reference's noise {floor:.2g}", rejected,
            )
        )  # fmt: skip
    groups: dict = {}
    for r in mine:
        if r["family"] == "mc":
            n = r["n_paths"]
            sd = max(r["l1_sd"] if math.isfinite(r["l1_sd"]) else 0.0, SPREAD / math.sqrt(n))
            settings = dict(solver=r["solver"], dt=r["dt"], n_paths=n)
            out.append(
                Candidate(
                    f"mc_{r['solver']}", "simulation", settings, r["l1"] + Z * sd,
                    r["run_seconds"] * speed,
                    f"measured: mean L1 {r['l1']:.3g} over {_repeats(r)} + {Z:g} sd {sd:.2g}",
                )
            )  # fmt: skip
            groups.setdefault((r["solver"], r["dt"]), []).append(r)
    # More paths than measured: the fit of L1(N) with the same margin.
    for (solver, dt), group in groups.items():
        A, B = _fit(group)
        n = _paths_for(tolerance, A, B)
        largest = max(r["n_paths"] for r in group)
        if n is None or n <= largest:
            continue
        per_step = float(np.median([r["run_seconds"] / r["path_steps"] for r in group]))
        steps = float(np.median([r["path_steps"] / r["n_paths"] for r in group]))
        out.append(
            Candidate(
                f"mc_{solver}", "simulation", dict(solver=solver, dt=dt, n_paths=n),
                _mc_bound(A, B, n), per_step * steps * n * speed,
                f"predicted from the measured rows: noise {A:.3g}/sqrt(N), bias {B:.2g}, "
                f"+ {Z:g} sd",
            )
        )  # fmt: skip
    return out


def _repeats(r) -> str:
    k = r.get("repeats")
    return f"{k} seeds" if k not in (None, "", "1") else "one seed"


def _fit(group) -> tuple[float, float]:
    """(A, B) of L1(N) ~ sqrt(A^2/N + B^2), least squares on L1^2 in relative terms."""
    n = np.array([r["n_paths"] for r in group], float)
    e2 = np.array([r["l1"] for r in group]) ** 2
    X = np.stack([1 / n, np.ones_like(n)], axis=1) / e2[:, None]
    coef, *_ = np.linalg.lstsq(X, np.ones_like(n), rcond=None)
    a2, b2 = max(coef[0], 0.0), max(coef[1], 0.0)
    if a2 == 0.0:  # degenerate fit: attribute everything to noise at the largest N
        a2 = float(np.max(e2 * n))
    return math.sqrt(a2), math.sqrt(b2)


# -- off the measured sets -------------------------------------------------------------------
def _pilot(model, output, t_max, seed) -> dict:
    """A small Monte Carlo run of the model itself: the histogram's noise constant
    (sqrt(2/pi) sum over the cells of sqrt(P (1 - P)): an N-path histogram's L1 noise is
    about that over sqrt(N)), its cells and masses, the mean simulated time per path, the
    fraction of slips still running at `t_max`, and the exact solver's miss bound."""
    from ._simulate import simulate

    scales = time_scales(model)
    if scales is not None:
        solver, dt = "exact", PILOT_STEP * scales[1]
    else:
        solver, dt = "euler", EULER_STEP
    start = time.perf_counter()
    ens = simulate(model, PILOT_PATHS, dt, t_max, seed=seed + 7919, solver=solver, progress=False)
    seconds = time.perf_counter() - start
    x = np.asarray(getattr(ens, output), float)
    finite = x[np.isfinite(x)]
    top = float(np.quantile(finite, 0.999)) if finite.size else t_max
    edges = np.linspace(0.0, max(top, 1e-12), BINS[output] + 1)
    counts = _histogram.counts(finite, edges)
    p = counts / PILOT_PATHS
    slip = np.asarray(ens.slip_time, float)
    return dict(
        n_paths=PILOT_PATHS,
        t_max=t_max,
        solver=solver,
        dt=dt,
        noise_constant=math.sqrt(2 / math.pi) * float(np.sum(np.sqrt(p * (1 - p)))),
        mean_time=float(np.mean(np.where(np.isfinite(slip), slip, t_max))),
        unfinished=float(np.mean(~np.isfinite(slip))),
        miss=float(ens.stats.get("miss_bound", 0.0)),
        beyond=float(np.sum(finite > top)) / PILOT_PATHS,  # mass past the range
        edges=edges,
        mass=p,
        seconds=seconds,
    )


@functools.lru_cache(maxsize=64)
def _set_scale(name: str, params: str) -> float | None:
    """The slow time scale of a measured set (the benchmark measures the `langevin` model)."""
    from ._registry import get_model

    try:
        return time_scales(get_model(name)(**json.loads(params)))[1]
    except Exception:
        return None


def _unmeasured(model, rows, tolerance, speed, pilot, output) -> list[Candidate]:
    A = pilot["noise_constant"]
    cut = pilot["unfinished"]
    out = []
    scales = time_scales(model)
    if scales is not None:
        slow = scales[1]
        # Exact stepping: the table's steps in units of each set's slow time scale; the
        # measured cost per path-step at that step (median over the sets).
        per_step: dict = {}
        for r in rows:
            if r["family"] != "mc" or r["solver"] != "exact" or not r["path_steps"]:
                continue
            s = _set_scale(r.get("model") or "langevin", json.dumps(r["params"], sort_keys=True))
            if not s:
                continue
            u = float(f"{r['dt'] / s:.3g}")
            per_step.setdefault(u, []).append(r["run_seconds"] / r["path_steps"])
        B = cut + MISS_FACTOR * pilot["miss"]
        for u, costs in sorted(per_step.items()):
            dt = float(f"{u * slow:.3g}")
            cost = float(np.median(costs)) * speed * pilot["mean_time"] / dt
            n = _paths_for(tolerance, A, B)
            basis = (
                f"exact in law: sampling noise {A:.3g}/sqrt(N) from the pilot + {Z:g} sd, "
                f"miss bound {MISS_FACTOR * pilot['miss']:.2g}"
                + (f", slips cut at t_max {cut:.2g}" if cut else "")
            )
            if n is None:
                out.append(
                    Candidate(
                        "mc_exact", "simulation", dict(solver="exact", dt=dt, n_paths=PILOT_PATHS),
                        B, cost * PILOT_PATHS, basis,
                        f"{cut:.2g} of the slips are longer than t_max = {pilot['t_max']:g}: "
                        "raise t_max",
                    )
                )  # fmt: skip
                continue
            out.append(
                Candidate(
                    "mc_exact", "simulation", dict(solver="exact", dt=dt, n_paths=n),
                    _mc_bound(A, B, n), cost * n, basis,
                )
            )  # fmt: skip
        out += _checked_analytic(model, rows, tolerance, speed, pilot, output, out)
        return out
    # No linear-Gaussian slip: Euler-Maruyama at the table's smallest step (in units of the
    # model's fastest time scale where it has one); only the sampling error is bounded.
    dt = EULER_STEP  # no linear-Gaussian slip: no time scale to scale it by
    euler = [r for r in rows if r["family"] == "mc" and r["solver"] == "euler" and r["path_steps"]]
    per = float(np.median([r["run_seconds"] / r["path_steps"] for r in euler])) if euler else 1e-7
    n = _paths_for(tolerance, A, cut)
    if n is None:
        return []
    out.append(
        Candidate(
            "mc_euler", "simulation", dict(solver="euler", dt=dt, n_paths=n),
            _mc_bound(A, cut, n), per * speed * pilot["mean_time"] / dt * n,
            "sampling error only", _UNPROMISED,
        )
    )  # fmt: skip
    return out


def _checked_analytic(model, rows, tolerance, speed, pilot, output, mc) -> list[Candidate]:
    """Level-crossing approximations off the measured sets, each checked against the pilot
    where that can pay (see the module docs)."""
    best = min(
        (c.seconds for c in mc if c.rejected is None and c.error <= tolerance), default=math.inf
    )
    noise = _mc_bound(pilot["noise_constant"], 0.0, pilot["n_paths"])
    if noise >= tolerance:
        return []  # the pilot cannot tell an error below the tolerance from its own noise
    costs: dict = {}
    for r in rows:
        if r["family"] == "analytic":
            costs.setdefault(r["method"], []).append(r["run_seconds"] * speed)
    out = []
    for key, seconds in sorted(costs.items(), key=lambda kv: float(np.median(kv[1]))):
        cost = float(np.median(seconds))
        m, o, n = ANALYTIC[key]
        settings = dict(method=m, order=o, normalized=n)
        if cost >= best or best <= CHECK_WORTH:
            continue  # Monte Carlo is cheaper than the approximation, or than checking it
        # The pilot's range is itself an estimate (its 99.9% quantile): the approximation is
        # also evaluated past it, up to TAIL_REACH times it, and its mass there counts as
        # error (with the pilot's own mass there), so that the bound holds on any range up to
        # that (the density's true 99.9% range in particular).
        edges = pilot["edges"]
        top, k = float(edges[-1]), edges.size - 1
        ext = np.concatenate([edges, np.linspace(top, TAIL_REACH * top, TAIL_CELLS + 1)[1:]])
        start = time.perf_counter()
        values = _analytic_cells(model, settings, output, ext)
        cost = time.perf_counter() - start
        width = np.diff(ext)
        inside = values[:k]  # the pilot's range (the stability rule looks at it alone)
        l1 = float(np.sum(np.abs(inside * width[:k] - pilot["mass"])))
        tail = float(np.sum(np.abs(values[k:] * width[k:]))) + pilot["beyond"]
        bound = l1 + noise + pilot["unfinished"] + tail
        rejected = None
        if np.min(inside) < -NEGATIVE * np.max(np.abs(inside)):
            rejected = "stability: density negative"
        out.append(
            Candidate(
                key, "analytic", settings, bound, cost,
                f"checked: L1 {l1:.3g} to the pilot + its noise {noise:.2g} + mass past its "
                f"range {tail:.2g}", rejected,
            )
        )  # fmt: skip
        best = min(best, cost) if rejected is None and bound <= tolerance else best
    return out


def _analytic_cells(model, settings, output, edges) -> np.ndarray:
    """One approximation as cell averages (as the accuracy-cost benchmark computes them)."""
    from ._estimate import CrossingEstimator
    from ._notes import collecting_notes

    est = CrossingEstimator(model, progress=False)
    args = (settings["method"], settings["order"], settings["normalized"])
    with collecting_notes():  # (its notes dropped: thread-safe, unlike catch_warnings)
        if output == "slip_time":
            return est.first_passage_cells(edges, *args)
        return np.asarray(est.period_density(0.5 * (edges[1:] + edges[:-1]), *args), float)


# -- computing a density by the chosen method ------------------------------------------------
def first_passage_density(
    model: FrictionModel,
    t,
    tolerance: float = 0.05,
    *,
    output: str = "slip_time",
    seed: int = 0,
    t_max: float | None = None,
    table: str | None = None,
) -> DensityResult:
    """The slip-time (first-passage) or period density at `t` by the cheapest method that
    meets `tolerance` (L1, see `select_method`).

    `t` must be increasing and evenly spaced: the result is the density's average over the
    cells centred on `t` (a histogram for a Monte Carlo choice, the exact cell averages of a
    level-crossing one), as the promised L1 error measures it. `seed`: of the
    Monte Carlo run if one is chosen; `t_max`: its longest slip (default: 100 or 1.5 t[-1]).

    **Returns:** a `DensityResult` whose `choice` says which method was used and why."""
    owner = "first_passage_density"
    try:
        t = np.asarray(t)
    except (TypeError, ValueError):  # ragged nestings
        t = np.asarray(None)
    if t.dtype.kind not in "iuf":
        raise ParameterError(owner, "t", "must be a 1-d array of at least two finite times")
    t = t.astype(float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)):
        raise ParameterError(owner, "t", "must be a 1-d array of at least two finite times")
    step = np.diff(t)
    if np.any(step <= 0) or np.ptp(step) > 1e-6 * step.mean():
        raise ParameterError(owner, "t", "must be increasing and evenly spaced")
    t_max = max(100.0, 1.5 * float(t[-1])) if t_max is None else t_max
    t_max = check_positive(owner, "t_max", t_max)
    choice = select_method(model, tolerance, output, table=table, t_max=t_max, seed=seed)
    if not choice.promised:
        warnings.warn(choice.reason.splitlines()[0], SelectionWarning, stacklevel=2)
    start = time.perf_counter()
    s = choice.settings
    se = None
    h = step.mean()
    edges = np.concatenate([t - h / 2, [t[-1] + h / 2]])
    if choice.kind == "analytic":
        from ._estimate import CrossingEstimator
        from ._notes import collecting_notes

        est = CrossingEstimator(model)
        args = (s["method"], s["order"], s["normalized"])
        with collecting_notes():  # (its notes dropped: thread-safe, unlike catch_warnings)
            if output == "slip_time":
                # Cell averages, as the histogram of a Monte Carlo choice (no mass below 0).
                inside = np.maximum(edges, 0.0)
                density = np.zeros(t.size)
                ok = inside[1:] > inside[:-1]
                cells = np.concatenate([inside[:-1][ok], inside[1:][ok][-1:]])
                density[ok] = est.first_passage_cells(cells, *args) * np.diff(cells) / h
            else:
                density = est.period_density(t, *args)
    else:
        from ._simulate import simulate

        ens = simulate(
            model, s["n_paths"], s["dt"], t_max, seed=seed, solver=s["solver"], progress=False
        )
        x = np.asarray(getattr(ens, output))
        counts = _histogram.counts(x, edges)  # nan (no stick) not counted
        p = counts / s["n_paths"]
        density, se = p / h, np.sqrt(p * (1 - p) / s["n_paths"]) / h
    return DensityResult(t, np.asarray(density, float), se, choice, time.perf_counter() - start)
