"""Shared test helpers: the reference data and the registry of models under contract."""

from __future__ import annotations

import json
import math
import os
import pathlib
import subprocess

import numpy as np
import pytest

DATA = pathlib.Path(__file__).parent / "data"

# The suite runs many models and sizes, each compiled once: it takes the stand-in sizes the
# simulator already has rather than compiling every buffer size (the same numbers: checked by
# tests/test_cold_start.py, which also tests the other policies), and starts no background
# compiler (`stickslip._compile.policy`). A value set by the caller is kept.
os.environ.setdefault("STICKSLIP_COMPILE", "reuse")


@pytest.hookimpl(trylast=True)  # (after the deselection of `-m`)
def pytest_collection_modifyitems(items):
    """The modules in the order the workers take them (`--dist loadscope
    --no-loadscope-reorder`): those marked `early` first, then the others by their number of
    tests, most first (xdist's own order). A module of one long test handed out last kept
    one worker busy while the other sat idle: the plugin package's build and run, 8-10 s at
    the end of the default tier."""
    modules: dict[str, list] = {}
    for item in items:
        modules.setdefault(item.nodeid.split("::")[0], []).append(item)
    order = sorted(
        modules.values(),
        key=lambda tests: (tests[0].get_closest_marker("early") is None, -len(tests)),
    )
    items[:] = [item for tests in order for item in tests]


RELEASE_RSS = 1.5e9  # bytes, per test process (up to 4 run at once)


def _rss() -> float:
    try:
        pages = int(pathlib.Path("/proc/self/statm").read_text().split()[1])
    except (OSError, ValueError, IndexError):
        return 0.0
    import os

    return pages * os.sysconf("SC_PAGE_SIZE")


_after_release = [0.0]  # the process's size after its last release


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_code():
    """Drop the compiled executables once a test module ends if the process holds more than
    RELEASE_RSS, and half of it more than after its last release: a whole suite in one
    process otherwise keeps every shape ever compiled (several GB by the end; a full run
    once aborted inside XLA there). The on-disk compilation cache keeps recompiling cheap.
    (The process does not shrink back to its size before: releasing after every module
    from there on only made each module load its executables again.)"""
    yield
    import sys

    if "stickslip._compile" not in sys.modules:
        return
    rss = _rss()
    if rss > max(RELEASE_RSS, _after_release[0] + RELEASE_RSS / 2):
        sys.modules["stickslip._compile"].clear_caches()
        _after_release[0] = _rss()


@pytest.fixture
def rent_held(monkeypatch):
    """The rent rule held off (`_compile.rent`: a run on a stand-in buffer compiles the size
    it wants once the time it wasted, summed over the process's runs, passes a
    compilation's cost), for a test that counts compilations: what comes due is a matter of
    timing (it did in one cold tier of five, 2026-12-01)."""
    from stickslip import _compile

    monkeypatch.setattr(_compile, "compile_estimate", lambda fn=None: math.inf)


@pytest.fixture(scope="session")
def reference():
    """The public reference set (independent NumPy implementation); see data/README.md."""
    npz = np.load(DATA / "langevin_ou_public.npz")
    meta = json.loads((DATA / "langevin_ou_public.json").read_text())
    return {k: npz[k] for k in npz.files} | {"meta": meta}


@pytest.fixture(scope="session")
def Langevin():
    import stickslip

    return stickslip.get_model("langevin")


def run_cli(*args, cwd=None) -> subprocess.CompletedProcess:
    """`stickslip *args` run in this process (click's `CliRunner`, from `cwd`), returned as
    `subprocess.run` returns it (`returncode`, `stdout`, `stderr`): a new process would spend
    1-2 s importing and loading compiled code before the command starts. An exception the
    command does not handle is raised here. The installed console script in a process of its
    own is tested in tests/test_study_errors.py (`test_console_script_exit_code`)."""
    from click.testing import CliRunner

    from stickslip.cli import main

    before = os.getcwd()
    if cwd is not None:
        os.chdir(cwd)
    try:
        result = CliRunner().invoke(main, [str(a) for a in args])
    finally:
        os.chdir(before)
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    return subprocess.CompletedProcess(args, result.exit_code, result.stdout, result.stderr)


def new_process(code: str, cache_dir, *args, timeout: float = 600, **env) -> str:
    """`python -c code *args` in a new process with its own compiled-code cache `cache_dir`
    (and `env` added to the environment): the last line it prints. For what only a new
    process shows (what it compiles, traces or loads from disk)."""
    import sys

    env = dict(os.environ, STICKSLIP_CACHE_DIR=str(cache_dir), **env)
    done = subprocess.run(
        [sys.executable, "-c", code, *map(str, args)], env=env, capture_output=True,
        text=True, check=True, timeout=timeout,
    )  # fmt: skip
    return done.stdout.strip().splitlines()[-1]


def run_script(path, *args) -> subprocess.CompletedProcess:
    """`python path *args` run in this process (as `__main__`, its stdout and stderr
    captured), returned as `subprocess.run` returns it: an example's run without a new
    process's start (importing JAX, loading compiled code: 1-2 s each). An exception the
    script does not handle is raised here."""
    import contextlib
    import io
    import runpy
    import sys

    out, err = io.StringIO(), io.StringIO()
    argv, code = sys.argv, 0
    sys.argv = [str(path), *(str(a) for a in args)]
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            runpy.run_path(str(path), run_name="__main__")
    except SystemExit as stop:
        code = stop.code if isinstance(stop.code, int) else int(stop.code is not None)
    finally:
        sys.argv = argv
    return subprocess.CompletedProcess(args, code, out.getvalue(), err.getvalue())


SLIP_METHODS = ("drift", "diffusion", "crossing", "crossing_rate", "crossing_noise")


def assert_same_slip(model, states) -> None:
    """`model.slip_phase()` (what the simulator's compiled slip-phase code runs on) gives the
    model's own slip-phase numbers, bit for bit, at each state in `states`."""
    slip = model.slip_phase()
    assert slip.state_names == model.state_names and slip.noise_dim == model.noise_dim
    assert slip.crossing_is_smooth == model.crossing_is_smooth
    assert float(slip.stick_level) == float(model.stick_level)
    for y in states:
        for f in SLIP_METHODS:
            np.testing.assert_array_equal(getattr(slip, f)(y), getattr(model, f)(y), err_msg=f)


def chi2_homogeneity(counts_a, counts_b, min_expected=5.0):
    """Chi-square test that two histograms (same bins) come from one distribution.

    Adjacent bins are merged until every expected count is at least `min_expected` (the
    usual validity rule). Returns `(statistic, dof, p_value)`.
    """
    from scipy import stats

    a = np.asarray(counts_a, float)
    b = np.asarray(counts_b, float)
    na, nb = a.sum(), b.sum()
    merged_a, merged_b = [], []
    acc_a = acc_b = 0.0
    for x, y in zip(a, b, strict=True):
        acc_a += x
        acc_b += y
        total = acc_a + acc_b
        if min(total * na / (na + nb), total * nb / (na + nb)) >= min_expected:
            merged_a.append(acc_a)
            merged_b.append(acc_b)
            acc_a = acc_b = 0.0
    if acc_a + acc_b > 0:  # leftover tail joins the last bin
        merged_a[-1] += acc_a
        merged_b[-1] += acc_b
    table = np.array([merged_a, merged_b])
    stat, p, dof, _ = stats.chi2_contingency(table, correction=False)
    return stat, dof, p


def without_zero_pile(counts, edges):
    """Slip-distance counts with the bin holding d = 0 merged into its left neighbour.

    The reference's grid convention (first grid point with v >= v_b, linear interpolation)
    puts a path whose velocity is back at v_b by the first grid point at T_sl = 0, d = 0
    exactly: about 0.1 % of its paths at dt = 0.005, an artefact of interpolating from
    v(0) = v_b. In continuous time such a path dips below v_b first and re-sticks a little
    ahead of its start (d slightly negative), one bin to the left. Merging the two bins
    compares everything else."""
    counts = np.asarray(counts, float).copy()
    k = int(np.searchsorted(edges, 0.0, side="right")) - 1
    counts[k - 1] += counts[k]
    return np.delete(counts, k)


def benchmark_module(name: str):
    """A module of `benchmarks/` (e.g. the independent generator `independent_slider`),
    loaded once by its path (the folder is not a package)."""
    import importlib.util
    import sys

    if name in sys.modules:
        return sys.modules[name]
    path = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
