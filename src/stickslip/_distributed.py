"""Running blocks of paths (or study points) as tasks on a Dask cluster.

Every simulator's numbers are a function of `(seed, path)` alone, so an ensemble splits into
contiguous blocks of paths that run anywhere and are joined in order, identical to a local
run. What goes over the wire: the model (its parameters, a few hundred bytes), the run's
arguments and a block's first and last path out; the block's per-path arrays back. Workers
compile once each, or load the compiled code from the on-disk cache (`_compile`) when they
share a file system with it. A task whose worker dies is re-run on another worker by the
scheduler (with `RETRIES` more tries for a task that raised): its block's numbers are the
same wherever it runs.

`dask.distributed` is an optional dependency (`pip install "stickslip[dask]"`).
"""

from __future__ import annotations

import contextlib
import math
import os
from typing import Any

from ._errors import ParameterError

RETRIES = 2  # further tries of a task that raised (a worker lost mid-task is re-run anyway)
BLOCKS_PER_THREAD = 4  # blocks per worker thread: late blocks balance uneven workers
MIN_BLOCK = 1024  # paths: below this a block's fixed costs (a buffer of 128..1024) dominate
# seconds to reach a scheduler given by address
CONNECT_TIMEOUT = float(os.environ.get("STICKSLIP_DASK_TIMEOUT", "10"))


def _import_distributed(owner: str):
    try:
        import distributed
    except ImportError:
        raise ParameterError(
            owner, "client", 'needs dask.distributed: pip install "stickslip[dask]"'
        ) from None
    return distributed


def local_workers() -> int:
    """The worker processes of `client="local"`: one per CPU this process may use, as Dask
    counts them (its CPU affinity and its cgroup's CPU quota, as a batch job or a container
    sets them), not one per core of the machine (`os.cpu_count()`: a job given 2 of a node's
    64 cores would start 64 processes, each importing JAX and compiling)."""
    from dask.system import CPU_COUNT

    return max(1, int(CPU_COUNT))


def connect(owner: str, client) -> tuple[Any, bool]:
    """The `distributed.Client` for `client`: a client as it is, or a scheduler address
    (`"tcp://host:8786"`) or `"local"` (a local cluster of one single-threaded worker
    process per CPU this process may use, `local_workers`). Returns `(client, owned)`: an
    owned client is closed by `close`. A scheduler that cannot be reached is one
    `ParameterError` line."""
    distributed = _import_distributed(owner)
    if isinstance(client, distributed.Client):
        return client, False
    if not isinstance(client, str) or not client.strip():
        raise ParameterError(
            owner, "client", "must be a dask.distributed.Client, a scheduler address or 'local'",
            client,
        )  # fmt: skip
    address = client.strip()
    if address == "local":
        cluster = distributed.LocalCluster(
            n_workers=local_workers(), threads_per_worker=1, processes=True,
            dashboard_address=":0",
        )  # fmt: skip
        return distributed.Client(cluster), True
    try:
        return distributed.Client(address, timeout=CONNECT_TIMEOUT), True
    except (OSError, TimeoutError, ValueError) as err:
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise ParameterError(
            owner, "client", f"cannot reach the Dask scheduler at {address!r} within "
            f"{CONNECT_TIMEOUT:g} s ({reason})",
        ) from None  # fmt: skip


def close(client, owned: bool) -> None:
    """Close a client that `connect` made (and its local cluster, if any)."""
    if not owned:
        return
    cluster = getattr(client, "cluster", None)
    with contextlib.suppress(Exception):
        client.close()
    if cluster is not None:
        with contextlib.suppress(Exception):
            cluster.close()


@contextlib.contextmanager
def connected(owner: str, client):
    """`connect` for the length of a block; None stays None (a local run)."""
    if client is None:
        yield None
        return
    client, owned = connect(owner, client)
    try:
        yield client
    finally:
        close(client, owned)


def threads(client) -> int:
    """Worker threads of the cluster (at least 1)."""
    info = client.scheduler_info()
    return max(1, sum(int(w.get("nthreads", 1)) for w in info.get("workers", {}).values()))


def blocks(n_paths: int, client, max_block: int | None = None) -> list[tuple[int, int]]:
    """Contiguous `[start, stop)` blocks of paths: at most `BLOCKS_PER_THREAD` per worker
    thread, of at least `MIN_BLOCK` (and at most `max_block`) paths, each a power of two
    but the last (the simulator's buffer sizes)."""
    count = max(1, min(threads(client) * BLOCKS_PER_THREAD, n_paths // MIN_BLOCK or 1))
    size = math.ceil(n_paths / count)
    # a block fills the simulator's buffers (powers of two) rather than padding them
    size = 1 << (size - 1).bit_length()
    if max_block is not None:
        size = min(size, max_block)
    return [(a, min(a + size, n_paths)) for a in range(0, n_paths, size)]


def run_tasks(client, fn, calls: list[tuple], on_done=None) -> list:
    """`fn(*call)` for every call, as tasks (retried `RETRIES` times when they raise; a task
    on a lost worker is re-run by the scheduler); the results in call order, or the first
    failed task's own error. `on_done(i)` is called as call `i` completes (progress)."""
    import uuid

    distributed = _import_distributed("client")
    run = uuid.uuid4().hex[:12]
    name = fn.__name__.strip("_")
    futures = [
        client.submit(fn, *call, retries=RETRIES, key=f"stickslip-{name}-{run}-{i}")
        for i, call in enumerate(calls)
    ]
    index = {f.key: i for i, f in enumerate(futures)}
    try:
        for done in distributed.as_completed(futures):
            if on_done is not None:
                on_done(index[done.key])
            if done.status == "error":
                break  # gather raises the task's own error
        return client.gather(futures)
    finally:
        for f in futures:
            f.release()


def run_blocks(client, fn, parts: list[tuple[int, int]], *args, progress=None, label="paths"):
    """`fn(*args, start, stop)` for every block (`run_tasks`); with `progress`, a bar over
    the paths done across the cluster."""
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=parts[-1][1], desc=fn.__name__.strip("_"), unit=label, leave=False)
    try:
        done = None if bar is None else (lambda i: bar.update(parts[i][1] - parts[i][0]))
        return run_tasks(client, fn, [(*args, a, b) for a, b in parts], done)
    finally:
        if bar is not None:
            bar.close()
