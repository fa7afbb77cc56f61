"""The background compiler: executables of the simulator's programs compiled by a separate,
low-priority process, for later runs.

A first run on a fresh machine meets one buffer size after another (the survivors of a
chunk are re-packed into smaller buffers as paths finish) and the exact refinement one
capacity after another; each is an XLA compilation of ~2 s on 2 cores. Under the
`"background"` policy (`_compile.policy`) a run instead keeps going on a larger size it
already has (padded: the numbers are keyed by path and step, not by buffer) and asks for
the exact size here: `request` writes a job into the cache directory's queue, and starts
`python -m stickslip._background CACHE_DIR` unless one already runs. That process, detached
and niced, makes each queued executable through `_compile.executable`, as the run would
have (the trace from disk, or traced anew from the pickled arguments; the same options),
which keeps it on disk where the runs look for it, and exits when the queue is empty. The
run that asked does not wait for it; a later run (or a later round of a long one) loads the
executable from disk.

One worker per cache directory and CPU kind (an exclusive `flock` on the queue's
`worker.lock`, taken as it starts, before it waits for its run); a job is the pickled
function and arguments, the arrays replaced by their shapes, named by its digest and
removed once done or failed (a model whose class a new process cannot import, say one
defined in a notebook, fails there: the run then compiles it when that pays).
Nothing here can change a result.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import os
import pathlib
import subprocess
import sys

from . import _cache

NICE = 10  # the worker's niceness: a run in the foreground keeps the cores it needs
# (its session's as well where Linux groups the CPU by session: `_lower_priority`)
# The worker starts compiling once the process that started it has exited, or after this
# many seconds: a first run's remaining seconds (its stand-in simulation, its exit) are not
# slowed by a compiler beside it (measured on 2 cores, niced as it is: 10.8 s against 8.8 s
# for the first call of benchmarks/cold_start.py), and a long-lived process (a notebook, a
# sweep) gets its executables soon all the same.
PARENT_WAIT = 10.0


def queue_dir(cache_dir) -> pathlib.Path:
    """The queue of the cache directory `cache_dir` for this machine's CPU kind
    (`_cpu.KIND`): where the nodes of a cluster share one cache directory, a worker
    compiles only for the CPU it runs on, so it serves the runs of its own kind."""
    from . import _cpu  # (not JAX: the worker reads this before it takes the queue's lock)

    return pathlib.Path(cache_dir) / "stickslip-queue" / _cpu.KIND


def _queue() -> pathlib.Path:
    from ._jax import jax

    return queue_dir(jax.config.jax_compilation_cache_dir)


class _Shape:
    """An array in a job: its shape and dtype (all an executable's key reads)."""

    def __init__(self, shape, dtype):
        self.shape, self.dtype = tuple(shape), str(dtype)

    def array(self):
        import numpy as np

        return np.broadcast_to(np.zeros((), self.dtype), self.shape)


@contextlib.contextmanager
def _try_lock(path: pathlib.Path):
    """An exclusive, non-blocking `flock` on `path`: yields whether it was taken."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no background compiler
        yield False
        return
    handle = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle = open(path, "a")  # noqa: SIM115
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        if handle is not None:
            handle.close()
        yield False
        return
    try:
        yield True
    finally:
        handle.close()


def _where(fn) -> tuple[str, str] | None:
    """`(module, attribute)` under which `fn` can be imported again, or `None`."""
    inner = getattr(fn, "__wrapped__", fn)
    module = sys.modules.get(getattr(inner, "__module__", None) or "")
    for name, value in vars(module or object()).items():
        if value is fn:
            return module.__name__, name
    return None


_requested: set = set()  # what this process has asked for


def request(fn, *args, paths: int) -> bool:
    """Under the `"background"` policy (`_compile.policy`), have the background compiler
    make `_compile.executable(fn, *args, paths=paths)` (arrays in `args` may be stand-ins
    of their shapes: only their shapes travel) and make sure a worker runs.
    Once per process and program; nothing where the program has no disk entry (no cache
    directory, or arguments without a reproducible text form) or cannot travel. Returns
    whether a job was queued."""
    import pickle

    import equinox as eqx

    from . import _compile
    from ._jax import jax

    if _compile.policy() != "background" or not jax.config.jax_compilation_cache_dir:
        return False
    where = _where(fn)
    if where is None:
        return False
    shaped = jax.tree_util.tree_map(
        lambda x: _Shape(x.shape, x.dtype) if eqx.is_array(x) else x, args
    )
    try:
        blob = pickle.dumps((where, shaped, paths))
    except Exception:  # an argument that cannot travel: nothing to hand over
        return False
    if blob in _requested or not _compile.disk_entry(fn, args):
        return False
    _requested.add(blob)
    queue = _queue()
    job = queue / f"{hashlib.sha256(blob).hexdigest()[:40]}.job"
    if job.exists():
        return False
    try:
        queue.mkdir(parents=True, exist_ok=True)
        tmp = job.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_bytes(blob)
        os.replace(tmp, job)
    except OSError:  # a read-only cache
        return False
    _compile.requests[0] += 1
    with _try_lock(queue / "worker.lock") as free:
        pass
    if free:  # no worker holds the queue: start one (it takes the lock itself)
        _spawn(pathlib.Path(jax.config.jax_compilation_cache_dir))
    return True


def _spawn(cache_dir: pathlib.Path) -> None:
    try:
        subprocess.Popen(
            [sys.executable, "-m", "stickslip._background", str(cache_dir), str(os.getpid())],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True, env=dict(os.environ, STICKSLIP_CACHE_DIR=str(cache_dir)),
        )  # fmt: skip
    except OSError:  # no process can be started here: the runs compile in the foreground
        pass


def pending(cache_dir) -> int:
    """Jobs still queued in the cache directory `cache_dir`."""
    return len(list(queue_dir(cache_dir).glob("*.job")))


def wait(cache_dir, timeout: float = 600.0) -> bool:
    """Wait until the queue of `cache_dir` is empty and no worker runs (for tests and
    benchmarks); returns whether it is."""
    import time

    queue = queue_dir(cache_dir)
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        with _try_lock(queue / "worker.lock") as free:
            if free and not pending(cache_dir):
                return True
        time.sleep(0.1)
    return False


def _work(queue: pathlib.Path) -> None:
    """Make the queued executables until the queue is empty."""
    import pickle

    from ._jax import jax

    while True:
        jobs = sorted(queue.glob("*.job"), key=lambda p: p.stat().st_mtime)
        if not jobs:
            return
        job = jobs[0]
        try:
            with open(job, "rb") as f:
                # A job is a pickle (it names a function and its arguments): only this
                # user's own are read.
                if not _cache.trusted(os.fstat(f.fileno())):
                    continue
                data = f.read()
            (module, name), shaped, paths = pickle.loads(data)
            fn = getattr(importlib.import_module(module), name)
            args = jax.tree_util.tree_map(
                lambda x: x.array() if isinstance(x, _Shape) else x,
                shaped,
                is_leaf=lambda x: isinstance(x, _Shape),
            )
            from . import _compile

            _compile.executable(fn, *args, paths=paths)
        except Exception:  # a damaged job, or one this process cannot rebuild: dropped
            pass
        finally:
            with contextlib.suppress(OSError):
                job.unlink()


def _wait_for(pid: int, timeout: float) -> None:
    """Wait until the process `pid` has exited, at most `timeout` seconds."""
    import time

    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            os.kill(pid, 0)
        except (OSError, ValueError):  # gone (or never ours to ask about)
            return
        time.sleep(0.1)


def _lower_priority() -> None:
    """Nice this process by `NICE`, and its session as well: Linux with autogrouping
    (`/proc/sys/kernel/sched_autogroup_enabled`, on by default in most distributions) first
    shares the CPU equally between sessions and applies a process's niceness only within its
    own, so the worker, in a session of its own (`_spawn`), took a whole core of two from the
    run in the foreground however niced it was (a two-thread NumPy job beside a niced
    spinning process in its own session: 2.8-3.0 s against 1.5 s alone; 1.6-1.7 s with the
    session niced too). Where there is no autogroup the file is absent: nothing to do."""
    import time

    with contextlib.suppress(OSError, AttributeError):
        os.nice(NICE)
    for _ in range(5):  # (raising a niceness needs no privilege)
        try:
            pathlib.Path("/proc/self/autogroup").write_text(str(NICE))
            return
        except BlockingIOError:  # unprivileged: one such write per 0.1 s on the machine
            time.sleep(0.1)
        except OSError:
            return


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    cache_dir = pathlib.Path(argv[0])
    _lower_priority()
    os.environ["STICKSLIP_COMPILE"] = "eager"  # (what this process compiles, it compiles)
    queue = queue_dir(cache_dir)
    first = True
    while True:
        with _try_lock(queue / "worker.lock") as mine:
            if not mine:
                return 0  # another worker has the queue
            if first and len(argv) > 1:
                # Waiting with the lock held: the run's later requests see a worker and
                # start no other (a cold main job started 8, each a new Python process).
                _wait_for(int(argv[1]), PARENT_WAIT)
            first = False
            _work(queue)
        if not pending(cache_dir):  # (a job queued while this one was finishing: go on)
            return 0


if __name__ == "__main__":  # (through the module itself: the jobs' `_Shape` is its own)
    from stickslip._background import main as _main

    sys.exit(_main())
