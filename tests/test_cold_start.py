"""The first run on a fresh machine (issue 43): stand-in buffer sizes instead of one
compilation per size, the background compiler, the rent rule, and the same numbers under
every policy (`stickslip._compile.policy`)."""

from __future__ import annotations

import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from conftest import new_process

import stickslip as ss
from stickslip import _background, _compile

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)
OUTPUTS = ("slip_time", "stick_time", "slip_distance", "stick_position", "next_onset_state")

SCRIPT = """
import json, sys
import numpy as np
import stickslip as ss
params = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)
if float(sys.argv[3]) > 0:
    params["tau"] = float(sys.argv[3])
m = ss.get_model("langevin")(**params)
e = ss.simulate(m, int(sys.argv[1]), float(sys.argv[2]), 50.0, seed=3)
out = {k: np.nan_to_num(getattr(e, k)).ravel().tolist() for k in OUTPUTS}
print(json.dumps({"info": ss.cache_info(), "out": out}))
""".replace("OUTPUTS", repr(OUTPUTS))


def _process(cache_dir, n, dt, tau, policy):
    return json.loads(new_process(SCRIPT, cache_dir, n, dt, tau, STICKSLIP_COMPILE=policy))


@pytest.fixture
def empty_cache(tmp_path):
    """An empty compiled-code cache for this process (as on a fresh machine), restored
    after the test."""
    import jax

    before = jax.config.jax_compilation_cache_dir
    _compile.clear_caches()
    jax.config.update("jax_compilation_cache_dir", str(tmp_path))
    try:
        yield tmp_path
    finally:
        jax.config.update("jax_compilation_cache_dir", before)
        _compile.clear_caches()


# The grid monitor in the default tier (3 s from an empty cache); the exact detector, whose
# refinement compiles several capacities of its own as well (12 s), in the slow one. Every
# other test of the suite runs under `"reuse"` (conftest.py) and checks its numbers against
# independent references, stand-ins included.
@pytest.mark.parametrize(
    "monitor", [pytest.param("continuous", marks=pytest.mark.slow), "grid"], ids=["exact", "grid"]
)
def test_stand_in_sizes_give_the_numbers_of_every_size_compiled(
    empty_cache, monkeypatch, rent_held, monitor
):
    """From an empty cache, the `"reuse"` policy runs on the buffers it has and compiles a
    few programs: the survivors of a run on its first buffer (padded), a run of more paths
    in chunks of a compiled buffer (the exact detector's refinement in batches of its
    compiled buffer), one of fewer paths on a larger compiled buffer; `"eager"` then
    compiles every buffer size the run passes through. The same numbers to the last bit:
    they are keyed by path and step, not by buffer or chunk (the first paths of each run
    are those of the others). The exact detector (refinement, speculation at small buffers)
    and the grid monitor (sticks located after the stepping)."""
    model = ss.get_model("langevin")(**PUBLIC, tau=0.1)
    run = lambda n: ss.simulate(model, n, 0.2, 30.0, seed=5, monitor=monitor)  # noqa: E731
    monkeypatch.setenv("STICKSLIP_COMPILE", "reuse")
    before = ss.cache_info()["compiles"]
    first = run(300)
    # the model's description, the per-path helpers, the loop, the refinement or locator
    assert ss.cache_info()["compiles"] - before <= 4
    before = ss.cache_info()["compiles"]
    reuse = run(3000)  # wants 8192 paths' buffer: in chunks of the 1024 compiled
    fewer = run(100)  # wants 128: on 1024
    more = run(8000)  # wants 8192: in chunks of 1024
    # no loop, locator or refinement compiled: the onset states of 3000 and 8000 paths
    # (each one call) at most
    assert ss.cache_info()["compiles"] - before <= 2
    for name in OUTPUTS:
        a = getattr(reuse, name)
        np.testing.assert_array_equal(getattr(first, name), a[:300], err_msg=name)
        np.testing.assert_array_equal(getattr(fewer, name), a[:100], err_msg=name)
        np.testing.assert_array_equal(getattr(more, name)[:3000], a, err_msg=name)
    _compile.clear_caches()
    monkeypatch.setenv("STICKSLIP_COMPILE", "eager")
    before = ss.cache_info()["compiles"]
    eager = run(3000)
    assert ss.cache_info()["compiles"] > before  # sizes the reuse run never compiled
    for name in OUTPUTS:
        np.testing.assert_array_equal(getattr(reuse, name), getattr(eager, name), err_msg=name)
    assert reuse.stats["miss_bound"] == pytest.approx(eager.stats["miss_bound"], rel=1e-12)


@pytest.mark.slow
def test_the_background_compiler_makes_what_the_eager_run_needs(tmp_path):
    """A first run under the default policy asks the background compiler for the sizes it
    stood in for; once it is done, a run that wants every size (`"eager"`) finds them all
    compiled, and gets the first run's numbers."""
    first = _process(tmp_path, 3000, 0.2, 0.1, "background")
    assert first["info"]["background"] > 0
    assert _background.wait(tmp_path, timeout=300)
    again = _process(tmp_path, 3000, 0.2, 0.1, "eager")
    assert again["info"]["compiles"] == 0 and again["info"]["traces"] == 0, again["info"]
    assert again["out"] == first["out"]


@pytest.mark.skipif(
    not pathlib.Path("/proc/self/autogroup").exists(), reason="no autogroups (Linux only)"
)
def test_the_background_compiler_nices_its_session_too():
    """Where Linux shares the CPU between sessions first (autogrouping), the worker, alone in
    its session (`_spawn`), nices the session as well as itself: the kernel reports both
    (a niced process in a session of its own took a core of two from the foreground)."""
    code = (
        "import os, pathlib\n"
        "from stickslip import _background\n"
        "before = os.nice(0)\n"
        "_background._lower_priority()\n"
        "print(before, os.nice(0), pathlib.Path('/proc/self/autogroup').read_text())\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
        start_new_session=True,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    before, after, group = out.stdout.split(maxsplit=2)
    assert int(after) == min(19, int(before) + _background.NICE)  # (19: the most there is)
    assert group.split()[-2:] == ["nice", str(_background.NICE)], group


def test_the_worker_holds_the_queue_while_it_waits_for_its_run(tmp_path, monkeypatch):
    """The worker takes the queue's lock before it waits for the run that started it, so
    that the run's later requests find a worker and start no other (a first main job
    started eight, each a new Python process)."""
    seen = []

    def wait_for(pid, timeout):  # (the run has not exited yet: is the queue held?)
        with _background._try_lock(_background.queue_dir(tmp_path) / "worker.lock") as free:
            seen.append(free)

    monkeypatch.setattr(_background, "_wait_for", wait_for)
    monkeypatch.setattr(_background, "_lower_priority", lambda: None)  # (this process)
    monkeypatch.setenv("STICKSLIP_COMPILE", "reuse")  # (`main` sets its own: restored)
    assert _background.main([str(tmp_path), "1"]) == 0
    assert seen == [False]


def test_each_cpu_kind_has_its_own_queue(tmp_path, monkeypatch):
    """Nodes of two CPU kinds sharing a cache directory: a job queued on one is not pending
    for the other, and the other's worker leaves it (it would compile for its own CPU, into
    its own kind's executables, and the node that asked would never find it)."""
    from stickslip import _cpu

    job = _background.queue_dir(tmp_path) / "queued-here.job"
    job.parent.mkdir(parents=True)
    job.write_bytes(b"a job of this CPU kind")
    assert _background.pending(tmp_path) == 1
    monkeypatch.setattr(_cpu, "KIND", "another-kind")
    monkeypatch.setattr(_background, "_lower_priority", lambda: None)  # (this process)
    monkeypatch.setenv("STICKSLIP_COMPILE", "reuse")  # (`main` sets its own: restored)
    assert _background.pending(tmp_path) == 0 and _background.wait(tmp_path, timeout=5)
    assert _background.main([str(tmp_path)]) == 0
    assert job.exists()


def test_the_worker_finds_its_queue_without_importing_jax(tmp_path):
    """The worker takes its queue's lock before anything slow: a run's requests that find
    the queue free meanwhile each start another worker (a first call started 12, each
    importing JAX beside the run, and took 1-2 s longer, when the CPU kind came with JAX)."""
    code = (
        "import sys; from stickslip._background import queue_dir; queue_dir(sys.argv[1]); "
        "print(sorted(m for m in ('jax', 'jaxlib', 'numpy') if m in sys.modules))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == "[]"


def test_a_bad_policy_is_one_line(monkeypatch):
    monkeypatch.setenv("STICKSLIP_COMPILE", "fastest")
    model = ss.get_model("langevin")(**PUBLIC)
    with pytest.raises(ss.ParameterError, match="STICKSLIP_COMPILE.*background, reuse, eager"):
        ss.simulate(model, 10, 0.4, 5.0)


def test_cache_info_reports_compile_seconds():
    before = ss.cache_info()
    for key in ("trace_seconds", "compile_seconds", "load_seconds", "background"):
        assert before[key] >= 0
    model = ss.get_model("langevin")(**PUBLIC, tau=0.1)
    ss.simulate(model, 100, 0.4, 5.0)
    after = ss.cache_info()
    if after["compiles"] > before["compiles"]:
        assert after["compile_seconds"] > before["compile_seconds"]


def test_rent_compiles_once_the_waste_passes_a_compilation(monkeypatch):
    """The ski-rental rule: a program's rent is the time wasted on larger stand-ins; it is
    due once it passes what a compilation costs here."""
    monkeypatch.setattr(_compile, "_rent", {})
    monkeypatch.setattr(_compile, "compile_estimate", lambda fn=None: 1.0)
    assert not _compile.rent("loop", 0.6)
    assert not _compile.due("loop")
    assert _compile.rent("loop", 0.5) and _compile.due("loop")
    assert not _compile.due("other")
    _compile.pay("loop")  # compiled: one compilation's cost off the rent
    assert not _compile.due("loop") and _compile._rent["loop"] == pytest.approx(0.1)


def test_the_cold_note_says_when_the_cache_is_empty(empty_cache, monkeypatch):
    """The note comes when this CPU kind has no executables: an empty cache, or one that
    holds only another kind's (a cache directory shared by the nodes of a cluster)."""
    from stickslip import _cpu

    assert "first run" in _compile.cold_note()
    ss.simulate(ss.get_model("langevin")(**PUBLIC), 100, 0.4, 5.0)
    assert _compile.cold_note() is None
    monkeypatch.setattr(_cpu, "KIND", "another-kind")
    assert "first run" in _compile.cold_note()


@pytest.mark.slow
@pytest.mark.parametrize("tau", [0.1, 0.0], ids=["ou-exact", "white-brownian"])
def test_the_public_set_cold_and_warm_gives_one_ensemble(tmp_path, tau):
    """The README's first call (10^5 paths of the public set at dt 0.8) from an empty cache:
    at most 4 compilations (OU noise); after the background compiler, the run on every
    exact size gives the same ensemble to the last bit."""
    first = _process(tmp_path, 100_000, 0.8, tau, "background")
    if tau:
        assert first["info"]["compiles"] <= 4
    assert _background.wait(tmp_path, timeout=600)
    again = _process(tmp_path, 100_000, 0.8, tau, "eager")
    assert again["info"]["compiles"] == 0
    assert again["out"] == first["out"]


@pytest.mark.slow
def test_a_long_run_on_few_paths_compiles_its_small_sizes(empty_cache, monkeypatch):
    """Many steps on a stand-in buffer pay its rent: the run compiles the smaller sizes it
    wants after all (a first run must not stay slow where compiling pays)."""
    monkeypatch.setenv("STICKSLIP_COMPILE", "reuse")
    monkeypatch.setattr(_compile, "compile_estimate", lambda fn=None: 0.05)
    model = ss.get_model("langevin")(**PUBLIC, tau=0.1)
    ss.simulate(model, 20_000, 0.02, 40.0, seed=1)
    assert ss.cache_info()["compiles"] > 4


@pytest.mark.slow  # compiles the cycles' programs from an empty cache (~8 s)
def test_the_cycles_prefetch_compiles_what_the_cycles_then_run(empty_cache):
    """A study compiles the programs of its time series' cycles in a thread while its
    ensemble runs (`prefetch_cycles`): the cycles then compile none of them again (were
    they another buffer size or program, the prefetch were wasted). The refinement is not
    prefetched (in a study the ensemble's larger capacity stands in for the cycles' few
    candidates): alone, the cycles compile it."""
    from stickslip._simulate.cycles import prefetch_cycles

    def made():
        names = ("steps.onset", "steps.advance", "cycles._record")
        counts = {_compile._name(f): n for f, (_, n) in _compile._compiled_seconds.items()}
        return {k: v for k, v in counts.items() if k.endswith(names)}

    model = ss.get_model("langevin")(**PUBLIC, tau=0.1)
    before = made()
    prefetch_cycles(model, 2, 0.005, 60.0).join()
    prefetched = made()
    assert sum(prefetched.values()) - sum(before.values()) == 3  # onset, stepping, recording
    series = ss.simulate_cycles(model, 2, 0.005, 60.0, seed=1)
    assert made() == prefetched
    assert series.cycles["period"].size > 2


@pytest.mark.slow  # traces every shipped configuration in a new process (~10 s; CI runs it)
def test_the_shipped_traces_are_current(tmp_path):
    """A first run of the built-in model on a new machine traces nothing: the traces shipped
    with the package (`stickslip._ship`) are the ones it would make. Fails after an edit of a
    traced source until `python -m stickslip._ship` makes them again. (Made with other
    library versions than the installed ones, they cannot apply: a release makes them with
    the versions it pins.)"""
    from stickslip import _ship

    made_with = json.loads((_compile.SHIPPED / "versions.json").read_text())
    if made_with != _ship.versions():
        pytest.skip(f"shipped traces made with {made_with}, installed {_ship.versions()}")
    first = _process(tmp_path, 1000, 0.4, 0.1, "reuse")
    info = first["info"]
    assert info["traces"] == 0 and info["shipped_loaded"] >= 4, (
        f"{info['traces']} traces made, {info['shipped_loaded']} shipped ones used: the "
        "shipped traces are stale; run `python -m stickslip._ship`"
    )
    # The other usual configurations (Euler-Maruyama, noise-free, the grid monitor, the
    # upcrossings of the docs' empirical estimator, the docs' chain) and the other built-in
    # models (the friction block, a threshold law), with other parameters than `_ship`'s.
    info = json.loads(new_process(OTHERS, tmp_path / "others"))
    assert info["traces"] == 0 and info["shipped_loaded"] >= 16, info


OTHERS = """
import json
import stickslip as ss
base = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)
ss.simulate(ss.get_model("langevin")(**base), 300, 0.02, 20.0, solver="euler")
ss.simulate(ss.get_model("langevin")(**base | {"D": 0.0}, tau=0.1), 8, 0.05, 30.0)
ss.simulate(ss.get_model("langevin")(**base, tau=0.1), 300, 0.005, 20.0, monitor="grid")
ss.simulate(ss.get_model("langevin")(**base, tau=0.1), 300, 0.005, 10.0, record_upcrossings=12)
ss.simulate_chain(ss.get_model("burridge-knopoff").example(), 1, 0.02, 20.0, record_dt=0.2)
ss.simulate(ss.get_model("langevin")(**base), 300, 0.2, 20.0, monitor="grid")
ss.simulate(ss.get_model("friction-block").example(), 300, 0.02, 20.0)
law = {"threshold": "weibull", "threshold_params": {"shape": 3.0, "scale": 1.1}}
rt = ss.get_model("random-threshold")(omega0=1.0, zeta=0.1, D=0.2, v_b=1.0, tau=0.1, **law)
ss.simulate(rt, 300, 0.2, 20.0)
print(json.dumps(ss.cache_info()))
"""
