"""`stickslip fit STUDY.yaml`: a study's `fit` block run, and its results written.

The data come from a CSV file: the cycles `stickslip cycles` wrote (its `# stickslip cycles`
header keeps the extraction's settings: read with `read_cycles` and fitted with the
measurement in the model), or any other table of per-cycle values (fitted as per-cycle
values of the model). The results are `fit.json` (estimates, 95 % intervals,
log-likelihood, goodness-of-fit p-values, method, settings, the measurement, the optimiser,
the Monte Carlo noise check, the warnings), `fit.png` (data against the fitted model,
log-likelihood along each parameter) and `summary.md` (the estimates with their intervals,
the p-values and whether the data reject the model), made in a temporary directory and
moved into place at the end, as `run` does.
"""

from __future__ import annotations

import codecs
import dataclasses
import difflib
import json
import os
import pathlib
import re
import shutil
import stat
import tempfile
import warnings

import numpy as np

from .load import StudyError, load_study

# A table of cycles is small (`stickslip cycles` writes about 60 B a row): the cap keeps a
# path naming something else (a disk image, a log) from being read whole.
MAX_DATA_BYTES = 256 * 2**20
_SHOWN = 5  # rows named in a message
_CYCLES_HEADER = "# stickslip cycles"  # the first line `Cycles.to_csv` writes


def read_cycles_csv(path: pathlib.Path, columns=None, source: str | None = None) -> dict:
    """Per-cycle columns of a CSV file with a header (UTF-8, a byte-order mark allowed);
    bad files are one `StudyError` at `fit.data`, which never quotes the file: a regular
    file of at most `MAX_DATA_BYTES`, text, the columns asked for, a number in each of their
    cells, no `nan` or `inf` (refused with the lines, not dropped: a table with holes is the
    user's to mend, knowing why they are there), durations of the right sign."""
    from .._inference.data import KINDS

    name = source or str(path)
    text = _read_text(path, name)
    lines = [
        (number, ln)
        for number, ln in enumerate(text.splitlines(), 1)
        if ln.strip() and not ln.lstrip().startswith("#")
    ]
    if not lines:
        raise _data_error(name, path, "is empty")
    header = [h.strip().strip('"').strip() for h in lines[0][1].split(",")]
    wanted = list(columns) if columns else [h for h in header if h in KINDS]
    missing = [c for c in wanted if c not in header]
    if not wanted or missing:
        shown = ", ".join(missing) if missing else f"{' or '.join(KINDS)}"
        raise _data_error(name, path, f"has no column {shown} ({_header_hint(header, KINDS)})")
    for c in wanted:
        if header.count(c) > 1:
            raise _data_error(name, path, f"names column {c} {header.count(c)} times in its header")
    if len(lines) < 2:
        raise _data_error(name, path, "has a header and no rows")
    index = [header.index(c) for c in wanted]
    values = []
    for number, ln in lines[1:]:
        cells = ln.split(",")
        if len(cells) != len(header):
            raise _data_error(
                name,
                path,
                f"line {number} has {_count(len(cells), 'value')}, its header {len(header)}",
            )
        try:
            values.append([float(cells[i]) for i in index])
        except ValueError:
            c = next(c for c, i in zip(wanted, index, strict=True) if not _is_number(cells[i]))
            raise _data_error(
                name, path, f"line {number}, column {c}: the value is not a number"
            ) from None
    rows = np.array(values, dtype=float).reshape(len(values), len(wanted))
    numbers = np.array([number for number, _ in lines[1:]])
    bad = ~np.all(np.isfinite(rows), axis=1)
    if bad.any():
        raise _data_error(
            name, path, f"has {_count(bad.sum(), 'row')} with nan or inf in "
            f"{', '.join(wanted)} ({_lines(numbers[bad])}): remove or fix them (rows are not "
            "dropped silently)",
        )  # fmt: skip
    data = {c: rows[:, j] for j, c in enumerate(wanted)}
    for c, x in data.items():
        wrong = x < 0 if c == "stick_time" else x <= 0
        if c != "slip_distance" and wrong.any():
            sign = "< 0" if c == "stick_time" else "<= 0 (a slip has positive length)"
            raise _data_error(
                name, path, f"column {c} has {_count(wrong.sum(), 'value')} {sign}, at "
                f"{_lines(numbers[wrong])}",
            )  # fmt: skip
    return data


def read_fit_data(path: pathlib.Path, columns=None, source: str | None = None):
    """The data of a study's fit: a `Cycles` (its measurement kept) when the file is one
    `stickslip cycles` wrote (first line `# stickslip cycles`), with only `columns` where
    given; else the per-cycle columns of `read_cycles_csv`. Bad files are one `StudyError`
    at `fit.data` that quotes none of the file."""
    from .._errors import DataError
    from .._extract import Cycles, read_cycles
    from .._inference.data import KINDS

    name = source or str(path)
    text = _read_text(path, name)
    if not text.lstrip("\ufeff").startswith(_CYCLES_HEADER):
        return read_cycles_csv(path, columns, source)
    try:
        cycles = read_cycles(path)
    except DataError as err:
        reason = str(err).removeprefix(f"{os.fspath(path)}: ")
        raise _data_error(name, path, reason) from None
    wanted = list(columns) if columns else [k for k in KINDS if k in cycles.table]
    missing = [c for c in wanted if c not in cycles.table]
    if missing:
        header = list(cycles.table)
        raise _data_error(
            name, path, f"has no column {', '.join(missing)} ({_header_hint(header, KINDS)})"
        )
    return Cycles({k: cycles.table[k] for k in wanted}, cycles.info)


def _read_text(path: pathlib.Path, name: str) -> str:
    """The text of a regular file of at most `MAX_DATA_BYTES`, UTF-8 (a byte-order mark is
    dropped); anything else is a `StudyError` that quotes none of it."""
    try:
        info = path.stat()
    except FileNotFoundError:
        raise _data_error(name, path, "does not exist") from None
    except OSError as err:
        raise _data_error(name, path, f"cannot be read ({err.strerror})") from None
    if stat.S_ISDIR(info.st_mode):
        raise _data_error(name, path, "is a folder, not a CSV file")
    if not stat.S_ISREG(info.st_mode):
        raise _data_error(name, path, "is not a regular file (a device, pipe or socket)")
    cap = f"past the limit of {MAX_DATA_BYTES / 2**20:.3g} MiB for a table of cycles"
    if info.st_size > MAX_DATA_BYTES:
        raise _data_error(name, path, f"is {info.st_size / 2**20:.3g} MiB, {cap}")
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_DATA_BYTES + 1)
    except OSError as err:
        raise _data_error(name, path, f"cannot be read ({err.strerror})") from None
    if len(raw) > MAX_DATA_BYTES:  # it grew since
        raise _data_error(name, path, f"is {cap}")
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        raise _data_error(name, path, "is UTF-16 text: save it as UTF-8")
    if b"\0" in raw:
        raise _data_error(name, path, "is a binary file, not CSV text")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise _data_error(
            name, path, f"is not UTF-8 text (a byte at offset {err.start} is not): save it as UTF-8"
        ) from None


def _data_error(name: str, path, reason: str) -> StudyError:
    """A `StudyError` at `fit.data` about the file `path` (its name alone where the path is
    long: the study names it, and the message must stay one short line)."""
    shown = str(path) if len(str(path)) <= 60 else pathlib.Path(path).name
    shown = shown if shown.isprintable() else ascii(shown)
    return StudyError(name, "fit.data", f"{shown[:60]} {reason}")


def _header_hint(header: list[str], kinds) -> str:
    """What the first line holds, without quoting it: its number of fields, and a field
    only where it is a plain name close to a column the fit knows."""
    hint = f"its first line has {len(header)} field{'s' if len(header) != 1 else ''}"
    if "t" in header and ("x" in header or "v" in header):
        return hint + "; t, x, v are a trace's: run `stickslip cycles` on it first"
    plain = [h for h in header if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_ ]{0,39}", h)]
    for kind in kinds:
        close = difflib.get_close_matches(kind, plain, n=1, cutoff=0.75)
        if close:
            return hint + f"; did you mean {kind} for '{close[0]}'?"
    return hint


def _count(n, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _lines(numbers: np.ndarray) -> str:
    """The first few of some line numbers, for a message."""
    shown = ", ".join(str(int(n)) for n in numbers[:_SHOWN])
    more = f" and {numbers.size - _SHOWN} more" if numbers.size > _SHOWN else ""
    return f"line{'s' if numbers.size > 1 else ''} {shown}{more}"


def _fit_field(err, data_path) -> tuple[str, str]:
    """Where an error of `fit` lies in the study, and why: its argument names, turned into
    the study's fields (`free['tau']` -> `fit.free.tau`, `fixed['x0']` -> `model.params.x0`,
    `data['slip_time']` -> the data file's column)."""
    # DataError and ResourceError carry these only when `fit` raised them (`data._refuse`)
    parameter = getattr(err, "parameter", None)
    if getattr(err, "owner", None) != "fit" or parameter is None:
        return "fit", str(err)
    value = getattr(err, "value", None)
    reason = err.reason + ("" if value is None else f" (got {value!r})")
    match = re.fullmatch(r"(data|free|fixed)\['(.+)'\]", parameter)
    if match:
        kind, key = match.groups()
        if kind == "data":
            return "fit.data", f"{data_path.name}, column {key}: {reason}"
        return (f"fit.free.{key}" if kind == "free" else f"model.params.{key}"), reason
    field = {"fixed": "model.params", "model": "model.name", "data": "fit.data"}
    return field.get(parameter, f"fit.{parameter}"), reason


def run_fit(study, out=None, *, overrides=None, force: bool = False, progress: bool = False):
    """Run the `fit` block of `study` (a path to a YAML file, a dict or a `Study`); write
    the results to `out` if given. Returns the `FitResult`."""
    from .._errors import DataError, ParameterError, ResourceError
    from .._inference.fit import fit
    from .run import _check_out

    base = pathlib.Path(study).parent if isinstance(study, (str, os.PathLike)) else pathlib.Path()
    source = str(study) if isinstance(study, (str, os.PathLike)) else None
    study = load_study(study, overrides)
    if study.fit is None:
        raise StudyError(source, "fit", "is missing: add a fit block (data, free) to the study")
    spec = study.fit
    path = pathlib.Path(spec.data)
    # the results may not replace or hold the study or its data: checked before any work
    inputs = [source, path if path.is_absolute() else base / path]
    out_dir = None if out is None else _check_out(out, force, inputs)
    data_path = path if path.is_absolute() else base / path
    data = read_fit_data(data_path, spec.columns, source)
    measured = not isinstance(data, dict)
    if spec.trace is not None or spec.sampling is not None:
        warnings.warn(
            "study fit: trace and sampling are deprecated and ignored: a cycles CSV written by "
            "`stickslip cycles` carries its measurement (its '# stickslip cycles' header); "
            "remove them from the fit block",
            DeprecationWarning,
            stacklevel=2,
        )
        if spec.trace and not measured:
            raise StudyError(
                source, "fit.trace", f"needs the cycles as `stickslip cycles` writes them: "
                f"{data_path.name} has no '# stickslip cycles' header with the extraction's "
                "settings (its measurement cannot be modelled)",
            )  # fmt: skip
    free = {k: tuple(v) for k, v in spec.free.items()}
    fixed = {k: v for k, v in study.model.params.items() if k not in free}
    try:
        result = fit(
            study.model.name, data, free, fixed, seed=spec.seed, n_sim=spec.n_sim, dt=spec.dt,
            t_max=spec.t_max, progress=progress,
        )  # fmt: skip
    except (ParameterError, DataError, ResourceError) as err:
        raise StudyError(source, *_fit_field(err, data_path)) from None
    if out_dir is not None:
        write_fit(result, study, out_dir, force)
    return result


def _jsonable(value):
    """JSON-ready settings: NumPy scalars and arrays to Python, dataclasses to dicts."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return _jsonable(dataclasses.asdict(value))
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def _verdict(result) -> str:
    """One plain sentence: do the data reject the fitted model?"""
    from .._inference.goodness import ALPHA

    p = result.p_values
    if p is None:
        return "The fit was not checked against the data (no p-values)."
    low = {k: v for k, v in p.items() if v < ALPHA}
    if low:
        shown = ", ".join(f"{k} (p = {v:.3g})" for k, v in low.items())
        return (
            f"The data reject the model: {shown} below {ALPHA}; its distribution is unlike "
            "the data's (see fit.png), so its parameters describe the data only roughly."
        )
    smallest = min(p.values())
    return (
        f"The data do not reject the model: every p-value is at least {smallest:.3g} "
        f"(>= {ALPHA}); the fitted model reproduces the distribution of each fitted quantity."
    )


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
            p_values=result.p_values,
            rejected=None if result.goodness is None else bool(result.goodness.rejected),
            method=result.method,
            goodness_method=None if result.goodness is None else result.goodness.method,
            fixed={k: v for k, v in study.model.params.items() if k not in result.estimate},
            settings={k: d[k] for k in ("n_sim", "dt", "t_max", "seed", "n_data")},
            measurement=_jsonable(d.get("measurement")),
            covariance=d["covariance"],
            evaluations=d["evaluations"],
            optimizer=_jsonable(d["optimizer"]),
            mc_noise=_jsonable(d["mc_noise"]),
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
        lines += [""]
        if result.p_values is not None:
            lines += ["| observable | goodness-of-fit p-value |", "|---|---|"]
            lines += [f"| {k} | {p:.3g} |" for k, p in result.p_values.items()]
            lines += [""]
        lines += [_verdict(result), ""]
        lines += [f"log-likelihood {result.log_likelihood:.2f}; {d['evaluations']} points "
                  f"evaluated in {d['seconds']:.1f} s; data: "
                  + ", ".join(f"{n} {k}" for k, n in d["n_data"].items()), ""]  # fmt: skip
        lines += [f"- warning: {w}" for w in d["warnings"]]
        lines += ["", "![fit](fit.png)", ""]
        (tmp / "summary.md").write_text("\n".join(lines))
        _replace(tmp, out, force)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
