r"""Model no more than a scene needs: choose the cheapest method that meets a tolerance.

`select_method(model, tolerance)` picks, among the level-crossing approximations and Monte
Carlo runs (exact stepping or Euler-Maruyama, at some step and number of paths), the one
with the smallest run time whose error meets `tolerance`, and says which and why.

**The error** is the L1 distance of the density (of slip times or of periods) to the exact
one, on 150 cells (100 for periods) spanning its 99.9% range: the measure of
`benchmarks/accuracy_cost.py`, whose measured table ships with the package
(`stickslip/_data/accuracy_cost.csv`) and decides the choice:

- parameters of a measured set: the measured errors and run times of that set's rows (Monte
  Carlo rows are means over repeated seeds); Monte Carlo with more paths than measured is
  extrapolated as below when no measured row meets the tolerance;
- other parameters: a level-crossing approximation is a candidate only within 25% of a
  measured set (in every parameter), with that set's measured error. Monte Carlo is always
  a candidate, its error predicted as $\sqrt{A^2/N + B^2}$: the sampling noise $A/\sqrt N$ is
  scaled from the measured fit by the density's own noise constant (from a small pilot run),
  and the bias floor $B$ of each (solver, step) is the measured one, the step scaled with the
  model's fastest time scale. The run time is the measured cost per path-step times the
  pilot's steps per path.

**The stability rules** (`stickslip.stability`) then veto: a level-crossing approximation
whose density or escape rate goes negative, or (off the measured sets, where no measured L1
counts it) whose mass is off or whose truncation does not normalise, is not chosen; with
white noise entering the crossing variable no method converges (the slip time is
degenerate, see the theory page) and the selection refuses.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import json
import math
import pathlib
import time
import warnings
from importlib import resources

import numpy as np

from ._errors import ParameterError, StickSlipError, check_positive
from ._model import FrictionModel
from .stability import ANALYTIC_METHODS as ANALYTIC
from .stability import stability_report

OUTPUTS = ("slip_time", "period")
# A level-crossing approximation's measured error is trusted for parameters within this
# factor of a measured set (every parameter); beyond it, its error is unknown.
NEAR = math.log(1.25)
# Monte Carlo path counts tried when extrapolating (1-2-5 ladder).
LADDER = [int(m * 10**k) for k in range(3, 8) for m in (1, 2, 5)]
# Predicted (not measured) errors must meet the tolerance with this margin.
MARGIN = 0.9
PILOT_PATHS = 4000


class SelectionError(StickSlipError):
    """No method meets the tolerance (or none may be used for this model)."""


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One method with its (measured or predicted) error and run time.

    `settings` are the arguments that run it: `method`, `order`, `normalized` for a
    level-crossing approximation; `solver`, `dt`, `n_paths` for Monte Carlo. `basis` says
    where the numbers come from; `rejected` why it may not be used (None if it may)."""

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
    """The method chosen for a tolerance, the candidates weighed, and why."""

    tolerance: float
    output: str
    chosen: Candidate
    candidates: tuple[Candidate, ...]
    reference_set: str | None
    distance: float

    @property
    def kind(self) -> str:
        return self.chosen.kind

    @property
    def settings(self) -> dict:
        return dict(self.chosen.settings)

    @property
    def reason(self) -> str:
        c = self.chosen
        where = (
            f"measured set '{self.reference_set}'"
            if self.distance == 0
            else (
                f"nearest measured set '{self.reference_set}' "
                f"(parameters within a factor {math.exp(self.distance):.3g})"
                if self.reference_set
                else "no measured set"
            )
        )
        lines = [
            f"{c.label}: L1 error {c.error:.3g} <= {self.tolerance:g} ({c.basis}), "
            f"run time {_seconds(c.seconds)}; the cheapest of the methods that meet the "
            f"tolerance for the {self.output.replace('_', ' ')} density ({where})."
        ]
        cheaper = [o for o in self.candidates if o.seconds < c.seconds and o.key != c.key]
        seen = set()
        for o in sorted(cheaper, key=lambda o: o.seconds):
            why = o.rejected or f"L1 {o.error:.3g} > {self.tolerance:g}"
            if (o.key, why) in seen or o.kind == "simulation" and not o.rejected:
                continue
            seen.add((o.key, why))
            lines.append(f"  cheaper, not chosen: {o.label} ({_seconds(o.seconds)}): {why}")
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


# -- the measured table ----------------------------------------------------------------------
def _table_path():
    return resources.files("stickslip") / "_data" / "accuracy_cost.csv"


@functools.lru_cache(maxsize=4)
def load_table(path: str | None = None) -> tuple[dict, ...]:
    """Rows of a measured accuracy-cost table (`benchmarks/accuracy_cost.py` output; the
    packaged one by default), with numbers parsed."""
    source = pathlib.Path(path) if path is not None else _table_path()
    with source.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    num = ("l1", "l1_sd", "ref_floor", "noise_constant", "run_seconds", "compile_seconds")
    out = []
    for r in rows:
        r = dict(r)
        for k in num:
            r[k] = float(r[k]) if r.get(k) not in (None, "") else math.nan
        r["dt"] = float(r["dt"]) if r["dt"] else None
        r["n_paths"] = int(r["n_paths"]) if r["n_paths"] else None
        r["path_steps"] = float(r["path_steps"]) if r.get("path_steps") else None
        r["params"] = json.loads(r["params"])
        out.append(r)
    return tuple(out)


def _distance(params: dict, measured: dict) -> float:
    """Largest |log ratio| over the parameters (inf if the names or the kind differ)."""
    if set(params) != set(measured):
        return math.inf
    d = 0.0
    for k, v in params.items():
        w = measured[k]
        if isinstance(v, str) or isinstance(w, str) or v is None or w is None:
            if v != w:
                return math.inf
            continue
        v, w = float(v), float(w)
        if v == w:
            continue
        if v <= 0 or w <= 0:
            return math.inf
        d = max(d, abs(math.log(v / w)))
    return d


def _as_model_params(model, measured: dict) -> dict:
    """A measured set's parameters as `model`'s class would hold them (defaults filled in);
    empty if that class cannot take them."""
    try:
        return _numeric_params(type(model)(**measured))
    except Exception:
        return {}


def _numeric_params(model) -> dict:
    return {
        k: (v if v is None or isinstance(v, str) else float(v)) for k, v in model.params().items()
    }


def _time_scale(model) -> float | None:
    """The fastest time scale of a linear-Gaussian slip, 1 / max |eig(A)|."""
    lg = model.linear_gaussian()
    if lg is None:
        return None
    return 1.0 / float(np.max(np.abs(np.linalg.eigvals(np.asarray(lg.A)))))


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
    `"period"`) meets `tolerance` (see the module docs for how errors and costs are known).

    `table`: a measured table to use instead of the packaged one. `t_max`, `seed`: of the
    small pilot run made for parameters that were not measured.

    **Returns:** a `MethodChoice`; `str(choice)` says what was chosen and why.

    **Raises:** `SelectionError` if no method meets the tolerance or none may be used."""
    owner = "select_method"
    if not isinstance(model, FrictionModel):
        raise ParameterError(owner, "model", f"must be a FrictionModel instance, got {model!r}")
    tolerance = check_positive(owner, "tolerance", tolerance)
    if output not in OUTPUTS:
        raise ParameterError(owner, "output", f"must be one of {', '.join(OUTPUTS)}", output)
    _check_white_noise(model)
    rows = [r for r in load_table(table) if r["output"] == output]
    params = _numeric_params(model)
    sets = {r["set"]: r["params"] for r in rows}
    dist = {name: _distance(params, _as_model_params(model, p)) for name, p in sets.items()}
    nearest = min(dist, key=dist.get) if dist else None
    d = dist[nearest] if nearest is not None else math.inf
    if d < 1e-12:
        d = 0.0
    mine = [r for r in rows if r["set"] == nearest] if math.isfinite(d) else []
    candidates = []
    has_lg = model.linear_gaussian() is not None
    for r in mine:
        if r["family"] != "analytic":
            continue
        key = r["method"]
        m, o, n = ANALYTIC[key]
        basis = "measured" if d == 0 else f"measured on '{nearest}'"
        rejected = None
        if not has_lg:
            rejected = "needs a linear-Gaussian model"
        elif d > NEAR:
            rejected = f"no measured error within {math.exp(NEAR):g}x of these parameters"
        candidates.append(
            Candidate(
                key,
                "analytic",
                dict(method=m, order=o, normalized=n),
                r["l1"],
                r["run_seconds"],
                basis,
                rejected,
            )
        )
    if d == 0:
        for r in mine:
            if r["family"] == "mc":
                candidates.append(_mc_row(r, "measured"))
    extrapolate = d != 0 or not any(
        c.kind == "simulation" and c.error <= tolerance for c in candidates
    )
    if extrapolate:
        candidates += _mc_predicted(model, mine, rows, tolerance, d, t_max, seed, output)
    candidates.sort(key=lambda c: c.seconds)
    chosen = None
    vetted = []
    for c in candidates:
        if c.rejected is None and c.error <= tolerance and chosen is None:
            veto = _veto(model, c, d)
            if veto:
                c = dataclasses.replace(c, rejected=veto)
            else:
                chosen = c
        vetted.append(c)
    if chosen is None:
        usable = [c for c in vetted if c.rejected is None]
        best = min(usable, key=lambda c: c.error, default=None)
        text = f"; the smallest error available is {best.error:.3g} ({best.label})" if best else ""
        raise SelectionError(
            f"select_method: no method meets L1 <= {tolerance:g} for the "
            f"{output.replace('_', ' ')} density{text}"
        )
    return MethodChoice(tolerance, output, chosen, tuple(vetted), nearest, d)


def _seconds(s: float) -> str:
    return f"{s * 1e3:.3g} ms" if s < 1 else f"{s:.3g} s"


def _mc_row(r, basis) -> Candidate:
    settings = dict(solver=r["solver"], dt=r["dt"], n_paths=r["n_paths"])
    return Candidate(f"mc_{r['solver']}", "simulation", settings, r["l1"], r["run_seconds"], basis)


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


def _veto(model, c: Candidate, distance: float) -> str | None:
    """The stability rules for one candidate (level-crossing approximations only). On a
    measured set the measured L1 already counts a lost or excess mass: only a density or
    escape rate that goes negative (not a density at all) vetoes there."""
    if c.kind != "analytic":
        return None
    report = stability_report(model, methods=(c.key,))
    failures = report.failures.get(c.key, ())
    if distance == 0:
        failures = [f for f in failures if "negative" in f]
    return "stability: " + ", ".join(failures) if failures else None


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


def _mc_predicted(model, mine, rows, tolerance, d, t_max, seed, output):
    """Monte Carlo candidates with predicted error and run time (see the module docs)."""
    source = mine or [r for r in rows if r["set"] == "public"]
    if not source:
        return []
    groups = {}
    for r in source:
        if r["family"] == "mc":
            groups.setdefault((r["solver"], r["dt"]), []).append(r)
    has_lg = model.linear_gaussian() is not None
    set_params = source[0]["params"]
    scale, pilot = 1.0, None
    if d != 0:
        ts_model = _time_scale(model)
        try:
            ts_set = _time_scale(type(model)(**set_params))
        except Exception:
            ts_set = None
        if ts_model and ts_set:
            scale = ts_model / ts_set
        pilot = _pilot(model, output, t_max, seed)
    out = []
    for (solver, dt), group in groups.items():
        if solver == "exact" and not has_lg:
            continue
        A, B = _fit(group)
        if pilot is not None:
            A *= pilot["noise_constant"] / group[0]["noise_constant"]
        dt_new = dt * scale
        per_step = float(np.median([r["run_seconds"] / r["path_steps"] for r in group]))
        if pilot is None:
            steps = float(np.median([r["path_steps"] / r["n_paths"] for r in group]))
        else:
            steps = pilot["mean_time"] / dt_new
        basis = (
            f"predicted: sampling noise {A:.3g}/sqrt(N), bias floor {B:.3g} "
            f"(fit to '{source[0]['set']}')"
        )
        settings = dict(solver=solver, dt=float(f"{dt_new:.3g}"))
        if B >= MARGIN * tolerance:
            out.append(
                Candidate(
                    f"mc_{solver}",
                    "simulation",
                    dict(settings, n_paths=LADDER[-1]),
                    B,
                    per_step * steps * LADDER[-1],
                    basis,
                    f"bias floor {B:.3g} of this step is above the tolerance",
                )
            )
            continue
        for n in LADDER:
            err = math.sqrt(A * A / n + B * B)
            if err <= MARGIN * tolerance:
                out.append(
                    Candidate(
                        f"mc_{solver}",
                        "simulation",
                        dict(settings, n_paths=n),
                        err,
                        per_step * steps * n,
                        basis,
                    )
                )
                break
    return out


def _pilot(model, output, t_max, seed) -> dict:
    """A small Monte Carlo run: the noise constant of the density (sqrt(2/pi) sum over
    the 150 (100) cells of sqrt(P (1 - P)), the L1 noise of an N-path histogram times
    sqrt(N)) and the mean simulated time per path."""
    from ._simulate import simulate

    dt = 0.02 * (_time_scale(model) or 1.0)
    ens = simulate(model, PILOT_PATHS, dt, t_max, seed=seed + 7919, progress=False)
    x = np.asarray(getattr(ens, output))
    x = x[np.isfinite(x)]
    bins = 150 if output == "slip_time" else 100
    top = float(np.quantile(x, 0.999)) if x.size else 1.0
    counts, _ = np.histogram(x, bins=np.linspace(0.0, top, bins + 1))
    p = counts / PILOT_PATHS
    t = np.where(np.isfinite(ens.slip_time), ens.slip_time, t_max)
    return dict(
        noise_constant=math.sqrt(2 / math.pi) * float(np.sum(np.sqrt(p * (1 - p)))),
        mean_time=float(np.mean(t)),
    )


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

    `t` must be increasing and evenly spaced: a Monte Carlo result is a histogram on the
    cells centred on `t`, a level-crossing one is the density at `t` (the period density is
    the cell average, as `CrossingEstimator.period_density` gives it). `seed`: of the
    Monte Carlo run if one is chosen; `t_max`: its longest slip (default: 100 or 1.5 t[-1]).

    **Returns:** a `DensityResult` whose `choice` says which method was used and why."""
    owner = "first_passage_density"
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)):
        raise ParameterError(owner, "t", "must be a 1-d array of at least two finite times")
    step = np.diff(t)
    if np.any(step <= 0) or np.ptp(step) > 1e-6 * step.mean():
        raise ParameterError(owner, "t", "must be increasing and evenly spaced")
    t_max = max(100.0, 1.5 * float(t[-1])) if t_max is None else t_max
    t_max = check_positive(owner, "t_max", t_max)
    choice = select_method(model, tolerance, output, table=table, t_max=t_max, seed=seed)
    start = time.perf_counter()
    s = choice.settings
    se = None
    if choice.kind == "analytic":
        from ._estimate import ApproximationWarning, CrossingEstimator

        est = CrossingEstimator(model)
        args = (s["method"], s["order"], s["normalized"])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ApproximationWarning)
            if output == "slip_time":
                density = est.first_passage(t, *args)
            else:
                density = est.period_density(t, *args)
    else:
        from ._simulate import simulate

        ens = simulate(
            model, s["n_paths"], s["dt"], t_max, seed=seed, solver=s["solver"], progress=False
        )
        h = step.mean()
        edges = np.concatenate([t - h / 2, [t[-1] + h / 2]])
        x = np.asarray(getattr(ens, output))
        counts, _ = np.histogram(x[np.isfinite(x)], bins=edges)
        p = counts / s["n_paths"]
        density, se = p / h, np.sqrt(p * (1 - p) / s["n_paths"]) / h
    return DensityResult(t, np.asarray(density, float), se, choice, time.perf_counter() - start)
