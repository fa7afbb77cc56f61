"""Compiled-code reuse: one trace per model structure (any dt, any buffer size), traces and
executables reused from disk by a new process, a bounded in-process cache."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import new_process

import stickslip as ss
from stickslip import _compile

WHITE = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)  # white noise: the smallest loop

SCRIPT = """
import json, sys
import numpy as np
import stickslip as ss
m = ss.get_model("langevin")(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)
e = ss.simulate(m, 300, float(sys.argv[1]), 50.0, seed=3)
print(json.dumps({"info": ss.cache_info(), "slip_time": np.nan_to_num(e.slip_time).tolist()}))
"""


def _fresh_process(cache_dir, dt, **env):
    return json.loads(new_process(SCRIPT, cache_dir, dt, **env))


def test_a_new_step_size_reuses_the_compiled_code():
    """OU noise (the exact detector): nothing is compiled again for a new dt. (The
    refinement's buffers follow the number of candidate steps, not dt: the first run, at the
    largest step, has the most and compiles every size the others use.)"""
    model = ss.get_model("langevin")(**WHITE, tau=0.1)
    ss.simulate(model, 100, 0.7, 20.0, seed=1)
    before = ss.cache_info()
    for dt in (0.02, 0.05, 0.1, 0.3):
        ens = ss.simulate(model, 100, dt, 20.0, seed=1)
        assert ens.stats["compile_seconds"] == 0.0
    after = ss.cache_info()
    assert (after["traces"], after["compiles"]) == (before["traces"], before["compiles"])


def test_a_new_number_of_paths_reuses_the_compiled_code():
    """Runs of 1000 and then 300, 500, 700 paths (one buffer size): nothing is compiled or
    loaded again, the per-path helpers (onset states, stick times) included, which run on
    the buffer size; their results are those of the run itself (cut back, not padded).
    (The refinement's buffers follow the number of candidates: the first run, the largest,
    compiles every size the others use.)"""
    model = ss.get_model("langevin")(**WHITE, tau=0.1)
    big = ss.simulate(model, 1000, 0.4, 20.0, seed=1)
    before = ss.cache_info()
    for n in (300, 500, 700):
        ens = ss.simulate(model, n, 0.4, 20.0, seed=1)
        assert ens.stats["compile_seconds"] == 0.0
        assert ens.next_onset_state.shape == ens.onset_state.shape == (n, 3)
        assert ens.slip_time.shape == ens.stick_time.shape == (n,)
    after = ss.cache_info()
    keys = ("traces", "compiles", "exported_loaded", "executables_loaded")
    assert [after[k] for k in keys] == [before[k] for k in keys]
    # The 700-path run is the first 700 paths of the 1000-path one (padding changes nothing).
    for name in ("slip_time", "stick_time", "slip_distance", "next_onset_state"):
        np.testing.assert_array_equal(getattr(big, name)[:700], getattr(ens, name))


def test_a_repeated_run_looks_up_its_loops_by_a_cheap_key(monkeypatch):
    """A second run of one configuration (a new model instance and new step) finds the
    stepping loop's and the refinement's executables without `_compile.executable`, whose
    key partitions and hashes the model and solver (~0.3 ms a call, 20 calls a run)."""
    model = ss.get_model("langevin")(**WHITE, tau=0.1)
    ss.simulate(model, 3000, 0.8, 20.0, seed=1)
    seen = []
    lookup = _compile.executable

    def spy(fn, *args, **kwargs):
        if kwargs.get("build", True):  # (probes for sizes never compiled may look)
            seen.append(getattr(fn, "__name__", repr(fn)))
        return lookup(fn, *args, **kwargs)

    monkeypatch.setattr(_compile, "executable", spy)
    again = ss.get_model("langevin")(**WHITE, tau=0.1)
    ens = ss.simulate(again, 3000, 0.4, 20.0, seed=2)
    assert ens.stats["candidates"] > 1000  # the refinement ran
    assert not {"advance", "refine_levels"} & set(seen), seen


def test_a_repeated_run_passes_its_model_arrays_already_on_the_device(monkeypatch):
    """The model's and solver's arrays go to the device once, for every run of the model: a
    second run's stepping loop gets device arrays (the same ones), not NumPy arrays that a
    compiled call would copy again."""
    import jax

    made = []
    fixed_init = _compile.Fixed.__init__

    def spy(self, fn, *args, **kwargs):
        fixed_init(self, fn, *args, **kwargs)
        made.append(self)

    monkeypatch.setattr(_compile.Fixed, "__init__", spy)
    runs = []
    for seed in (1, 2):
        made.clear()
        ss.simulate(ss.get_model("langevin")(**WHITE, tau=0.1), 1000, 0.8, 20.0, seed=seed)
        runs.append([f.leaves for f in made if f.fn.__name__ == "advance"][0])
    first, second = runs
    assert len(first) > 10 and all(isinstance(x, jax.Array) for x in first + second)
    assert all(a is b for a, b in zip(first, second, strict=True))
    big = np.arange(2.0 * _compile._RESIDENT_BYTES)
    assert _compile.on_device(big) is not _compile.on_device(big)  # large: not kept
    np.testing.assert_array_equal(np.asarray(_compile.on_device(big)), big)


def test_white_noise_recompiles_only_the_locator_per_node_count():
    """White noise (Brownian-bridge location): the stepping loop is shared by every dt; only
    the stick locator, whose interpolation nodes follow dt (powers of two), is compiled per
    node count."""
    model = ss.get_model("langevin")(**WHITE)
    nodes = set()
    ss.simulate(model, 100, 0.3, 20.0, seed=1)
    before = ss.cache_info()
    for dt in (0.3, 0.2, 0.1, 0.05):
        nodes.add(ss.simulate(model, 100, dt, 20.0, seed=1).info["interpolation_nodes"])
    after = ss.cache_info()
    assert after["compiles"] - before["compiles"] <= len(nodes) - 1


def test_a_new_process_neither_traces_nor_compiles(tmp_path):
    """The second process loads every executable from disk and gets the same numbers, bar
    one entry damaged in between (a write cut short), which it compiles again (from the
    first one's trace) with the same result."""
    first = _fresh_process(tmp_path, 0.1)
    assert first["info"]["compiles"] > 1
    entries = sorted(_compile.executable_dir(tmp_path).glob("*.bin"))
    assert len(entries) == first["info"]["compiles"]
    entries[0].write_bytes(b"not an executable")
    second = _fresh_process(tmp_path, 0.1)
    assert second["info"]["traces"] == 0 and second["info"]["compiles"] == 1
    assert second["info"]["executables_loaded"] == len(entries) - 1
    assert second["slip_time"] == first["slip_time"]


SOLVE = """
import json
import jax.numpy as jnp
from stickslip import _compile
def solve(a, b):  # a linear solve: LAPACK, as the implicit solvers of a model with memory
    return jnp.linalg.solve(a, b)
f = _compile.eqx.filter_jit(solve)
a = jnp.array([[4.0, 1.0, 0.5], [1.0, 3.0, -1.0], [0.5, -1.0, 2.0]])
b = jnp.array([1.0, -2.0, 0.25])
x = _compile.call(f, a, b, paths=0)
print(json.dumps(dict(x=[float(v) for v in x], stats=_compile.stats)))
"""


def test_an_executable_that_calls_lapack_runs_when_loaded_from_disk(tmp_path):
    """A program with a linear solve, compiled by one process and loaded from disk by the
    next, which lowers nothing: the second process runs it (it crashed, a segmentation
    fault, while nothing had bound LAPACK's routines) and gets NumPy's solution."""
    first = json.loads(new_process(SOLVE, tmp_path))
    second = json.loads(new_process(SOLVE, tmp_path))
    assert first["stats"]["compiles"] == 1
    assert second["stats"]["compiles"] == 0 and second["stats"]["executables_loaded"] == 1
    a = np.array([[4.0, 1.0, 0.5], [1.0, 3.0, -1.0], [0.5, -1.0, 2.0]])
    expected = np.linalg.solve(a, [1.0, -2.0, 0.25])
    np.testing.assert_allclose(second["x"], expected, rtol=1e-12)
    np.testing.assert_allclose(first["x"], expected, rtol=1e-12)


SHARED = """
import json
import jax.numpy as jnp
from stickslip import _compile
def loop(x, option):  # `option`: a static argument the program does not read
    return jnp.sin(x) * 1.25
f = _compile.eqx.filter_jit(loop)
x = jnp.linspace(0.0, 1.0, 64)
def here():
    return _compile.call(f, x, "a", paths=64)
def there():
    def deeper():
        return _compile.call(f, x, "b", paths=64)
    return deeper()
first = here()
before = dict(_compile.stats)
second = there()
print(json.dumps(dict(before=before, after=_compile.stats, same=bool((first == second).all()))))
"""


def test_one_program_reached_from_two_places_compiles_once(tmp_path):
    """Two static keys that trace the same program, from two call stacks (say `langevin`
    with `eta0="zero"` and `"stationary"`, which the stepping loop does not read, one run
    by a test and one by `select_method`): the second trace loads the first one's
    executable. (Source locations in the traces made them two modules before 2026-11-26,
    and the test suite compiled ~1.5 s per buffer size again for each.)"""
    got = json.loads(new_process(SHARED, tmp_path, timeout=300))
    before, after = got["before"], got["after"]
    assert after["traces"] == before["traces"] + 1  # a new static key: a new trace
    assert after["compiles"] == before["compiles"]  # ... but no new compilation
    assert after["executables_loaded"] == before["executables_loaded"] + 1
    assert got["same"]


HOLDER = """
import sys
import jax.numpy as jnp
from stickslip import _compile
x = jnp.linspace(0.0, 1.0, 64)
f = _compile.eqx.filter_jit(lambda x: jnp.sin(x) * 1.25)
dynamic, static = _compile.eqx.partition((x,), _compile.eqx.is_array)
leaves, treedef = _compile.jax.tree_util.tree_flatten(dynamic)
exported = _compile._export(f, leaves, treedef, static, 64)
file = _compile._executable_file(exported, leaves)
with _compile._exclusive(file):
    print("locked", flush=True)
    sys.stdin.readline()  # the waiter is now at the lock
    compiled = _compile._fresh(_compile.jax.jit(exported.call).lower(*leaves))
    _compile._save_executable(file, compiled, exported, leaves)
"""

WAITER = """
import json
import jax.numpy as jnp
from stickslip import _compile
x = jnp.linspace(0.0, 1.0, 64)
f = _compile.eqx.filter_jit(lambda x: jnp.sin(x) * 1.25)
print("calling", flush=True)
y = _compile.call(f, x, paths=64)
print(json.dumps(dict(_compile.stats, y=float(y.sum()))), flush=True)
"""


def test_a_process_waits_for_the_one_compiling_the_same_code(tmp_path):
    """Two processes that meet the same executable cold compile it once: the second waits
    for the first (a lock beside the disk entry) and loads its copy."""
    env = dict(os.environ, STICKSLIP_CACHE_DIR=str(tmp_path))
    run = dict(env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    holder = subprocess.Popen([sys.executable, "-c", HOLDER], **run)
    waiter = None
    try:
        assert holder.stdout.readline().strip() == "locked"
        waiter = subprocess.Popen([sys.executable, "-c", WAITER], **run)
        assert waiter.stdout.readline().strip() == "calling"
        time.sleep(1.0)  # unlocked, the waiter would have compiled by now
        holder.stdin.write("go\n")
        holder.stdin.flush()
        assert holder.wait(timeout=120) == 0
        out, _ = waiter.communicate(timeout=120)
    finally:  # nothing left running if an assertion failed
        for proc in (holder, waiter):
            if proc is not None:
                proc.kill()
    stats = json.loads(out.strip().splitlines()[-1])
    assert stats["compiles"] == 0 and stats["traces"] == 0
    assert stats["executables_loaded"] == 1
    assert stats["y"] == pytest.approx(float(np.sum(np.sin(np.linspace(0.0, 1.0, 64)) * 1.25)))


@pytest.mark.slow
def test_other_xla_options_compile_again_with_the_same_numbers(tmp_path):
    """Executables are keyed by `XLA_FLAGS` too (they change the code XLA emits): a process
    with XLA's default 256-bit vectors does not load the entries of one with stickslip's
    choice (512-bit on an AVX-512 CPU), and gets the same numbers to the last bit."""
    first = _fresh_process(tmp_path, 0.1)
    other = _fresh_process(tmp_path, 0.1, XLA_FLAGS="--xla_cpu_prefer_vector_width=256")
    assert other["info"]["compiles"] > 0 and other["info"]["executables_loaded"] == 0
    assert other["slip_time"] == first["slip_time"]


def test_the_cpu_kind_follows_the_instruction_sets():
    """A CPU's kind (the compiled code's key on disk) is its maker, family, model and
    instruction-set flags, whatever their order: a CPU with AVX-512 beside one without, or
    another maker's, is another kind."""
    from stickslip._cpu import kind

    zen3 = {
        "vendor_id": "AuthenticAMD", "cpu family": "25", "model": "1",
        "flags": "fpu sse2 avx avx2 fma", "bogomips": "4890.8", "cpu MHz": "2445.4",
    }  # fmt: skip
    same = dict(zen3, flags="fma avx2 avx sse2  fpu", bogomips="4891.0", **{"cpu MHz": "3000"})
    assert kind(zen3) == kind(same)
    for change in ({"flags": zen3["flags"] + " avx512f"}, {"vendor_id": "GenuineIntel"},
                   {"model": "17"}, {"cpu family": "26"}):  # fmt: skip
        assert kind(zen3 | change) != kind(zen3), change
    arm = {"CPU implementer": "0x41", "CPU part": "0xd0c", "Features": "fp asimd atomics"}
    assert kind(arm) != kind(arm | {"Features": "fp asimd atomics sve"})
    assert kind(arm) != kind(arm | {"CPU part": "0xd40"})
    power9 = {"cpu": "POWER9 (raw), altivec supported", "revision": "2.2 (pvr 004e 1202)"}
    assert kind(power9) != kind({**power9, "cpu": "POWER10 (raw), altivec supported"})
    s390 = {"vendor_id": "IBM/S390", "features": "esan3 zarch stfle msa vx vxd vxe"}
    assert kind(s390) != kind(s390 | {"features": s390["features"] + " vxe2"})
    riscv = {"isa": "rv64imafdc", "uarch": "sifive,u74-mc"}
    assert kind(riscv) != kind(riscv | {"isa": "rv64imafdcv"})


def test_the_cpu_description_is_the_first_processors(tmp_path):
    """Linux's CPU description read up to the first processor's end: a blank line, or the
    next processor's first entry where no blank line parts them; lines without an entry
    skipped."""
    from stickslip._cpu import description

    text = "\nprocessor\t: 0\nvendor_id\t: AuthenticAMD\nnot an entry\nflags\t\t: fpu avx2\n"
    apart, joined = tmp_path / "apart", tmp_path / "joined"
    apart.write_text(text + "\nprocessor\t: 1\nflags\t\t: fpu avx512f\n")
    joined.write_text(text + "processor\t: 1\nflags\t\t: fpu avx512f\n")
    first = {"processor": "0", "vendor_id": "AuthenticAMD", "flags": "fpu avx2"}
    assert description(str(apart)) == description(str(joined)) == first
    assert description(str(tmp_path / "absent")) == {}


def test_compiled_code_on_disk_is_kept_per_cpu_kind(monkeypatch, tmp_path):
    """The executables' folder, and the key of JAX's own persistent cache (which holds CPU
    entries under "cpu" alone), name the CPU kind: a node of another kind sharing the cache
    directory finds none of this one's code."""
    from jax._src import cache_key

    from stickslip import _cpu, _jax

    if _jax.CACHE_SET_HERE:  # (the default: stickslip set the cache directory at import)
        assert _cpu.KIND in cache_key.custom_hook()
    _jax._key_by_cpu()  # (once only: a second call adds nothing)
    here, hook = _compile.executable_dir(tmp_path), cache_key.custom_hook()
    assert hook.count(_cpu.KIND) == 1
    assert here.parent == tmp_path / "stickslip-executable" and _cpu.KIND in hook
    monkeypatch.setattr(_cpu, "KIND", "another-kind")
    assert _compile.executable_dir(tmp_path) != here
    assert cache_key.custom_hook() != hook and "another-kind" in cache_key.custom_hook()


OTHER_CPU = """
import json, sys
import numpy as np
from stickslip import _cpu
_cpu.KIND = sys.argv[2]
import stickslip as ss
m = ss.get_model("langevin")(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)
e = ss.simulate(m, 300, float(sys.argv[1]), 50.0, seed=3)
from stickslip._compile import _cache_hits, jax  # a program JAX itself keeps on disk
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
jax.jit(lambda x: 2.0 * x + 1.0)(np.arange(3.0))
print(json.dumps({"info": ss.cache_info(), "jax_hits": _cache_hits[0],
                  "slip_time": np.nan_to_num(e.slip_time).tolist()}))
"""


@pytest.mark.slow  # three new processes, two compiling from scratch (~15 s)
def test_a_node_of_another_cpu_kind_compiles_its_own_code(tmp_path):
    """A cache directory shared by nodes of two CPU kinds: the second kind loads none of the
    first's executables nor JAX's own entries (XLA would load them with only a logged
    error, and code for another CPU may stop on an illegal instruction), compiles its own
    with the same numbers, and the first kind's next process still finds all of its own."""
    first = json.loads(new_process(OTHER_CPU, tmp_path, 0.1, "kind-a"))
    other = json.loads(new_process(OTHER_CPU, tmp_path, 0.1, "kind-b"))
    assert other["info"]["executables_loaded"] == 0 and other["jax_hits"] == 0
    assert other["info"]["compiles"] == first["info"]["compiles"] > 0
    assert other["info"]["traces"] == 0  # the traces (portable) are shared
    again = json.loads(new_process(OTHER_CPU, tmp_path, 0.1, "kind-a"))
    assert again["info"]["compiles"] == 0 and again["jax_hits"] == 1
    assert again["slip_time"] == other["slip_time"] == first["slip_time"]


@pytest.mark.slow  # two new processes compiling from scratch (~10 s)
def test_executables_are_kept_whatever_jax_own_cache_holds(tmp_path):
    """With the executables gone but JAX's own persistent cache left (where an executable
    JAX loads cannot be serialised again), a new process compiles and keeps them once more,
    and the one after it compiles nothing."""
    import shutil

    _fresh_process(tmp_path, 0.1)
    shutil.rmtree(tmp_path / "stickslip-executable")
    again = _fresh_process(tmp_path, 0.1)
    assert again["info"]["compiles"] > 0
    third = _fresh_process(tmp_path, 0.1)
    assert third["info"]["compiles"] == 0 and third["slip_time"] == again["slip_time"]


def test_the_in_process_cache_is_bounded_and_can_be_cleared(monkeypatch):
    model = ss.get_model("langevin")(**WHITE)
    monkeypatch.setattr(_compile, "MAX_ENTRIES", 3)
    monkeypatch.setenv("STICKSLIP_COMPILE", "eager")
    a = ss.simulate(model, 300, 0.1, 20.0, seed=2)  # several buffer sizes, more than 3 entries
    assert ss.cache_info()["entries"] <= 3
    ss.clear_caches()
    assert ss.cache_info()["entries"] == 0
    b = ss.simulate(model, 300, 0.1, 20.0, seed=2)
    np.testing.assert_array_equal(a.slip_time, b.slip_time)


def test_quick_programs_give_the_numbers_of_optimised_ones(monkeypatch):
    """The onset, the stick locator and the cycles' recording are compiled with XLA's
    elemental emitters (`_compile.QUICK`: a third less compile time). Compiled with its
    default fusion emitters instead (kept apart on disk: the options are in the key), they
    give the same sticks, slips and trajectories to the last bit: an Euler run (cubic stick
    location) and an exact one, and a cycle series."""
    from stickslip._simulate import cycles, steps

    assert {_compile._name(f) for f in (steps.onset, steps.locate, cycles._record)} <= (
        _compile._quick
    )

    class Module:  # what the executable's key reads of an exported trace
        mlir_module_serialized = b"module"

    leaves = [np.zeros(3)]
    quick_file = _compile._executable_file(Module, leaves, _compile._options(steps.onset))
    assert quick_file != _compile._executable_file(Module, leaves, _compile._OWN_KEY)
    model = ss.get_model("langevin")(**WHITE, tau=0.1)

    def runs():
        euler = ss.simulate(model, 100, 0.02, 20.0, seed=4, solver="euler")
        exact = ss.simulate(model, 100, 0.3, 20.0, seed=4)
        series = ss.simulate_cycles(model, 1, 0.05, 30.0, seed=4)
        return [
            *(np.stack([e.slip_time, e.stick_time, e.slip_distance]) for e in (euler, exact)),
            *series.trajectory(0)[:2],
        ]

    quick = runs()
    _compile.clear_caches()
    monkeypatch.setattr(_compile, "_quick", set())
    optimised = runs()  # (compiled, or loaded from the entries under the default key)
    _compile.clear_caches()  # (none of the optimised ones stays in memory for later tests)
    for a, b in zip(quick, optimised, strict=True):
        np.testing.assert_array_equal(a, b)


def _run_logged(cache_dir, dt):
    """`SCRIPT` in a new process: (its output, its stderr)."""
    env = dict(os.environ, STICKSLIP_CACHE_DIR=str(cache_dir))
    done = subprocess.run([sys.executable, "-c", SCRIPT, str(dt)], env=env, capture_output=True,
                          text=True, timeout=600)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1]), done.stderr


def _damage(cache_dir) -> int:
    """Change bytes inside every entry of the cache (sizes kept), and swap two entries'
    contents; returns how many entries there were."""
    entries = sorted(cache_dir.glob("stickslip-exported/*.bin"))
    entries += sorted(_compile.executable_dir(cache_dir).glob("*.bin"))
    for k, file in enumerate(entries[2:]):
        data = bytearray(file.read_bytes())
        for at in (len(data) // 3, len(data) // 2 + k, len(data) - 1):
            data[at] ^= 0x5A
        file.write_bytes(bytes(data))
    a, b = entries[0].read_bytes(), entries[1].read_bytes()
    entries[0].write_bytes(b)
    entries[1].write_bytes(a)
    return len(entries)


@pytest.mark.slow  # three new processes compiling (~10-20 s); tests/test_fuzz.py damages
# the entries of a small program in the default tier
def test_a_damaged_cache_is_rebuilt_with_the_same_numbers(tmp_path):
    """Bytes changed in every trace and executable on disk, and two entries swapped: the
    next process neither crashes nor uses them. It says so once, makes them again, and
    gets the clean cache's numbers to the bit; the process after it loads everything."""
    clean, _ = _run_logged(tmp_path, 0.1)
    n = _damage(tmp_path)
    assert n >= 3
    damaged, stderr = _run_logged(tmp_path, 0.1)
    assert damaged["slip_time"] == clean["slip_time"]
    assert stderr.count("damaged entries of the compiled-code cache") == 1, stderr
    assert damaged["info"]["compiles"] >= clean["info"]["compiles"] - 1
    again, stderr = _run_logged(tmp_path, 0.1)
    assert again["info"]["compiles"] == 0 and "damaged" not in stderr
    assert again["slip_time"] == clean["slip_time"]


@pytest.fixture
def own_cache(tmp_path):
    """JAX's cache directory (and so stickslip's entries) in `tmp_path` for the test."""
    before = _compile.jax.config.jax_compilation_cache_dir
    _compile.jax.config.update("jax_compilation_cache_dir", str(tmp_path))
    yield tmp_path
    _compile.jax.config.update("jax_compilation_cache_dir", before)


def _tiny_call():
    """A small program, kept on disk; a new function object each time, so that only the
    disk can give its executable (as to a new process)."""
    import jax.numpy as jnp

    f = _compile.eqx.filter_jit(lambda x: jnp.sin(x) * 1.25)
    return float(_compile.call(f, jnp.linspace(0.0, 1.0, 64), paths=64).sum())


def test_entries_others_may_write_are_not_loaded(own_cache, monkeypatch):
    """An executable is code: an entry that others may write (or another user's) is not
    loaded; the run compiles, says so once and keeps its own copy, this user's only."""
    first = _tiny_call()
    (entry,) = _compile.executable_dir(own_cache).glob("*.bin")
    entry.chmod(0o666)
    monkeypatch.setattr(_compile, "_reported", set())
    before = dict(_compile.stats)
    with pytest.warns(RuntimeWarning, match="belong to another user or others may write them"):
        assert _tiny_call() == first
    assert _compile.stats["compiles"] == before["compiles"] + 1
    assert _compile.stats["executables_loaded"] == before["executables_loaded"]
    assert entry.stat().st_mode & 0o777 == 0o600  # made again, this user's only
    assert _tiny_call() == first
    assert _compile.stats["executables_loaded"] == before["executables_loaded"] + 1


@pytest.mark.skipif(os.getuid() != 0, reason="only root can give a folder away")
def test_a_cache_folder_of_another_user_is_not_used(tmp_path):
    from stickslip import _cache

    other = tmp_path / "other"
    other.mkdir(mode=0o755)
    os.chown(other, 12345, 12345)
    assert "belongs to another user" in _cache.prepare(other)
    shared = tmp_path / "shared"  # a folder everyone may write, as /tmp: left as it is
    shared.mkdir()
    shared.chmod(0o1777)
    assert "others may write it" in _cache.prepare(shared, tighten=True)
    assert shared.stat().st_mode & 0o7777 == 0o1777


def test_a_new_cache_folder_is_this_users_only(tmp_path, monkeypatch):
    """The cache folder is made readable and writable by its user only; stickslip's own
    default folder, where others may write it, is closed to them; a folder the user named
    is never changed (it is refused, with the command that closes it)."""
    from stickslip import _cache

    made = tmp_path / "a" / "jax"
    assert _cache.prepare(made) is None and made.stat().st_mode & 0o777 == 0o700
    open_one = tmp_path / "open"
    open_one.mkdir()
    open_one.chmod(0o777)
    assert "chmod go-w" in _cache.prepare(open_one)  # named by the user: left as it is
    assert open_one.stat().st_mode & 0o777 == 0o777
    assert _cache.prepare(open_one, tighten=True) is None  # stickslip's own default folder
    assert open_one.stat().st_mode & 0o022 == 0
