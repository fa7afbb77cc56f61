"""Compiled code of the simulator: ahead-of-time compilation (compile time is measured apart
from run time), a bounded in-process cache, shape-polymorphic traces and executables kept on
disk.

`call(fn, *args, paths=n)` traces `fn` once with the path axis (the last axis of every
array argument whose last dimension is `n`) left symbolic (`jax.export`), then compiles
that one trace for each buffer size it meets. Traces and executables are written to the
cache directory (the one of JAX's persistent compilation cache, see `stickslip._jax`), so a
new process neither traces nor compiles. A trace that cannot be exported (say a user model
whose code needs concrete sizes) falls back to one trace per shape, in memory only.

Traces are keyed by the sources of stickslip and of the packages of every class in the
static arguments, the versions of jax, jaxlib, diffrax and equinox, the device, the function
and the static arguments (arguments whose text form is not reproducible, objects printed by
address, keep theirs in memory only). Executables are keyed by the traced module itself, the
shapes, the versions and the device.

Every entry on disk starts with a line holding a digest of its name and its contents
(`_pack`), checked before the entry is used: a damaged entry (bytes changed, cut short, or
moved under another key) is removed, reported once per process and made again, with the
numbers of a clean cache. Entries are read only from files of this user that no one else
can write (`_cache.trusted`): an executable is code, and loading one runs it.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import functools
import hashlib
import importlib.metadata
import inspect
import os
import pathlib
import re
import sys
import threading
import time
import warnings

import equinox as eqx
import numpy as np

from . import _cpu
from ._cache import trusted as _trusted
from ._jax import jax

MAX_ENTRIES = 64  # compiled executables kept in memory (least recently used dropped)

_cache: collections.OrderedDict = collections.OrderedDict()  # executables, LRU
_entries: collections.OrderedDict = collections.OrderedDict()  # `memoized`, LRU
_entries_lock = threading.RLock()
_exported: dict = {}  # shape-polymorphic traces (few: one per function and model structure)
_absent: dict = {}  # (Fixed key, shapes) -> when its executable was last found missing
ABSENT_SECONDS = 5.0
_trace_files: dict = {}  # their disk entries' paths (`_trace_file`)
stats = {
    "traces": 0, "compiles": 0, "exported_loaded": 0, "executables_loaded": 0, "shipped_loaded": 0,
}  # fmt: skip
SHIPPED = pathlib.Path(__file__).parent / "_data" / "traces"  # traces made by `_ship`
# Seconds spent (since the process started) tracing, compiling, and loading from disk; and the
# executables handed to the background compiler (`_background`) instead of compiled here.
seconds = {"trace_seconds": 0.0, "compile_seconds": 0.0, "load_seconds": 0.0}
requests = [0]
_cache_hits = [0]  # hits of JAX's own persistent cache (see `_compile`)
_resident: collections.OrderedDict = collections.OrderedDict()  # `on_device`, LRU
_RESIDENT_ENTRIES = 512
_RESIDENT_BYTES = 1 << 16
_keys: dict = {}  # `Fixed` keys, one object per distinct key (`_interned`)


def _count_hits(event: str, **kwargs) -> None:
    if event == "/jax/compilation_cache/cache_hits":
        _cache_hits[0] += 1


jax.monitoring.register_event_listener(_count_hits)


class Timer:
    """Accumulates the seconds spent tracing and compiling during one run."""

    def __init__(self):
        self.compile_seconds = 0.0


def clear_caches() -> None:
    """Drop the simulator's compiled executables and traces held in memory, and JAX's own
    caches (the disk entries stay: the next run loads instead of compiling)."""
    _cache.clear()
    _entries.clear()
    _exported.clear()
    _absent.clear()
    _trace_files.clear()
    _resident.clear()
    _keys.clear()
    _rent.clear()
    _compiled_seconds.clear()
    jax.clear_caches()


def memoized(key, make):
    """`make()`, kept in memory under the hashable `key` (least recently used dropped past
    `MAX_ENTRIES`): for callers that know a cheaper key for an executable than `executable`
    computes from the arguments (~0.3 ms a call for the simulator's model and solver)."""
    with _entries_lock:  # threads of one process (the refinement's, a threaded Dask worker)
        entry = _entries.get(key)
        if entry is None:
            entry = _entries[key] = make()
            while len(_entries) > MAX_ENTRIES:
                _entries.popitem(last=False)
        else:
            _entries.move_to_end(key)
        return entry


def cache_info() -> dict:
    """Counts since the process started: `traces` (functions traced), `compiles` (XLA
    compilations), `exported_loaded` / `executables_loaded` (traces and executables read
    from disk), `shipped_loaded` (traces shipped with the package, `_ship`), `background`
    (executables left to the background compiler, `policy()`), `entries` (executables held
    in memory, at most `MAX_ENTRIES`); and the seconds spent tracing, compiling and loading
    (`trace_seconds`, `compile_seconds`, `load_seconds`)."""
    out = dict(stats, background=requests[0], entries=len(_cache), max_entries=MAX_ENTRIES)
    return out | {k: round(v, 3) for k, v in seconds.items()}


def cold_note() -> str | None:
    """One line for a command's user when the compiled-code cache is empty (a first run on
    this machine compiles the simulator's programs), else `None`."""
    where = jax.config.jax_compilation_cache_dir
    if not where:
        return None
    folder = executable_dir(where)
    if folder.is_dir() and any(folder.glob("*.bin")):
        return None
    return (
        f"stickslip: first run with an empty compiled-code cache ({where}): compiling the "
        "simulator, about 5-15 s on 2 cores per model; later runs load it in about a second"
    )


POLICIES = ("background", "reuse", "eager")
# How far another size stands in for the one a call wants (not under "eager"): a compiled
# one up to this many times larger (padded), or one down to 1 / STAND_IN of it (the
# caller then makes more calls: chunks, batches); 0: only what the call wants (and, in the
# simulator's shrinking buffers, the larger buffer already running).
STAND_IN = 8


def policy() -> str:
    """How the simulator meets a buffer size it has no executable for (`STICKSLIP_COMPILE`):

    - `"background"` (default): where an executable of another size of the same program is
      at hand (in memory or on disk), run on it (a larger one padded, a smaller one in more
      chunks: the same numbers, keyed by path and step) and have the exact size compiled by
      a background process (`_background`) for later runs; compile here only what nothing
      can stand in for. A first run on a fresh machine then compiles a handful of programs
      instead of one per buffer size, and a later run of another size none.
    - `"reuse"`: the same, without the background process (later runs stay on the larger
      sizes until something compiles the exact ones: for test suites and short-lived jobs).
    - `"eager"`: compile every buffer size where it is first needed (the fastest run once
      everything is compiled; each size costs ~2 s to compile on 2 cores).
    Without a cache directory, `"background"` works as `"reuse"`."""
    value = os.environ.get("STICKSLIP_COMPILE", "background").strip().lower() or "background"
    if value not in POLICIES:
        from ._errors import ParameterError

        raise ParameterError(
            "environment", "STICKSLIP_COMPILE", f"must be one of {', '.join(POLICIES)}", value
        )
    return value


def call(fn, *args, timer: Timer | None = None, paths: int | None = None):
    """Call `fn` (an `eqx.filter_jit` function) through a compiled executable cached by the
    structure, shapes and dtypes of the array arguments and the value of the others.

    With `paths`, the size of the path axis, the trace is shape-polymorphic in that axis
    and kept on disk (see the module docs); `paths=0`: kept on disk, no path axis."""
    compiled, flat, leaves = executable(fn, *args, timer=timer, paths=paths)
    return compiled(*leaves) if flat else compiled(*args)


def executable(fn, *args, timer: Timer | None = None, paths: int | None = None, build: bool = True):
    """`(compiled, flat, leaves)`: the executable `call` would run on `args`; it takes the
    array leaves `leaves` if `flat`, else `args` themselves. With `build=False`, only an
    executable already in memory or on disk, else `None`."""
    dynamic, static = eqx.partition(args, eqx.is_array)
    leaves, treedef = jax.tree_util.tree_flatten(dynamic)
    key = (fn, treedef, tuple((x.shape, str(x.dtype)) for x in leaves), _static_key(static))
    entry = _cache.get(key)
    if entry is None:
        start = time.perf_counter()
        entry = _compile(fn, args, leaves, treedef, static, paths, build)
        if timer is not None:
            timer.compile_seconds += time.perf_counter() - start
        if entry is None:
            return None  # (`build=False`)
        _cache[key] = entry
        while len(_cache) > MAX_ENTRIES:
            _cache.popitem(last=False)
    else:
        _cache.move_to_end(key)
    return entry + (leaves,)


def on_device(x):
    """`x` as a device array if it is a NumPy array (kept by content, so that the runs of one
    model reuse one copy: a compiled call converts every NumPy argument again, ~4 us each,
    and the simulator's model and solver are ~30 of them), else `x`."""
    if not isinstance(x, np.ndarray):
        return x
    if x.nbytes > _RESIDENT_BYTES:  # (not kept: its key would be a copy as large)
        return jax.device_put(x)
    key = (x.dtype.str, x.shape, x.tobytes())
    with _entries_lock:
        out = _resident.get(key)
        if out is None:
            out = _resident[key] = jax.device_put(x)
            while len(_resident) > _RESIDENT_ENTRIES:
                _resident.popitem(last=False)
        else:
            _resident.move_to_end(key)
        return out


def _static_key(static):
    """The non-array part of a call's arguments as a dictionary key: its tree structure and
    leaves, as `eqx.filter_jit` keys it (the part itself may not be hashable: a dict of
    arrays leaves a dict of `None`s)."""
    leaves, treedef = jax.tree_util.tree_flatten(static)
    return treedef, tuple(leaves)


class _Key:
    """A key hashed once (hashing the model's static parts took ~0.1 ms a look-up)."""

    __slots__ = ("key", "hash")

    def __init__(self, key):
        self.key, self.hash = key, hash(key)

    def __hash__(self):
        return self.hash

    def __eq__(self, other):
        return self is other or (
            isinstance(other, _Key) and self.hash == other.hash and self.key == other.key
        )


def _interned(key) -> _Key:
    """One `_Key` for equal keys: the `memoized` look-ups of later runs compare it by
    identity."""
    k = _Key(key)
    with _entries_lock:
        if len(_keys) > 4 * MAX_ENTRIES:
            _keys.clear()
        return _keys.setdefault(k, k)


class Fixed:
    """`call(fn, *fixed, *rest)` for calls that share their leading arguments `fixed` (a
    run's model and solver): those are partitioned and flattened once (their arrays put on
    the device once), and the executable of each shape of `rest` (arrays only) is kept, so a
    call costs a dictionary look-up (the generic `call` re-partitions every argument, about
    0.7 ms a call for the simulator)."""

    def __init__(self, fn, *fixed, timer: Timer | None = None):
        self.fn, self.fixed, self.timer = fn, fixed, timer
        dynamic, static = eqx.partition(fixed, eqx.is_array)
        leaves, treedef = jax.tree_util.tree_flatten(dynamic)
        # What the executable depends on in `fixed` (as `executable`'s key): the entries are
        # shared with every `Fixed` of the same structure (the runs of one configuration).
        shapes = tuple((x.shape, x.dtype) for x in leaves)
        self.key = _interned((fn, treedef, shapes, _static_key(static)))
        self.leaves = [on_device(x) for x in leaves]
        self.entries: dict = {}
        self.traced: set = set()  # the shapes `trace` found traced (or traced)

    def __call__(self, *rest, paths: int | None = None):
        key = (paths,) + tuple((x.shape, x.dtype) for x in rest)
        entry = self.entries.get(key)
        if entry is None:

            def make():
                compiled, flat, _ = executable(
                    self.fn, *self.fixed, *rest, timer=self.timer, paths=paths
                )
                return compiled, flat

            entry = self.entries[key] = memoized((Fixed, self.key) + key, make)
        compiled, flat = entry
        return compiled(*self.leaves, *rest) if flat else compiled(*self.fixed, *rest)

    def trace(self, *rest, paths: int) -> None:
        """Trace the program for these shapes now (memory, disk, or a new trace), compiling
        nothing: a caller that wants other work (a thread's) to start after the tracing,
        which holds Python's lock, and overlap the compilation, which does not. Once per
        shape for this object (a model with memory steps its cycles one round at a time,
        and asked again every round: the look-up's partition took ~1 ms)."""
        key = (paths,) + tuple((x.shape, x.dtype) for x in rest)
        if key in self.traced or key in self.entries:
            return
        dynamic, static = eqx.partition((*self.fixed, *rest), eqx.is_array)
        leaves, treedef = jax.tree_util.tree_flatten(dynamic)
        _export(self.fn, leaves, treedef, static, paths)
        self.traced.add(key)

    def ready(self, *rest, paths: int, build: bool = False) -> bool:
        """Whether a call on these shapes (`rest`: arrays, or stand-ins of their shapes) runs
        without tracing or compiling: its executable is in memory or on disk (then loaded).
        An executable found missing is not looked for again for `ABSENT_SECONDS` (a look on
        disk costs a few milliseconds; another process may write it meanwhile). With
        `build`, one that is missing is compiled (traced if need be), and the answer is True."""
        key = (paths,) + tuple((x.shape, x.dtype) for x in rest)
        if key in self.entries:
            return True
        entry = remembered((Fixed, self.key) + key)
        if entry is None:
            seen = _absent.get((self.key,) + key)
            if not build and seen is not None and time.monotonic() - seen < ABSENT_SECONDS:
                return False
            found = executable(self.fn, *self.fixed, *rest, timer=self.timer, paths=paths,
                               build=build)  # fmt: skip
            if found is None:
                if len(_absent) > 4 * MAX_ENTRIES:
                    _absent.clear()
                _absent[(self.key,) + key] = time.monotonic()
                return False
            entry = memoized((Fixed, self.key) + key, lambda: found[:2])
        self.entries[key] = entry
        return True


# -- rent or compile ----------------------------------------------------------------------------
# A run that has no executable for the size it wants goes on with a larger one (`policy`):
# the ski-rental rule decides when to compile the wanted one after all. Each call made on a
# larger size than wanted adds the time it wasted (its seconds times the fraction of the
# buffer it did not need) to the program's rent (one rent for all sizes of a program: as
# paths finish the wanted size moves on, and a rent per size spread a long run's 2.5 s of
# waste over six sizes, none of which came due); once the rent passes what a compilation
# costs, the size wanted then is compiled and one compilation's cost comes off the rent (at
# most about twice the best cost in hindsight). A long run soon compiles the sizes it
# needs; a short first run compiles none.
COMPILE_SECONDS = 2.0  # a compilation of the simulator's loops on 2 cores, until measured
_rent: dict = {}
_rent_lock = threading.Lock()


_compiled_seconds: dict = {}  # function -> (seconds, compilations) in this process


def compile_estimate(fn=None) -> float:
    """Seconds a compilation of `fn` takes here: the mean of this process's compilations of
    it, else `COMPILE_SECONDS`."""
    total, count = _compiled_seconds.get(fn, (0.0, 0))
    return total / count if count else COMPILE_SECONDS


def _key_fn(key):
    """The function of a rent key: `(Fixed key, size)` or `(fn, ...)`."""
    head = key[0] if isinstance(key, tuple) and key else key
    if isinstance(head, _Key):
        head = head.key[0]
    return head


def rent(key, wasted: float) -> bool:
    """Add `wasted` seconds to the rent of the program `key` (a tuple whose first item is
    its function or a `Fixed` key); whether to compile it now."""
    with _rent_lock:
        total = _rent[key] = _rent.get(key, 0.0) + max(0.0, wasted)
    return total >= compile_estimate(_key_fn(key))


def due(key) -> bool:
    """Whether the rent of the program `key` has passed a compilation's cost."""
    return _rent.get(key, 0.0) >= compile_estimate(_key_fn(key))


def pay(key) -> None:
    """A compilation of the program `key` was decided: its cost comes off the rent."""
    with _rent_lock:
        _rent[key] = max(0.0, _rent.get(key, 0.0) - compile_estimate(_key_fn(key)))


def _count_compile(fn, elapsed: float) -> None:
    with _rent_lock:  # (threads compile at once: the study's theory, the refinement's)
        seconds["compile_seconds"] += elapsed
        total, count = _compiled_seconds.get(fn, (0.0, 0))
        _compiled_seconds[fn] = (total + elapsed, count + 1)


def remembered(key):
    """The entry `memoized` keeps under `key`, or `None` (nothing is made)."""
    with _entries_lock:
        entry = _entries.get(key)
        if entry is not None:
            _entries.move_to_end(key)
        return entry


def disk_entry(fn, args) -> bool:
    """Whether the trace of `fn` on these arguments can have a disk entry (a cache
    directory, and static arguments with a reproducible text form)."""
    dynamic, static = eqx.partition(args, eqx.is_array)
    leaves, treedef = jax.tree_util.tree_flatten(dynamic)
    shapes = tuple((tuple(x.shape), str(x.dtype)) for x in leaves)
    return _trace_file(fn, treedef, shapes, static) is not None


def _compile(fn, args, leaves, treedef, static, paths, build=True):
    """`(executable, takes_flat_leaves)` for one shape; `None` where `build` is false and
    it would have to be traced or compiled."""
    if paths is not None:
        exported = _export(fn, leaves, treedef, static, paths, build)
        if exported is None and not build:
            return None
        if exported is not None:
            file = _executable_file(exported, leaves, _options(fn))
            compiled = _load_executable(file, exported, leaves)
            if compiled is None and not build:
                return None
            if compiled is None:
                # Another process may be compiling the same executable (test workers, a
                # sweep's processes, all starting cold): wait for it and load its copy.
                with _exclusive(file):
                    compiled = _load_executable(file, exported, leaves)
                    if compiled is None:
                        stats["compiles"] += 1
                        hits = _cache_hits[0]
                        start = time.perf_counter()
                        compiled = _fresh(jax.jit(exported.call).lower(*leaves), _options(fn))
                        _count_compile(fn, time.perf_counter() - start)
                        # An executable that JAX itself loaded from its persistent cache
                        # cannot be serialised again (XLA's CPU runtime then loses its
                        # functions: "Function ... not found" when the copy runs); only
                        # freshly compiled ones are written.
                        if _cache_hits[0] == hits:
                            _save_executable(file, compiled, exported, leaves)
                        return compiled, True
            stats["executables_loaded"] += 1
            return compiled, True
    if not build:
        return None
    stats["traces"] += 1
    stats["compiles"] += 1
    start = time.perf_counter()
    jitted = fn if hasattr(fn, "lower") else eqx.filter_jit(fn)
    compiled = jitted.lower(*args).compile(compiler_options=QUICK if _is_quick(fn) else None)
    _count_compile(fn, time.perf_counter() - start)
    return compiled, False


# An XLA option that leaves the code as it is (fast math is off by default) but changes the key
# of JAX's persistent cache: see `_fresh`.
_OWN_KEY = {"xla_cpu_enable_fast_math": False}

# XLA's CPU backend writes each fused kernel with its fusion emitters (its default) or with its
# older elemental emitters. The older ones emit the same arithmetic in fewer, plainer LLVM
# modules: a third less compile time (the stepping loop 15-17 s against 10-12 s for ten buffer
# sizes, the stick locator 0.85 against 0.5 s, the same ensembles to the last bit), but the
# stepping loop ran ~12 % slower and the refinement ~35 % (10^5 paths of the public set at
# dt = 0.8). The programs that run briefly (once per chunk or per batch of sticks: the onset,
# the locator, the tables, the cycles' recording) are compiled with them (`quick`); the hot
# loops and the estimator's kernels (whose densities moved in the last bits, and ran slower)
# are not.
QUICK = {"xla_cpu_use_fusion_emitters": False}
_quick: set = set()  # names (`_name`) of the functions compiled with `QUICK`


def quick(fn):
    """Compile `fn` (a function of the package's) with `QUICK`: for programs whose run time
    is small beside their compile time. Returns `fn`."""
    _quick.add(_name(fn))
    return fn


def _is_quick(fn) -> bool:
    return _name(fn) in _quick


def _options(fn) -> dict:
    """The XLA compile options of `fn`'s executables on disk (see `QUICK`, `_fresh`)."""
    return {**_OWN_KEY, **QUICK} if _is_quick(fn) else _OWN_KEY


def _fresh(lowered, options=_OWN_KEY):
    """Compile `lowered` into an executable this module can keep on disk. One that JAX
    loaded from its own persistent cache cannot be serialised again (see `_compile`), and
    an entry there without one here would be loaded from JAX's cache by every new process
    (about 0.25 s each). So this compile neither reads JAX's cache (its options give it a
    key of its own) nor writes it (the executable is kept here instead)."""
    with _fresh_lock:  # (threads compile at once: the first sets the limit, the last resets it)
        if not _fresh_open:
            _fresh_saved[:] = [jax.config.jax_persistent_cache_min_compile_time_secs]
            jax.config.update("jax_persistent_cache_min_compile_time_secs", float("inf"))
        _fresh_open.append(None)
    try:
        return lowered.compile(compiler_options=options)
    finally:
        with _fresh_lock:
            _fresh_open.pop()
            if not _fresh_open:
                jax.config.update("jax_persistent_cache_min_compile_time_secs", _fresh_saved[0])


_fresh_lock = threading.Lock()
_fresh_open: list = []  # the compilations under way in `_fresh`
_fresh_saved: list = []  # the limit they replaced


def _poly_specs(leaves, paths):
    """Shape specs of the leaves with their path axis symbolic."""
    from jax import export

    (n,) = export.symbolic_shape("n")
    specs = []
    for x in leaves:
        shape = tuple(x.shape)
        if paths and shape and shape[-1] == paths:
            shape = shape[:-1] + (n,)
        specs.append(jax.ShapeDtypeStruct(shape, x.dtype))
    return specs


def _export(fn, leaves, treedef, static, paths, build=True):
    """The shape-polymorphic trace of `fn` for these arguments (memory, then disk, then a
    new trace unless `build` is false); `None` where it cannot be exported."""
    specs = _poly_specs(leaves, paths)
    poly_shapes = tuple((str(s.shape), str(s.dtype)) for s in specs)
    key = (fn, treedef, poly_shapes, _static_key(static))
    if key in _exported:
        return _exported[key]
    file = _trace_file(fn, treedef, poly_shapes, static)
    exported = _load_exported(file)
    if exported is None and file is not None:
        # Traces of the built-in models ship with the package (`_ship`): a first run on a
        # new machine loads them instead of tracing (valid for the same sources and
        # library versions only, which the key says).
        exported = _load_exported(SHIPPED / file.name)
        if exported is not None:
            stats["shipped_loaded"] += 1
            _save(file, lambda: (SHIPPED / file.name).read_bytes(), packed=True)
    if exported is None:
        if not build:
            return None
        with _exclusive(file):
            # Another process may be tracing it (see `_compile`): load its copy after it.
            exported = _load_exported(file)
            if exported is None:
                start = time.perf_counter()
                exported = _trace(fn, specs, treedef, static, file)
                seconds["trace_seconds"] += time.perf_counter() - start
            else:
                stats["exported_loaded"] += 1
    else:
        stats["exported_loaded"] += 1
    _exported[key] = exported
    return exported


def _trace(fn, specs, treedef, static, file):
    """A new shape-polymorphic trace of `fn`, kept in `file`; `None` where it cannot be
    exported."""
    from jax import export

    def flat_fn(*flat):
        dynamic = jax.tree_util.tree_unflatten(treedef, flat)
        return fn(*eqx.combine(dynamic, static))

    try:
        with _without_source_locations():
            exported = export.export(jax.jit(flat_fn))(*specs)
    except Exception as err:  # not shape-polymorphic: one trace per shape instead
        warnings.warn(
            f"stickslip: {_name(fn)} cannot be traced once for every buffer size "
            f"({type(err).__name__}); tracing it per size",
            RuntimeWarning,
            stacklevel=5,
        )
        return None
    stats["traces"] += 1
    _save(file, lambda: exported.serialize())
    return exported


def _without_source_locations():
    """Trace with no source lines in the module's locations. The executables on disk are
    keyed by the traced module, and its locations hold the Python frames that led to each
    operation: the caller's own (a test, `select_method`, a study) among them. The same
    program reached from two places (say two models whose static fields differ where the
    loop does not look, as `langevin`'s `eta0`) was then two modules and two compilations
    of ~1.5 s per buffer size. Locations only serve profiles and error messages, which the
    loop's names still give. (A JAX-internal switch, thread-local; if it is gone, traces
    keep their locations and only the sharing is lost.)"""
    try:
        from jax._src import config

        return config.traceback_in_locations_limit(0)
    except (ImportError, AttributeError, TypeError):  # pragma: no cover - another JAX
        return contextlib.nullcontext()


@contextlib.contextmanager
def _exclusive(file):
    """Hold an exclusive lock on `file`'s lock file across processes (POSIX `flock`; the
    lock goes with the process if it dies). Without a lock (no cache directory, a
    read-only one, no `fcntl`), go on unlocked: the entries are written atomically anyway."""
    handle = None
    if file is not None:
        try:
            import fcntl

            file.parent.mkdir(parents=True, exist_ok=True)
            handle = open(file.with_suffix(".lock"), "a")  # noqa: SIM115
            fcntl.flock(handle, fcntl.LOCK_EX)
        except (ImportError, OSError):
            if handle is not None:
                handle.close()
            handle = None
    try:
        yield
    finally:
        if handle is not None:
            handle.close()  # releases the lock


# -- disk entries --------------------------------------------------------------------------------
def _name(fn) -> str:
    inner = getattr(fn, "__wrapped__", fn)
    return f"{getattr(inner, '__module__', '?')}.{getattr(inner, '__qualname__', repr(inner))}"


_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


def _classes(tree, found: set) -> set:
    """Every class of the dataclass / equinox nodes in `tree` (recursively)."""
    if dataclasses.is_dataclass(tree) and not isinstance(tree, type):
        found.add(type(tree))
        for f in dataclasses.fields(tree):
            _classes(getattr(tree, f.name, None), found)
    elif isinstance(tree, (tuple, list)):
        for item in tree:
            _classes(item, found)
    elif isinstance(tree, dict):
        for item in tree.values():
            _classes(item, found)
    return found


@functools.cache
def _source_hash(file: str) -> str:
    try:
        return hashlib.sha256(pathlib.Path(file).read_bytes()).hexdigest()
    except OSError:
        return "?"


@functools.cache
def _package_hash(top: str) -> str:
    """The sources of a model's whole top-level package (or module): a trace depends on every
    helper its classes call, not only on the file that defines them."""
    module = sys.modules.get(top)
    try:
        file = inspect.getsourcefile(module) if module else None
    except TypeError:
        file = None
    if file is None:
        return f"{top}:?"
    path = pathlib.Path(file)
    files = sorted(path.parent.rglob("*.py")) if path.name == "__init__.py" else [path]
    return top + ":" + ",".join(_source_hash(str(f)) for f in files)


@functools.cache
def _environment(sources: bool = True) -> str:
    """Versions of the libraries and the device (and of stickslip's own sources)."""
    parts = []
    for dist in ("jax", "jaxlib", "diffrax", "equinox"):
        try:
            parts.append(f"{dist}={importlib.metadata.version(dist)}")
        except importlib.metadata.PackageNotFoundError:
            parts.append(f"{dist}=?")
    try:
        device = jax.devices()[0]
        parts.append(f"{device.platform}:{device.device_kind}:{device.client.platform_version}")
    except Exception:
        parts.append("device=?")
    if not sources:
        return "\n".join(parts)
    root = pathlib.Path(__file__).parent
    for file in sorted(root.rglob("*.py")):
        name = file.relative_to(root)
        if name.parts[0] not in _UNTRACED:
            parts.append(f"{name}:{_source_hash(str(file))}")
    return "\n".join(parts)


# Parts of the package that no traced function (the simulator's, the estimator's kernels)
# imports: an edit there keeps the traces on disk; everything else counts.
_UNTRACED = (
    "study", "cli", "_inference", "_extract", "selection.py", "stability.py",
    "__init__.py", "extract.py", "units.py", "_background.py", "_output.py", "_ship.py",
    "_cpu.py", "_cache.py", "_model_check.py", "quantities.py", "trace_kinds.py", "_keyed.py",
    "_trace_kind.py", "_registry.py",
)  # fmt: skip


def _trace_file(fn, treedef, shapes, static) -> pathlib.Path | None:
    """Where the disk entry of a trace lives; `None` if it has none (no cache
    directory, or arguments without a reproducible text form)."""
    where = jax.config.jax_compilation_cache_dir
    if not where:
        return None
    key = (where, fn, treedef, shapes, _static_key(static))
    if key in _trace_files:  # (a probe for a size at hand asks again: the text took ~2 ms)
        return _trace_files[key]
    _trace_files[key] = file = _trace_path(where, fn, treedef, shapes, static)
    return file


def _trace_path(where, fn, treedef, shapes, static) -> pathlib.Path | None:
    """`_trace_file`, made."""
    static_text = repr(static)
    if _ADDRESS.search(static_text):
        return None
    classes = sorted(_classes(static, set()), key=lambda c: (c.__module__, c.__qualname__))
    sources = [f"{c.__module__}.{c.__qualname__}" for c in classes]
    # (stickslip's own sources are in `_environment`, less the parts no trace imports)
    tops = {c.__module__.split(".")[0] for c in classes} - {__name__.split(".")[0]}
    sources += [_package_hash(top) for top in sorted(tops)]
    text = "\n".join([_environment(), _name(fn), str(treedef), repr(shapes), static_text, *sources])
    digest = hashlib.sha256(text.encode()).hexdigest()[:40]
    return pathlib.Path(where) / "stickslip-exported" / f"{digest}.bin"


def _executable_file(exported, leaves, options=_OWN_KEY) -> pathlib.Path | None:
    """The disk entry of the executable of `exported` for these concrete shapes and compile
    `options`: keyed by the traced module itself (so a source change that leaves the trace
    alone keeps it)."""
    where = jax.config.jax_compilation_cache_dir
    if not where:
        return None
    digest = hashlib.sha256(ENTRY_FORMAT + b"\n" + _environment(sources=False).encode())
    # XLA's options change the code it emits (`_jax`'s vector width, or the user's own).
    digest.update(os.environ.get("XLA_FLAGS", "").encode())
    if options != _OWN_KEY:
        digest.update(repr(sorted(options.items())).encode())
    digest.update(bytes(exported.mlir_module_serialized))
    digest.update(repr([(tuple(x.shape), str(x.dtype)) for x in leaves]).encode())
    return executable_dir(where) / f"{digest.hexdigest()[:40]}.bin"


def executable_dir(where) -> pathlib.Path:
    """The folder of the executables under the cache directory `where`: one per CPU kind
    (`_cpu.KIND`). XLA emits code for the CPU it compiles on, and loads an executable
    made for another with only a logged error (it may then stop on an illegal instruction),
    so the nodes of a cluster sharing one cache directory each find their own kind's."""
    return pathlib.Path(where) / "stickslip-executable" / _cpu.KIND


ENTRY_FORMAT = b"stickslip-entry-2"  # the first line's tag (`_pack`); in the executables' key too


def _pack(file: pathlib.Path, payload: bytes) -> bytes:
    """An entry's bytes on disk: one line `ENTRY_FORMAT digest`, then `payload`. The digest
    (SHA-256) covers the entry's name as well as its contents, so an entry copied or moved
    under another key fails the check like a damaged one."""
    digest = hashlib.sha256(file.stem.encode() + b"\n" + payload).hexdigest().encode()
    return ENTRY_FORMAT + b" " + digest + b"\n" + payload


def _unpack(file: pathlib.Path, data: bytes) -> bytes | None:
    """The payload of the entry `data` read from `file`, or `None` if it fails the check."""
    head, sep, payload = data.partition(b"\n")
    tag, _, digest = head.partition(b" ")
    if not sep or tag != ENTRY_FORMAT:
        return None
    expected = hashlib.sha256(file.stem.encode() + b"\n" + payload).hexdigest().encode()
    return payload if digest == expected else None


_reported: set = set()  # the cache directories whose damaged entries were reported


def _report(file: pathlib.Path, what: str) -> None:
    """One warning per process and cache directory for entries that were not used."""
    ours = ("stickslip-exported", "stickslip-executable")
    where = next((p.parent for p in file.parents if p.name in ours), file.parent)
    key = (str(where), what)
    if key in _reported:
        return
    _reported.add(key)
    if what == "damaged":
        text = (f"stickslip: damaged entries of the compiled-code cache in {where} were "
                "removed and are made again (this run compiles them)")  # fmt: skip
    else:
        text = (f"stickslip: entries of the compiled-code cache in {where} belong to another "
                "user or others may write them: not loaded (this run compiles them; set "
                "STICKSLIP_CACHE_DIR to a folder of your own)")  # fmt: skip
    warnings.warn(text, RuntimeWarning, stacklevel=2)


def _read_entry(file) -> bytes | None:
    """The checked payload of the entry `file`, or `None` (absent, not trusted, or damaged:
    a damaged one is removed and reported)."""
    if file is None:
        return None
    try:
        with open(file, "rb") as f:
            # (the shipped traces are part of the installed package, as its code is)
            if file.parent != SHIPPED and not _trusted(os.fstat(f.fileno())):
                _report(file, "untrusted")
                return None
            data = f.read()
    except OSError:  # absent (the usual case), or unreadable
        return None
    payload = _unpack(file, data)
    if payload is None:
        _discard(file)
    return payload


def _discard(file: pathlib.Path) -> None:
    """Remove the damaged entry `file` (it is made again) and report it; a shipped trace
    (`SHIPPED`, part of the package) is left: the trace is made in the cache instead."""
    _report(file, "damaged")
    if file.parent != SHIPPED:
        with contextlib.suppress(OSError):
            file.unlink()


def _load_exported(file):
    start = time.perf_counter()
    try:
        payload = _read_entry(file)
        if payload is None:
            return None
        from jax import export

        try:
            return export.deserialize(bytearray(payload))
        except Exception:  # checked, yet not a trace this JAX reads: make it again
            _discard(file)
            return None
    finally:
        seconds["load_seconds"] += time.perf_counter() - start


def _trees(exported, leaves):
    """The argument and result trees of `exported`'s executable called on the flat
    `leaves` (not kept on disk: they are known here)."""
    return jax.tree_util.tree_structure((tuple(leaves), {})), exported.out_tree


def _load_executable(file, exported, leaves):
    start = time.perf_counter()
    try:
        payload = _read_entry(file)
        if payload is None:
            return None
        from jax.experimental.serialize_executable import deserialize_and_load

        if b"lapack" in exported.mlir_module_serialized:  # (its calls name their targets)
            _lapack_ready()
        try:
            return deserialize_and_load(payload, *_trees(exported, leaves))
        except Exception:  # checked, yet not loadable by this runtime: compile again
            _discard(file)
            return None
    finally:
        seconds["load_seconds"] += time.perf_counter() - start


@functools.cache
def _lapack_ready() -> None:
    """Bind the LAPACK routines that compiled code calls (a linear solve: the implicit
    solvers of a model with memory). JAX binds them when it lowers such an operation; an
    executable loaded from disk lowers nothing, and its first call crashed the process
    (a segmentation fault) where nothing before had bound them. Only for a program that
    calls them: binding imports SciPy's LAPACK, ~0.25 s in a new process."""
    try:
        from jax._src.lax.linalg import initialize_lapack
    except ImportError:  # (moved in another JAX: then it binds them itself, or we learn)
        return
    initialize_lapack()


def _save_executable(file, compiled, exported, leaves) -> None:
    from jax.experimental.serialize_executable import serialize

    blob, in_tree, out_tree = serialize(compiled)
    # The trees are not kept (`_trees` makes them again), so they must be those.
    if (in_tree, out_tree) != _trees(exported, leaves):
        return
    _save(file, lambda: blob)


def _save(file, blob, packed: bool = False) -> None:
    """Write `blob()` to `file` atomically (a concurrent reader sees all of it or nothing),
    with its digest (`_pack`) unless `packed`, readable and writable by this user only."""
    if file is None:
        return
    tmp = file.with_suffix(f".{os.getpid()}.tmp")
    try:
        data = blob()
        file.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with open(fd, "wb") as f:
            f.write(data if packed else _pack(file, data))
        os.replace(tmp, file)
    except Exception:  # a read-only cache, or no serialiser: keep it in memory only
        with contextlib.suppress(OSError):
            tmp.unlink()
