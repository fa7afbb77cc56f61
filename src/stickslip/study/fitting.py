"""`stickslip fit STUDY.yaml`: a study's `fit` block run, and its results written.

The data come from a CSV file of per-cycle values; the results are `fit.json` (estimates,
95 % intervals, log-likelihood, method, settings), `fit.png` (data against the fitted model,
log-likelihood along each parameter) and `summary.md`, made in a temporary directory and
moved into place at the end, as `run` does.
"""

from __future__ import annotations

import json
import os
import pathlib
import shutil
import tempfile

import numpy as np

from .load import StudyError, load_study


def read_cycles_csv(path: pathlib.Path, columns=None, source: str | None = None) -> dict:
    """Per-cycle columns of a CSV file with a header; bad files are one `StudyError`."""
    from .._fit import KINDS

    name = source or str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise StudyError(name, "fit.data", f"no such file: {path}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise StudyError(name, "fit.data", f"{path} cannot be read ({err})") from None
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    if not lines:
        raise StudyError(name, "fit.data", f"{path} is empty")
    header = [h.strip() for h in lines[0].split(",")]
    known = [h for h in header if h in KINDS]
    wanted = list(columns) if columns else known
    missing = [c for c in wanted if c not in header]
    if not wanted or missing:
        raise StudyError(
            name, "fit.data", f"{path} has no column {', '.join(missing or KINDS)} (its header: "
            f"{', '.join(header)})",
        )  # fmt: skip
    if len(lines) < 2:
        raise StudyError(name, "fit.data", f"{path} has a header and no rows")
    try:
        rows = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]], dtype=float)
    except ValueError as err:
        raise StudyError(name, "fit.data", f"{path}: a value is not a number ({err})") from None
    if rows.ndim != 2 or rows.shape[1] != len(header):
        raise StudyError(name, "fit.data", f"{path}: rows must have {len(header)} values")
    data = {c: rows[:, header.index(c)] for c in wanted}
    for c, x in data.items():
        if np.any(x[np.isfinite(x)] < 0) and c != "slip_distance":
            raise StudyError(name, "fit.data", f"{path}: column {c} has negative values")
    return data


def run_fit(study, out=None, *, overrides=None, force: bool = False, progress: bool = False):
    """Run the `fit` block of `study` (a path to a YAML file, a dict or a `Study`); write
    the results to `out` if given. Returns the `FitResult`."""
    from .._errors import ParameterError
    from .._fit import fit
    from .run import _check_out

    base = pathlib.Path(study).parent if isinstance(study, (str, os.PathLike)) else pathlib.Path()
    source = str(study) if isinstance(study, (str, os.PathLike)) else None
    study = load_study(study, overrides)
    if study.fit is None:
        raise StudyError(source, "fit", "is missing: add a fit block (data, free) to the study")
    out_dir = None if out is None else _check_out(pathlib.Path(out), force)
    spec = study.fit
    path = pathlib.Path(spec.data)
    data = read_cycles_csv(path if path.is_absolute() else base / path, spec.columns, source)
    free = {k: tuple(v) for k, v in spec.free.items()}
    fixed = {k: v for k, v in study.model.params.items() if k not in free}
    try:
        result = fit(
            study.model.name, data, free, fixed, seed=spec.seed, n_sim=spec.n_sim, dt=spec.dt,
            t_max=spec.t_max, trace=spec.trace, sampling=spec.sampling, progress=progress,
        )  # fmt: skip
    except ParameterError as err:
        field = err.parameter if err.parameter.startswith("data") else f"fit.{err.parameter}"
        raise StudyError(source, field.replace("data", "fit.data", 1), err.reason) from None
    if out_dir is not None:
        write_fit(result, study, out_dir, force)
    return result


def write_fit(result, study, out: pathlib.Path, force: bool):
    from .write import _replace

    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = pathlib.Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        d = result.diagnostics
        record = dict(
            model=study.model.name,
            estimate=result.estimate,
            ci95={k: list(v) for k, v in result.ci.items()},
            log_likelihood=result.log_likelihood,
            method=result.method,
            fixed={k: v for k, v in study.model.params.items() if k not in result.estimate},
            settings={
                k: d[k] for k in ("n_sim", "dt", "t_max", "seed", "trace", "sampling", "n_data")
            },
            covariance=d["covariance"],
            evaluations=d["evaluations"],
            seconds=d["seconds"],
            warnings=d["warnings"],
        )
        (tmp / "fit.json").write_text(json.dumps(record, indent=2, default=float) + "\n")
        result.plot(tmp / "fit.png")
        title = study.title or f"Fit of {study.model.name}"
        lines = [f"# {title}", "", result.method, "", "| parameter | estimate | 95 % interval |",
                 "|---|---|---|"]  # fmt: skip
        for k, v in result.estimate.items():
            lo, hi = result.ci[k]
            lines.append(f"| {k} | {v:.4g} | [{lo:.4g}, {hi:.4g}] |")
        lines += ["", f"log-likelihood {result.log_likelihood:.2f}; {d['evaluations']} points "
                  f"evaluated in {d['seconds']:.1f} s; data: "
                  + ", ".join(f"{n} {k}" for k, n in d["n_data"].items()), ""]  # fmt: skip
        lines += [f"- warning: {w}" for w in d["warnings"]]
        lines += ["", "![fit](fit.png)", ""]
        (tmp / "summary.md").write_text("\n".join(lines))
        _replace(tmp, out, force)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
