"""Bad input to the study CLI: exit code 2 and one line `error: SOURCE: FIELD: REASON`.

Every case here fails at validation (or at the check of `--out`), before any simulation:
`_no_simulation` makes sure of it, so a case whose bad input is wrongly accepted fails fast
instead of running a Monte Carlo. The problems it found
while it was written are fixed.
"""

from __future__ import annotations

import copy
import os
import pathlib
import subprocess
import sys

import pytest
import yaml
from click.testing import CliRunner

from stickslip.cli import main

# -- valid studies, one per model ----------------------------------------------------------
LANGEVIN = {
    "title": "public reference set",
    "model": {
        "name": "langevin",
        "params": {"omega0": 1.0, "zeta": 0.1, "D": 0.4, "v_b": 1.0, "x0": 1.0, "tau": 0.1},
    },
    "simulation": {"n_paths": 2000, "dt": 0.005, "t_max": 30},
    "analytic": [{"method": "decoupling", "order": 1}],
    "outputs": ["slip_time", "period"],
}
FRICTION_BLOCK = {
    "model": {
        "name": "friction-block",
        "params": {
            "k": 1.0,
            "v_b": 1.0,
            "D": 0.1,
            "tau": 0.1,
            "friction": "coulomb",
            "friction_params": {"static": 1.0, "kinetic": 0.5},
        },  # fmt: skip
    },
    "simulation": {"n_paths": 2000, "dt": 0.005, "t_max": 30},
    "analytic": [{"method": "decoupling", "order": 1, "source": "empirical"}],
}
CHAIN = {
    "model": {
        "name": "burridge-knopoff",
        "params": {
            "n_blocks": 8,
            "k_c": 1.0,
            "k_p": 0.5,
            "v_b": 0.01,
            "friction": "velocity-weakening",
            "friction_params": {"F0": 1.0, "alpha": 1.0, "sigma": 0.1},
        },  # fmt: skip
    },
    "simulation": {"n_paths": 2, "dt": 0.01, "t_max": 100},
    "outputs": ["event_size", "event_duration"],
}
RANDOM_THRESHOLD = {
    "model": {
        "name": "random-threshold",
        "params": {
            "omega0": 1.0,
            "zeta": 0.1,
            "D": 0.4,
            "v_b": 1.0,
            "threshold": "lognormal",
            "threshold_params": {"median": 1.0, "sigma": 0.2},
        },  # fmt: skip
    },
    "simulation": {"n_paths": 2000, "dt": 0.005, "t_max": 30},
}

VALID_YAML = """\
title: public reference set
model:
  name: langevin
  params: {omega0: 1.0, zeta: 0.1, D: 0.4, v_b: 1.0, x0: 1.0, tau: 0.1}
simulation: {n_paths: 2000, dt: 0.005, t_max: 30}
analytic:
  - {method: decoupling, order: 1}
outputs: [slip_time, period]
"""


def _node(data, parts):
    for part in parts:
        data = data[int(part)] if isinstance(data, list) else data[part]
    return data


def study(changes=None, drop=(), base=LANGEVIN) -> str:
    """YAML text of `base` with dotted `changes` set and the dotted keys in `drop` removed."""
    data = copy.deepcopy(base)
    for path in drop:
        *head, last = path.split(".")
        parent = _node(data, head)
        del parent[int(last) if isinstance(parent, list) else last]
    for path, value in (changes or {}).items():
        *head, last = path.split(".")
        parent = _node(data, head)
        parent[int(last) if isinstance(parent, list) else last] = value
    return yaml.safe_dump(data, sort_keys=False)


def case(case_id, argv, expect, *, text=None, contains=(), absent=()):
    """One bad input: `argv` (placeholders in braces, see `paths`), the study text written
    to {study}, the required start of the error line, and substrings it must (not) hold."""
    return pytest.param(argv, text, expect, tuple(contains), tuple(absent), id=case_id)


V = ["validate", "{study}"]  # validate the study written from `text`
S = "error: {study}: "  # the start of an error about the study file

CASES = [
    # -- typos in keys, at every level ------------------------------------------------------
    case("typo-top-level", V, S + "outptus: unknown key",
         text=study({"outptus": ["slip_time"]}, drop=["outputs"]),
         contains=["did you mean 'outputs'?"]),
    case("typo-simulation", V, S + "simulation.n_path: unknown key",
         text=study({"simulation.n_path": 2000}, drop=["simulation.n_paths"]),
         contains=["did you mean 'n_paths'?"]),
    case("typo-simulation-cycles", V, S + "simulation.cycles.npaths: unknown key",
         text=study({"simulation.cycles": {"npaths": 2}}), contains=["did you mean 'n_paths'?"]),
    case("typo-model", V, S + "model.parms: unknown key",
         text=study({"model.parms": {}}), contains=["did you mean 'params'?"]),
    case("typo-model-params", V, S + "model.params.taux: unknown parameter of langevin",
         text=study({"model.params.taux": 0.1}, drop=["model.params.tau"]),
         contains=["did you mean 'tau'?"]),
    case("typo-required-model-param", V, S + "model.params.zetta: unknown parameter",
         text=study({"model.params.zetta": 0.1}, drop=["model.params.zeta"]),
         contains=["did you mean 'zeta'?"]),
    case("typo-analytic-item", V, S + "analytic.0.ordr: unknown key",
         text=study({"analytic.0.ordr": 1}, drop=["analytic.0.order"]),
         contains=["did you mean 'order'?"]),
    case("typo-grid", V, S + "grid.slip_tme: unknown key",
         text=study({"grid": {"slip_tme": {"bins": 10}}}), contains=["did you mean 'slip_time'?"]),
    case("typo-grid-range", V, S + "grid.slip_time.bin: unknown key",
         text=study({"grid": {"slip_time": {"bin": 10}}}), contains=["did you mean 'bins'?"]),
    case("typo-estimator", V, S + "estimator.mix: unknown key",
         text=study({"estimator": {"mix": "process"}}), contains=["did you mean 'mixing'?"]),
    case("typo-sweep", V, S + "sweep.mdoe: unknown key",
         text=study({"sweep": {"parameters": {"model.params.v_b": [1, 2]}, "mdoe": "zip"}}),
         contains=["did you mean 'mode'?"]),
    case("typo-sweep-required-key", V, S + "sweep.parameter: unknown key",
         text=study({"sweep": {"parameter": {"model.params.v_b": [1, 2]}}}),
         contains=["did you mean 'parameters'?"]),
    # -- wrong types --------------------------------------------------------------------------
    case("string-for-float", V, S + "simulation.dt: must be a number",
         text=study({"simulation.dt": "0.01"}), contains=["'0.01'"]),
    case("string-for-model-param", V, S + "model.params.zeta: must be a number",
         text=study({"model.params.zeta": "abc"}), contains=["'abc'"]),
    case("list-for-mapping", V, S + "simulation: must be a mapping",
         text=study({"simulation": [1, 2]}), contains=["got a list"]),
    case("list-for-params-mapping", V, S + "model.params: must be a mapping",
         text=study({"model.params": [1.0, 0.1]}), contains=["got a list"]),
    case("scalar-for-model-block", V, S + "model: must be a mapping",
         text=study({"model": "langevin"}), contains=["got a string"]),
    case("bool-for-float", V, S + "simulation.dt: must be a number",
         text=study({"simulation.dt": True}), contains=["True"]),
    case("bool-for-model-param", V, S + "model.params.zeta: must be a number",
         text=study({"model.params.zeta": True}), contains=["True"]),
    case("float-for-int", V, S + "simulation.n_paths: must be a valid integer",
         text=study({"simulation.n_paths": 100.5}), contains=["100.5"]),
    case("float-for-int-model-param", V, S + "model.params.n_blocks: must be a valid integer",
         text=study({"model.params.n_blocks": 8.0}, base=CHAIN), contains=["8.0"]),
    case("string-for-list", V, S + "outputs: must be a list",
         text=study({"outputs": "slip_time"})),
    # -- invalid values ----------------------------------------------------------------------
    case("negative-zeta", V, S + "model.params.zeta: must be > 0",
         text=study({"model.params.zeta": -0.1}), contains=["-0.1"]),
    case("negative-D", V, S + "model.params.D: must be >= 0",
         text=study({"model.params.D": -0.4}), contains=["-0.4"]),
    case("dt-zero", V, S + "simulation.dt: must be > 0", text=study({"simulation.dt": 0})),
    case("dt-nan", V, S + "simulation.dt: must be a finite number",
         text=study({"simulation.dt": float("nan")})),
    case("n_paths-zero", V, S + "simulation.n_paths: must be >= 1",
         text=study({"simulation.n_paths": 0})),
    case("t_max-below-dt", V, S + "simulation.t_max: must be >= dt",
         text=study({"simulation.t_max": 0.001}), contains=["0.005", "0.001"]),
    case("order-3", V, S + "analytic.0.order: must be 1 or 2",
         text=study({"analytic.0.order": 3}), contains=["got 3"]),
    case("unknown-method", V, S + "analytic.0.method: must be 'truncation' or 'decoupling'",
         text=study({"analytic.0.method": "magic"}), contains=["'magic'"]),
    case("unknown-solver", V, S + "simulation.solver: must be 'auto', 'exact' or 'euler'",
         text=study({"simulation.solver": "rk4"}), contains=["'rk4'"]),
    case("unknown-output", V, S + "outputs.1: must be 'slip_time'",
         text=study({"outputs": ["slip_time", "slip_tme"]}), contains=["'slip_tme'"]),
    case("output-not-of-block-model", V,
         S + "outputs.1: 'event_size' is not an output of langevin",
         text=study({"outputs": ["slip_time", "event_size"]})),
    case("output-not-of-chain-model", V,
         S + "outputs.0: 'slip_time' is not an output of burridge-knopoff",
         text=study({"outputs": ["slip_time"]}, base=CHAIN), contains=["event_size"]),
    case("duplicated-output", V, S + "outputs.2: 'slip_time' is listed twice",
         text=study({"outputs": ["slip_time", "period", "slip_time"]})),
    case("grid-stop-below-start", V, S + "grid.period.stop: must be > start",
         text=study({"grid": {"period": {"start": 2.0, "stop": 1.0}}})),
    case("grid-stop-equals-start", V, S + "grid.period.stop: must be > start",
         text=study({"grid": {"period": {"start": 2.0, "stop": 2.0}}})),
    case("duplicated-analytic", V, S + "analytic.1: repeats an earlier entry",
         text=study({"analytic": [{"method": "decoupling"}, {"method": "decoupling"}]})),
    # -- the model -----------------------------------------------------------------------------
    case("unknown-model", V, S + "model.name: unknown model 'langevn'",
         text=study({"model.name": "langevn"}), contains=["did you mean 'langevin'?"]),
    case("missing-model-param", V, S + "model.params.x0: required parameter",
         text=study(drop=["model.params.x0"]), contains=["missing"]),
    case("missing-model-block", V, S + "model: is required", text=study(drop=["model"])),
    case("exact-source-not-linear-gaussian", V,
         S + "analytic.0.source: 'exact' needs a linear-Gaussian model",
         text=study({"analytic.0.source": "exact"}, base=FRICTION_BLOCK),
         contains=["friction-block"]),
    case("analytic-on-chain", V, S + "analytic: the crossing estimator needs a single-block",
         text=study({"analytic": [{"method": "decoupling"}]}, base=CHAIN),
         contains=["burridge-knopoff"]),
    case("normalized-with-decoupling", V,
         S + "analytic.0.normalized: applies only to method 'truncation'",
         text=study({"analytic.0.normalized": True})),
    case("unknown-friction-law", V, S + "model.params.friction: must be one of",
         text=study({"model.params.friction": "magic"}, base=FRICTION_BLOCK),
         contains=["'magic'"]),
    case("unknown-threshold-law", V, S + "model.params.threshold: must be one of",
         text=study({"model.params.threshold": "gamma"}, base=RANDOM_THRESHOLD),
         contains=["'gamma'"]),
    case("list-for-threshold-params", V, S + "model.params.threshold_params: ",
         text=study({"model.params.threshold_params": [1.0]}, base=RANDOM_THRESHOLD),
         absent=["dictionary update sequence"]),
    # -- the document ------------------------------------------------------------------------
    case("empty-file", V, S + "the study is empty", text=""),
    case("comments-only", V, S + "the study is empty", text="# nothing here\n"),
    case("document-is-a-list", V, S + "a study must be a mapping", text="- a\n- b\n",
         contains=["got a list"]),
    case("document-is-a-scalar", V, S + "a study must be a mapping", text="hello\n",
         contains=["got a string"]),
    case("yaml-bad-indentation", V, S + "YAML syntax error at line 4",
         text=VALID_YAML.replace("  params:", "   params:"),
         contains=["mapping values are not allowed here"]),
    case("yaml-unclosed-bracket", V, S + "YAML syntax error at line",
         text=VALID_YAML.replace("period]", "period"), contains=["expected ',' or ']'"]),
    case("yaml-unclosed-brace", V, S + "YAML syntax error at line",
         text=VALID_YAML.replace("t_max: 30}", "t_max: 30"), contains=["expected ',' or '}'"]),
    case("yaml-tab", V, S + "YAML syntax error at line 3",
         text=VALID_YAML.replace("  name:", "\tname:"), contains=["cannot start any token"]),
    case("yaml-duplicate-top-key", V, S + "YAML syntax error at line 2",
         text="title: a\n" + VALID_YAML, contains=["duplicate key 'title'"]),
    case("yaml-duplicate-nested-key", V, S + "YAML syntax error at line 4",
         text=VALID_YAML.replace("zeta: 0.1", "zeta: 0.1, zeta: 0.2"),
         contains=["duplicate key 'zeta'"]),
    case("yaml-unhashable-key", V, S + "YAML syntax error at line",
         text="? [a, b]\n: 1\n", contains=["unhashable key"]),
    case("yaml-two-documents", V, S + "YAML syntax error at line",
         text=VALID_YAML + "---\ntitle: b\n", contains=["single document"]),
    case("not-utf8", V, S + "is not a UTF-8 text file", text=b"title: \xff\xfe\n"),
    # -- the study file -------------------------------------------------------------------------
    case("missing-study-file", ["validate", "{missing}"], "error: {missing}: no such file"),
    case("study-path-is-a-directory", ["validate", "{dir}"], "error: {dir}: is a directory"),
    case("run-missing-study-file", ["run", "{missing}", "--out", "{out}"],
         "error: {missing}: no such file"),
    case("run-bad-study", ["run", "{study}", "--out", "{out}", "--quiet"],
         S + "model.params.zeta: must be > 0", text=study({"model.params.zeta": -1.0})),
    # -- --set ----------------------------------------------------------------------------------
    case("set-without-equals", [*V, "--set", "simulation.n_paths"],
         "error: --set: expected KEY=VALUE", text=VALID_YAML,
         contains=["'simulation.n_paths'"]),
    case("set-without-key", [*V, "--set", "=3"], "error: --set: expected KEY=VALUE",
         text=VALID_YAML),
    case("set-invalid-yaml", [*V, "--set", "simulation.n_paths=[1,"],
         "error: --set: simulation.n_paths: value '[1,' is not valid YAML", text=VALID_YAML),
    case("set-unknown-key", [*V, "--set", "simulation.n_pathz=3"], "error: ",
         text=VALID_YAML, contains=["simulation.n_pathz: unknown key", "did you mean 'n_paths'?"]),
    case("set-invalid-value", [*V, "--set", "simulation.n_paths=0"], "error: ",
         text=VALID_YAML, contains=["simulation.n_paths: must be >= 1"]),
    case("set-through-a-scalar", [*V, "--set", "title.x=3"],
         "error: --set: title.x: 'title' is not a mapping or list", text=VALID_YAML),
    case("set-list-index-out-of-range", [*V, "--set", "analytic.5.order=1"],
         "error: --set: analytic.5.order: ", text=VALID_YAML,
         absent=["is not a mapping or list"]),
    # -- sweeps -----------------------------------------------------------------------------------
    case("sweep-unknown-parameter", V,
         S + "sweep.parameters.model.params.v_bb: unknown parameter of langevin",
         text=study({"sweep": {"parameters": {"model.params.v_bb": [1, 2]}}}),
         contains=["did you mean 'v_b'?"]),
    case("sweep-unknown-setting", V,
         S + "sweep.parameters.simulation.nn: cannot sweep 'simulation.nn'",
         text=study({"sweep": {"parameters": {"simulation.nn": [1, 2]}}})),
    case("sweep-invalid-value", V, S + "sweep.parameters.model.params.v_b.1: value -2",
         text=study({"sweep": {"parameters": {"model.params.v_b": [1, -2]}}}),
         contains=["model.params.v_b: must be > 0"]),
    case("sweep-zip-unequal-lengths", V, S + "sweep.parameters: mode 'zip' needs lists",
         text=study({"sweep": {"mode": "zip", "parameters": {
             "model.params.v_b": [1, 2], "model.params.zeta": [0.1]}}})),
    case("sweep-no-parameters", V, S + "sweep.parameters: ",
         text=study({"sweep": {"parameters": {}}}), contains=["must not be empty"]),
    case("sweep-no-values", V, S + "sweep.parameters.model.params.v_b: needs at least one",
         text=study({"sweep": {"parameters": {"model.params.v_b": []}}})),
    case("sweep-cli-param-without-equals",
         ["sweep", "{valid}", "-p", "model.params.v_b", "--out", "{out}"],
         "error: --param: expected KEY=V1,V2,...", contains=["'model.params.v_b'"]),
    case("sweep-cli-param-without-values",
         ["sweep", "{valid}", "-p", "model.params.v_b=", "--out", "{out}"],
         "error: --param: expected KEY=V1,V2,..."),
    case("sweep-cli-unknown-parameter",
         ["sweep", "{valid}", "-p", "model.params.v_bb=1,2", "--out", "{out}"], "error: ",
         contains=["model.params.v_bb: unknown parameter of langevin", "did you mean 'v_b'?"]),
    case("sweep-cli-invalid-value",
         ["sweep", "{valid}", "-p", "model.params.v_b=1,-1", "--out", "{out}"], "error: ",
         contains=["model.params.v_b.1: value -1: model.params.v_b: must be > 0"]),
    case("sweep-cli-zip-unequal-lengths",
         ["sweep", "{valid}", "-p", "model.params.v_b=1,2", "-p", "model.params.zeta=0.1",
          "--zip", "--out", "{out}"],
         "error: ", contains=["sweep.parameters: mode 'zip' needs lists of one length"]),
    case("sweep-cli-invalid-yaml-value",
         ["sweep", "{valid}", "-p", "model.params.v_b=[1,2", "--out", "{out}"],
         "error: --param: model.params.v_b: ", contains=["not valid YAML"]),
    case("sweep-cli-param-given-twice",
         ["sweep", "{valid}", "-p", "model.params.v_b=1", "-p", "model.params.v_b=2",
          "--out", "{out}"],
         "error: --param: model.params.v_b"),
    # -- --out ------------------------------------------------------------------------------------
    case("out-is-non-empty-directory", ["run", "{valid}", "--out", "{full}", "--quiet"],
         "error: --out: {full} exists and is not empty", contains=["--force"]),
    case("out-is-a-file", ["run", "{valid}", "--out", "{file}", "--quiet"],
         "error: --out: {file} exists and is not a directory"),
    case("out-parent-missing", ["run", "{valid}", "--out", "{out}/a/b", "--quiet"],
         "error: --out: parent directory", contains=["does not exist"]),
    case("sweep-out-is-non-empty-directory",
         ["sweep", "{valid}", "-p", "model.params.v_b=1,2", "--out", "{full}", "--quiet"],
         "error: --out: {full} exists and is not empty"),
    # -- schema -----------------------------------------------------------------------------------
    case("schema-unknown-model", ["schema", "--model", "nosuchmodel"],
         "error: --model: unknown model 'nosuchmodel'", contains=["langevin"]),
    case("schema-misspelt-model", ["schema", "--model", "langevn"],
         "error: --model: unknown model 'langevn'", contains=["did you mean 'langevin'?"]),
]  # fmt: skip


@pytest.fixture(autouse=True)
def _no_simulation(monkeypatch):
    """Every case must stop before the simulation: starting one is a failure (exit 1)."""
    import stickslip.study.run as run_module

    def refuse(*args, **kwargs):
        raise AssertionError("a simulation was started")

    monkeypatch.setattr(run_module, "_compute", refuse)
    monkeypatch.setattr(run_module, "_compute_chain", refuse)


@pytest.fixture
def paths(tmp_path):
    """The placeholders of the cases: files and directories in `tmp_path`."""
    (tmp_path / "adir").mkdir()
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("keep me\n")
    (tmp_path / "afile.txt").write_text("not a directory\n")
    (tmp_path / "valid.yaml").write_text(VALID_YAML)
    return {
        "study": tmp_path / "study.yaml",
        "valid": tmp_path / "valid.yaml",
        "missing": tmp_path / "missing.yaml",
        "dir": tmp_path / "adir",
        "out": tmp_path / "out",
        "full": tmp_path / "full",
        "file": tmp_path / "afile.txt",
    }


def fill(text: str, paths: dict) -> str:
    for name, path in paths.items():
        text = text.replace("{" + name + "}", str(path))
    return text


def invoke(argv):
    result = CliRunner().invoke(main, argv)
    return result.exit_code, result.stdout, result.stderr, result.exception


def assert_one_error_line(code, stdout, stderr, exception=None):
    assert "Traceback" not in stderr and "Traceback" not in stdout, stderr
    if exception is not None:  # CliRunner keeps an uncaught exception here
        assert isinstance(exception, SystemExit), repr(exception)
    assert code == 2, f"exit code {code}, stderr: {stderr!r}"
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, f"expected one line on stderr, got {stderr!r}"
    assert lines[0].strip(), stderr
    assert lines[0].startswith("error:"), stderr
    return lines[0]


@pytest.mark.parametrize("argv, text, expect, contains, absent", CASES)
def test_bad_input(paths, argv, text, expect, contains, absent):
    if isinstance(text, bytes):
        paths["study"].write_bytes(text)
    elif text is not None:
        paths["study"].write_text(text, encoding="utf-8")
    code, stdout, stderr, exception = invoke([fill(a, paths) for a in argv])
    line = assert_one_error_line(code, stdout, stderr, exception)
    assert line.startswith(fill(expect, paths)), line
    for part in contains:
        assert fill(part, paths) in line, line
    for part in absent:
        assert part not in line, line
    assert stdout == "", stdout


def test_enough_cases():
    assert len(CASES) >= 35


# -- where an error from the command line is reported -----------------------------------------
@pytest.mark.parametrize(
    "argv, expect",
    [
        (["validate", "{valid}", "--set", "simulation.n_pathz=3"],
         "error: --set: simulation.n_pathz: unknown key"),
        (["validate", "{valid}", "--set", "simulation.n_paths=0"],
         "error: --set: simulation.n_paths: must be >= 1"),
        (["sweep", "{valid}", "-p", "model.params.v_bb=1,2", "--out", "{out}"],
         "error: --param: model.params.v_bb: unknown parameter of langevin"),
    ],
    ids=["set-unknown-key", "set-invalid-value", "param-unknown-parameter"],
)  # fmt: skip
def test_command_line_errors_name_the_option(paths, argv, expect):
    code, stdout, stderr, exception = invoke([fill(a, paths) for a in argv])
    line = assert_one_error_line(code, stdout, stderr, exception)
    assert line.startswith(fill(expect, paths)), line


# -- the real process ----------------------------------------------------------------------------
def test_console_script_exit_code(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(study({"model.params.zeta": -0.1}))
    proc = subprocess.run(
        [sys.executable, "-m", "stickslip.cli", "validate", str(bad)],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "JAX_PLATFORMS": "cpu"},
    )
    assert "Traceback" not in proc.stderr, proc.stderr
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines == [f"error: {bad}: model.params.zeta: must be > 0 (got -0.1)"], proc.stderr
    assert proc.stdout == ""


_QUICK_EXIT = """
import atexit, sys, threading, time
import stickslip.cli as cli
atexit.register(lambda: print("exit handler ran"))  # (stdout is a pipe: block-buffered)
mode, path, plain_exit = sys.argv[1], sys.argv[2], cli.quick_exit
def late():
    time.sleep(0.5)
    open(path, "w").write("done")
def quick_exit(code):  # a plugin's thread, not a daemon, still working at the end
    if mode == "thread":
        threading.Thread(target=late).start()
    plain_exit(code)
cli.quick_exit = quick_exit
sys.argv = ["stickslip", *sys.argv[3:]]
cli.console()
"""


@pytest.mark.parametrize("thread", ["none", "thread"])
def test_the_quick_exit_runs_exit_handlers_flushes_and_waits_for_threads(tmp_path, thread):
    """`console` leaves without the interpreter's teardown (`cli.quick_exit`), but as the
    ordinary exit would: exit handlers run, buffered output is written, the exit code kept,
    and a thread that is not a daemon finishes its work."""
    marker = tmp_path / "thread.txt"

    def command(*argv):
        return subprocess.run(
            [sys.executable, "-c", _QUICK_EXIT, thread, str(marker), *argv],
            capture_output=True, text=True, timeout=120,
            env={**os.environ, "JAX_PLATFORMS": "cpu"},
        )  # fmt: skip

    proc = command("models")
    assert proc.returncode == 0, proc.stderr
    assert "langevin" in proc.stdout
    assert proc.stdout.rstrip().endswith("exit handler ran")
    assert marker.exists() == (thread == "thread")
    if thread == "thread":
        assert marker.read_text() == "done"
    proc = command("validate", str(tmp_path / "missing.yaml"))
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: ") and "missing.yaml" in proc.stderr
    assert proc.stdout == "exit handler ran\n"


# -- nothing already written is lost or corrupted ---------------------------------------------
def _snapshot(root: pathlib.Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() if p.is_file() else b"<dir>"
        for p in sorted(root.rglob("*"))
    }


@pytest.mark.parametrize(
    "argv, text, expect",
    [
        (["run", "{study}", "--out", "{results}", "--quiet"], study({"simulation.dt": 0}),
         "error: {study}: simulation.dt: must be > 0"),
        (["run", "{study}", "--out", "{results}", "--quiet"], VALID_YAML,
         "error: --out: {results} exists and is not empty"),
        (["run", "{study}", "--out", "{results}"], VALID_YAML,
         "error: --out: {results} exists and is not empty"),
        (["run", "{study}", "--out", "{results}", "--quiet", "--set", "model.params.D=-1"],
         VALID_YAML, "error: "),
        (["sweep", "{study}", "-p", "model.params.v_b=1,-1", "--out", "{results}"], VALID_YAML,
         "error: "),
        (["sweep", "{study}", "-p", "model.params.v_b=1,2", "--out", "{results}"], VALID_YAML,
         "error: --out: {results} exists and is not empty"),
    ],
    ids=["run-bad-study", "run-no-force", "run-no-force-progress", "run-bad-set",
         "sweep-bad-value", "sweep-no-force"],
)  # fmt: skip
def test_existing_output_is_kept(tmp_path, argv, text, expect):
    area = tmp_path / "area"  # holds only the output directory: siblings are visible
    results = area / "results"
    results.mkdir(parents=True)
    (results / "keep.txt").write_text("precious results\n")
    src = tmp_path / "study.yaml"
    src.write_text(text)
    before = _snapshot(area)
    names = {"study": src, "results": results}
    code, stdout, stderr, exception = invoke([fill(a, names) for a in argv])
    line = assert_one_error_line(code, stdout, stderr, exception)
    assert line.startswith(fill(expect, names)), line
    assert _snapshot(area) == before
    assert sorted(p.name for p in area.iterdir()) == ["results"]  # no .results.partial-*
    assert (results / "keep.txt").read_text() == "precious results\n"


def test_bad_study_creates_no_output(tmp_path):
    area = tmp_path / "area"
    area.mkdir()
    src = tmp_path / "study.yaml"
    src.write_text(study({"simulation.n_paths": 0}))
    code, stdout, stderr, exception = invoke(["run", str(src), "--out", str(area / "results")])
    line = assert_one_error_line(code, stdout, stderr, exception)
    assert line.startswith(f"error: {src}: simulation.n_paths: must be >= 1"), line
    assert list(area.iterdir()) == []


# -- a fit with several candidate models: each mistake is one line at its field ---------------
FIT_STUDY = {
    "model": LANGEVIN["model"],
    "fit": {
        "data": "cycles.csv",
        "candidates": [
            {"name": "white", "params": {"tau": 0.03}, "free": {"D": [0.05, 2.0]}},
            {"name": "ou", "free": {"D": [0.05, 2.0], "tau": [0.01, 3.0]}},
        ],
    },
}


def _fit_study(change) -> str:
    spec = copy.deepcopy(FIT_STUDY)
    change(spec["fit"])
    return yaml.safe_dump(spec)


@pytest.mark.parametrize(
    "change, expect",
    [
        (lambda f: f["candidates"][0].update(colour="red"),
         "fit.candidates.0.colour: unknown key (known: name, model, params, free)"),
        (lambda f: f["candidates"][1].update(model={"name": "langevine"}),
         "fit.candidates.1.model.name: unknown model 'langevine'"),
        (lambda f: f["candidates"][1].update(name="white"),
         "fit.candidates.1.name: 'white' is already the name of candidates.0"),
        (lambda f: f.update(candidates=[]),
         "fit.candidates: must list at least two models to choose from (got an empty list)"),
        (lambda f: f.update(candidates=f["candidates"][:1]),
         "fit.candidates: must list at least two models"),
        (lambda f: f.update(free={"D": [0.1, 1.0]}),
         "fit.free: goes inside each candidate when candidates are listed"),
        (lambda f: f.pop("candidates"), "fit.free: is required"),
        (lambda f: f["candidates"][0].update(name="../white"), "fit.candidates.0.name: must be"),
        (lambda f: f["candidates"][0]["free"].update(tua=[0.1, 1.0]),
         "fit.candidates.0.free.tua: is not a parameter of langevin"),
        (lambda f: f["candidates"][0]["params"].update(tau=-1.0),
         "fit.candidates.0.params.tau: must be > 0"),
        (lambda f: f["candidates"][0].update(model=FIT_STUDY["model"]),
         "fit.candidates.0.params: give either model"),
        (lambda f: f["candidates"][1].update(free={}), "fit.candidates.1.free: must not be empty"),
        (lambda f: f.update(scales={"time": 0.01}), "fit.scales.force: is required"),
        (lambda f: f.update(alpha=0), "fit.alpha: must be > 0"),
    ],
    ids=["unknown-key", "unknown-model", "duplicate-name", "empty-list", "one-candidate",
         "free-and-candidates", "neither", "name-a-path", "unknown-free", "bad-change",
         "model-and-params", "no-free", "scales-no-force", "alpha-zero"],
)  # fmt: skip
def test_bad_candidates_are_one_line_and_keep_earlier_results(
    tmp_path, monkeypatch, change, expect
):
    """`stickslip fit` with a mistake in its candidates: exit 2, one line naming the field,
    before any fit; an earlier results folder under --out stays as it was."""
    import stickslip._inference.fit as fit_module

    def refuse(*args, **kwargs):
        raise AssertionError("a fit was started")

    monkeypatch.setattr(fit_module, "fit", refuse)
    area = tmp_path / "area"
    results = area / "results"
    results.mkdir(parents=True)
    (results / "keep.txt").write_text("precious results\n")
    src = tmp_path / "study.yaml"
    src.write_text(_fit_study(change))
    (tmp_path / "cycles.csv").write_text(
        "slip_time\n" + "".join(f"{1 + i / 7}\n" for i in range(30))
    )
    before = _snapshot(area)
    code, stdout, stderr, exception = invoke(
        ["fit", str(src), "--out", str(results), "-q", "--force"]
    )
    line = assert_one_error_line(code, stdout, stderr, exception)
    assert line.startswith(f"error: {src}: {expect}"), line
    assert _snapshot(area) == before
