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

With `candidates`, each candidate model is fitted to the same data with the same settings
(seed included: common random numbers), `compare_fits` chooses the simplest one the data
do not reject, and the results say which and why: fit.json holds every candidate and the
comparison, fit_<name>.png each candidate's figure, summary.md the chosen model first.
The cycles of a force trace (seconds and newtons) need `scales`, the model's units in SI;
the summary then states the estimates in SI too.
"""

from __future__ import annotations

import codecs
import difflib
import json
import math
import os
import pathlib
import re
import shutil
import stat
import sys
import types
import warnings

import numpy as np

from .._inference.saved import jsonable
from .._trace_kind import kind_of_signal
from .load import StudyError, load_study

# A table of cycles is small (`stickslip cycles` writes about 60 B a row): the cap keeps a
# path naming something else (a disk image, a log) from being read whole.
MAX_DATA_BYTES = 256 * 2**20
_SHOWN = 5  # rows named in a message
_CYCLES_HEADER = "# stickslip cycles"  # the first line `Cycles.to_csv` writes
# The model choice's replicates are seeded with the fit's seed plus this: a stream other than
# the one the fits simulate with (`compare_fits` asks for a seed other than the fits').
COMPARE_SEED_OFFSET = 1


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


def _fit_field(err, data_path, loc: str = "model") -> tuple[str, str]:
    """Where an error of `fit` lies in the study, and why: its argument names, turned into
    the study's fields (`free['tau']` -> `fit.free.tau`, `fixed['x0']` -> `model.params.x0`,
    `data['slip_time']` -> the data file's column). `loc` is where the fitted model's
    settings lie (`Fit.models`): `model` for a single fit, a candidate's otherwise (its
    `free` at `fit.candidates.N.free`)."""
    # DataError and ResourceError carry these only when `fit` raised them (`data.refusal`)
    parameter = getattr(err, "parameter", None)
    if getattr(err, "owner", None) != "fit" or parameter is None:
        return "fit" if loc == "model" else loc.removesuffix(".model"), str(err)
    value = getattr(err, "value", None)
    reason = err.reason + ("" if value is None else f" (got {value!r})")
    free = "fit.free" if loc == "model" else f"{loc.removesuffix('.model')}.free"
    params = "model.params" if loc == "model" else f"{loc}.params"
    name = f"{loc}.name" if loc.endswith("model") else "model.name"
    match = re.fullmatch(r"(data|free|fixed)\['(.+)'\]", parameter)
    if match:
        kind, key = match.groups()
        if kind == "data":
            return "fit.data", f"{data_path.name}, column {key}: {reason}"
        return (f"{free}.{key}" if kind == "free" else f"{params}.{key}"), reason
    field = {"fixed": params, "model": name, "data": "fit.data", "free": free}
    return field.get(parameter, f"fit.{parameter}"), reason


def run_fit(study, out=None, *, overrides=None, force: bool = False, progress: bool = False):
    """Run the `fit` block of `study` (a path to a YAML file, a dict or a `Study`); write
    the results to `out` if given. Returns the `FitResult`, or with `candidates` the
    `Comparison` of the candidates' fits (its `chosen` the chosen one's `FitResult`)."""
    from .._errors import DataError, ParameterError, ResourceError
    from .._inference.compare import compare_fits
    from .._inference.fit import fit
    from .run import check_out

    base = pathlib.Path(study).parent if isinstance(study, (str, os.PathLike)) else pathlib.Path()
    source = str(study) if isinstance(study, (str, os.PathLike)) else None
    study = load_study(study, overrides)
    if study.fit is None:
        raise StudyError(source, "fit", "is missing: add a fit block (data, free) to the study")
    spec = study.fit
    path = pathlib.Path(spec.data)
    # the results may not replace or hold the study or its data: checked before any work
    inputs = [source, path if path.is_absolute() else base / path]
    out_dir = None if out is None else check_out(out, force, inputs)
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
    scales = None
    if spec.scales is not None:
        kind = kind_of_signal(data.info.get("input")) if measured else None
        if kind is None or not kind.in_si:
            what = (
                "per-cycle values" if not measured
                else f"the cycles of a {data.info.get('input')} trace"
            )  # fmt: skip
            raise StudyError(
                source, "fit.scales", f"applies to the cycles of a force trace only: "
                f"{data_path.name} holds {what}, in the model's units (remove scales)",
            )  # fmt: skip
        # what `Measurement.from_cycles` reads of a `Scales` (or a `Slider`)
        scales = types.SimpleNamespace(time=float(spec.scales.time), force=float(spec.scales.force))
    models = spec.models(study.model)
    results = {}
    for name, model, boxes, loc in models:
        free = {k: tuple(v) for k, v in boxes.items()}
        fixed = {k: v for k, v in model.params.items() if k not in free}
        if progress and spec.candidates is not None:
            print(f"fitting candidate {name} ({model.name}: {', '.join(free)} free)",
                  file=sys.stderr)  # fmt: skip
        try:
            results[name] = fit(
                model.name, data, free, fixed, seed=spec.seed, n_sim=spec.n_sim, dt=spec.dt,
                t_max=spec.t_max, scales=scales, progress=progress, intervals=spec.intervals,
            )  # fmt: skip
        except (ParameterError, DataError, ResourceError) as err:
            raise StudyError(source, *_fit_field(err, data_path, loc)) from None
    if spec.candidates is None:
        result = results["fit"]
        if out_dir is not None:
            write_fit(result, study, out_dir, force, scales)
        return result
    try:
        # a seed of its own for the replicates, other than the fits' (their simulations)
        comparison = compare_fits(
            results, alpha=spec.alpha, n_boot=spec.n_boot, seed=spec.seed + COMPARE_SEED_OFFSET
        )
    except (ParameterError, DataError) as err:
        raise StudyError(source, "fit.candidates", str(err)) from None
    if out_dir is not None:
        write_comparison(comparison, study, out_dir, force, scales)
    return comparison


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


def _record(result, params: dict, model_name: str) -> dict:
    """What fit.json says of one fit: `params` are the fitted model's settings (its fixed
    parameters are those not estimated)."""
    d = result.diagnostics
    return dict(
        model=model_name,
        estimate=result.estimate,
        # none where the fit has no interval (its surface not concave: nan)
        ci95={
            k: [float(x) if math.isfinite(x) else None for x in v] for k, v in result.ci.items()
        },  # fmt: skip
        log_likelihood=result.log_likelihood,
        p_values=result.p_values,
        rejected=None if result.goodness is None else bool(result.goodness.rejected),
        method=result.method,
        goodness_method=None if result.goodness is None else result.goodness.method,
        fixed=jsonable({k: v for k, v in params.items() if k not in result.estimate}),
        settings={k: d[k] for k in ("n_sim", "dt", "t_max", "seed", "n_data")},
        measurement=jsonable(d.measurement),
        covariance=d.covariance,
        evaluations=d.evaluations,
        optimizer=jsonable(d.optimizer),
        mc_noise=jsonable(d.mc_noise),
        seconds=d.seconds,
        warnings=d.warnings,
    )


# A parameter's unit in SI, for a force trace fitted with `scales` (the model's time unit
# `time` = 1/omega0 s, force unit `force` = k x0 N, as `Slider.to_model` makes the model:
# omega0 = 1, lengths in x0): its factor as a function of (time, force), and its unit.
# A threshold (x0, a law's location) is a force above the sliding level F_k + c V; the
# noise intensity D is S / (m^2 omega0^3 x0^2), and m^2 omega0^3 x0^2 = (k x0)^2 / omega0.
_ABOVE = "N above the sliding force"
_SI = {
    "D": (lambda t, f: f * f * t, "N^2 s"),
    "tau": (lambda t, f: t, "s"),
    "x0": (lambda t, f: f, _ABOVE),
    "threshold_params.mean": (lambda t, f: f, _ABOVE),
    "threshold_params.median": (lambda t, f: f, _ABOVE),
    "threshold_params.low": (lambda t, f: f, _ABOVE),
    "threshold_params.high": (lambda t, f: f, _ABOVE),
    "threshold_params.scale": (lambda t, f: f, _ABOVE),
    "threshold_params.sd": (lambda t, f: f, "N"),
}


def _in_data_units(name: str, value: float, scales) -> tuple[float, str] | None:
    """`value` of the parameter `name` in the data's SI units, and the unit; `None` where
    the data are in the model's units (no `scales`) or the parameter has no SI form here
    (a rate ratio such as zeta; v_b, which needs the length unit)."""
    if scales is None or name not in _SI:
        return None
    factor, unit = _SI[name]
    return value * factor(scales.time, scales.force), unit


def _parameter_table(result, scales) -> list[str]:
    """The estimates with their 95 % intervals, in the model's units and, for a force
    trace with `scales`, in SI."""
    si = scales is not None
    head = "| parameter | estimate | 95 % interval |" + (
        " in SI | 95 % interval (SI) |" if si else ""
    )
    lines = [head, "|---|---|---|" + ("---|---|" if si else "")]
    for k, v in result.estimate.items():
        lo, hi = result.ci[k]
        if not (math.isfinite(lo) and math.isfinite(hi)):
            row = f"| {k} | {v:.4g} | none (warnings) |"
            if si:
                got = _in_data_units(k, v, scales)
                row += " (model units) | |" if got is None else f" {got[0]:.4g} {got[1]} | |"
            lines.append(row)
            continue
        row = f"| {k} | {v:.4g} | [{lo:.4g}, {hi:.4g}] |"
        if si:
            got = _in_data_units(k, v, scales)
            if got is None:
                row += " (model units) | |"
            else:
                value, unit = got
                a, b = (_in_data_units(k, x, scales)[0] for x in (lo, hi))
                row += f" {value:.4g} {unit} | [{a:.4g}, {b:.4g}] {unit} |"
        lines.append(row)
    return lines


def _units_sentence(scales) -> str:
    if scales is None:
        return (
            "Units: the model's (the data are in the model's time and length units; no `scales`)."
        )
    return (
        f"Units: the data are a force trace's in seconds and newtons; the model's time unit "
        f"is {scales.time:.4g} s and its force unit {scales.force:.4g} N (`fit.scales`); the "
        "SI columns assume the model is Slider.to_model's (omega0 = 1, lengths in x0)."
    )


def _fit_lines(result, scales) -> list[str]:
    """The body of a summary for one fit: parameters, p-values, verdict, cost, warnings."""
    d = result.diagnostics
    lines = [result.method, "", *_parameter_table(result, scales), "", _units_sentence(scales), ""]
    if result.p_values is not None:
        lines += ["| observable | goodness-of-fit p-value |", "|---|---|"]
        lines += [f"| {k} | {p:.3g} |" for k, p in result.p_values.items()]
        lines += [""]
    lines += [_verdict(result), ""]
    lines += [f"log-likelihood {result.log_likelihood:.2f}; {d.evaluations} points "
              f"evaluated in {d.seconds:.1f} s; data: "
              + ", ".join(f"{n} {k}" for k, n in d.n_data.items()), ""]  # fmt: skip
    return lines


def write_fit(result, study, out: pathlib.Path, force: bool, scales=None):
    from .._output import partial_dir
    from .write import replace_file

    tmp = partial_dir(out)
    try:
        record = _record(result, study.model.params, study.model.name)
        (tmp / "fit.json").write_text(json.dumps(record, indent=2, default=float) + "\n")
        result.plot(tmp / "fit.png")
        title = study.title or f"Fit of {study.model.name}"
        lines = [f"# {title}", "", *_fit_lines(result, scales)]
        lines += [f"- warning: {w}" for w in result.diagnostics.warnings]
        lines += ["", "![fit](fit.png)", ""]
        (tmp / "summary.md").write_text("\n".join(lines))
        replace_file(tmp, out, force)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def plot_candidates(comparison, path: pathlib.Path, seed: int | None = None) -> None:
    """candidates.png: per fitted column, the data's histogram against each candidate's
    simulated cycles at its estimate (`FitResult.simulated`, through the data's
    measurement), labelled with its goodness-of-fit p-value; the chosen one drawn
    thicker. `seed`: the simulations' (default each fit's own)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    best = comparison.chosen
    kinds = list(best.data)
    fig, axes = plt.subplots(1, len(kinds), figsize=(4.2 * len(kinds), 3.4), squeeze=False)
    sims = {name: r.simulated(seed=seed) for name, r in comparison.fits.items()}
    for ax, k in zip(axes[0], kinds, strict=True):
        x = np.asarray(best.data[k], float)
        edges = np.histogram_bin_edges(x, bins=min(60, max(10, x.size // 50)))
        ax.hist(x, edges, density=True, alpha=0.4, color="0.5", label=f"data ({x.size})")
        for name, r in comparison.fits.items():
            p = r.p_values
            chosen = r is best
            label = name + ("" if p is None else f" (p = {p[k]:.2g})")
            label += ", chosen" if chosen else ""
            lw = 2.2 if chosen else 1.0
            ax.hist(sims[name][k], edges, density=True, histtype="step", lw=lw, label=label)
        ax.set_xlabel(k)
        ax.legend(fontsize=7)
    fig.suptitle(f"candidates against the data: {comparison.chosen_name} chosen", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_comparison(comparison, study, out: pathlib.Path, force: bool, scales=None):
    """The results of a fit with candidates: fit.json (the chosen one's record at the top,
    as a single fit writes it, then `chosen`, every candidate's record and the comparison),
    fit.png (the chosen one), fit_<name>.png (each candidate) and candidates.png (every
    candidate against the data), summary.md (the chosen
    model, its parameters with their intervals, in SI for a force trace with `scales`, its
    p-values and verdict, the comparison's table, and every warning)."""
    from .._output import partial_dir
    from .write import replace_file

    specs = {name: model for name, model, _, _ in study.fit.models(study.model)}
    chosen = comparison.chosen_name
    best = comparison.chosen
    tmp = partial_dir(out)
    try:
        records = {
            name: _record(r, specs[name].params, specs[name].name)
            for name, r in comparison.fits.items()
        }
        record = {
            **records[chosen],
            "chosen": chosen,
            "candidates": records,
            "comparison": dict(
                table=jsonable(comparison.table), tests=jsonable(comparison.tests),
                alpha=comparison.alpha, n_boot=comparison.n_boot, method=comparison.method,
                warnings=comparison.warnings,
            ),
        }  # fmt: skip
        (tmp / "fit.json").write_text(json.dumps(record, indent=2, default=float) + "\n")
        best.plot(tmp / "fit.png")
        for name, r in comparison.fits.items():
            r.plot(tmp / f"fit_{name}.png")
        plot_candidates(comparison, tmp / "candidates.png")
        title = study.title or f"Model choice for {study.fit.data}"
        row = comparison.table[0]
        free = ", ".join(best.estimate)
        lines = [
            f"# {title}", "",
            f"**Chosen model: {chosen}** ({specs[chosen].name}, {free} free). Why: "
            f"{row['verdict'].removeprefix('chosen: ')}.",
            "", *_fit_lines(best, scales), "## Candidates", "", comparison.method, "",
            "| rank | candidate | model | free | log-likelihood | 2 dlogL | p | verdict |",
            "|---|---|---|---|---|---|---|---|",
        ]  # fmt: skip
        for r in comparison.table:
            stat = "" if r["statistic"] is None else f"{r['statistic']:.2f}"
            p = "" if r["p_value"] is None else f"{r['p_value']:.3g}"
            lines.append(
                f"| {r['rank']} | {r['name']} | {r['model']} | {', '.join(r['free'])} | "
                f"{r['log_likelihood']:.2f} | {stat} | {p} | {r['verdict']} |"
            )
        lines += [""]
        for name, r in comparison.fits.items():
            est = ", ".join(
                f"{k} = {v:.4g} [{r.ci[k][0]:.4g}, {r.ci[k][1]:.4g}]" for k, v in r.estimate.items()
            )
            lines.append(f"- {name}: {est}")
        lines += ["", "## Warnings", ""]
        said = [f"- model choice: {w}" for w in comparison.warnings]
        for name, r in comparison.fits.items():
            said += [f"- {name}: {w}" for w in r.diagnostics.warnings]
        lines += said or ["none"]
        lines += ["", "![candidates against the data](candidates.png)", ""]
        lines += [f"![{chosen}](fit.png)", ""]
        lines += [f"![{name}](fit_{name}.png)" for name in comparison.fits if name != chosen]
        lines += [""]
        (tmp / "summary.md").write_text("\n".join(lines))
        replace_file(tmp, out, force)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
