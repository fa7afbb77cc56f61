"""Ensembles and sweeps on a Dask cluster: the numbers of a local run, whatever the cluster
does (issue: past one machine)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from conftest import run_cli

import stickslip as ss

distributed = pytest.importorskip("distributed")

pytestmark = pytest.mark.early  # (worker processes: a few seconds in each test)

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
OUTPUTS = ("slip_time", "slip_distance", "stick_time", "period")
# A small sweep: three points of the noise intensity.
SWEEP = dict(
    model=dict(name="langevin", params=PUBLIC),
    simulation=dict(n_paths=1000, dt=0.1, t_max=30, seed=4),
    analytic=[dict(method="decoupling", order=1)],
    outputs=["slip_time", "period"],
    sweep=dict(parameters={"model.params.D": [0.2, 0.4, 0.6]}),
)


def _cluster(n_workers=2):
    return distributed.LocalCluster(
        n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=":0"
    )


@pytest.fixture(scope="module")
def client():
    """Two worker processes: the work is split between processes (the slow tier's runs)."""
    with _cluster() as cluster, distributed.Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def one_worker():
    """One worker process: the sweep's points still run as tasks in another process (each
    worker costs ~5 s of CPU: a new process's start and loading)."""
    with _cluster(n_workers=1) as cluster, distributed.Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def model(Langevin):
    return Langevin(**PUBLIC)


def assert_same(a, b, names):
    for name in names:
        x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        assert x.shape == y.shape, name
        assert np.array_equal(x, y, equal_nan=True), name


@pytest.mark.slow  # 15 s
def test_ensemble_on_two_worker_processes_is_the_local_one(client, model):
    """The issue's acceptance: 40000 paths, dt 0.01, t_max 30, seed 3 on a 2-process local
    cluster give exactly the local arrays."""
    local = ss.simulate(model, 40000, dt=0.01, t_max=30, seed=3)
    remote = ss.simulate(model, 40000, dt=0.01, t_max=30, seed=3, client=client)
    assert remote.stats["tasks"] > 1
    assert_same(local, remote, (*OUTPUTS, "immediate", "stuck", "onset_state", "stick_state"))
    assert remote.stats["miss_bound"] == pytest.approx(local.stats["miss_bound"], rel=1e-12)


@pytest.mark.slow
def test_upcrossings_cycles_and_chains_on_the_cluster(client, model):
    """Recorded upcrossings, successive cycles (with their time series) and chains of blocks
    (random thresholds: a block of paths draws its own paths' strengths) split over tasks
    without changing a number."""
    kw = dict(seed=1, record_upcrossings=4)
    local = ss.simulate(model, 3000, 0.05, 10.0, **kw)
    remote = ss.simulate(model, 3000, 0.05, 10.0, client=client, **kw)
    assert remote.stats["tasks"] == 2
    assert_same(local.upcrossings, remote.upcrossings, ("times", "positions", "count"))

    local = ss.simulate_cycles(model, 3, 0.01, 40.0, seed=2)
    remote = ss.simulate_cycles(model, 3, 0.01, 40.0, seed=2, client=client)
    for k in local.cycles:
        assert np.array_equal(local.cycles[k], remote.cycles[k], equal_nan=True), k
    for p in range(3):
        for x, y in zip(local.trajectory(p), remote.trajectory(p), strict=True):
            assert np.array_equal(x, y)

    chain = ss.get_model("burridge-knopoff")(
        4, k_c=5.0, k_p=1.0, v_b=0.05, friction="velocity-weakening",
        friction_params={"F0": 1.0, "alpha": 2.0}, D=1e-3, tau=0.1, threshold="uniform",
        threshold_params={"low": 0.6, "high": 1.0},
    )  # fmt: skip
    local = ss.simulate_chain(chain, 3, 0.01, 60.0, seed=5, record_releases=True)
    remote = ss.simulate_chain(chain, 3, 0.01, 60.0, seed=5, record_releases=True, client=client)
    assert remote.info["tasks"] > 1
    assert local.events("size").size > 10
    for k in ("size", "slip", "duration", "start"):
        assert np.array_equal(local.events(k), remote.events(k)), k
    assert_same(local, remote, ("n_events", "mean_velocity", "slipping", "mean_force"))
    assert np.array_equal(np.concatenate(local.releases), np.concatenate(remote.releases))


@pytest.mark.slow  # (12 s: a worker process's start and loading, and the sweep twice)
def test_sweep_on_the_cluster_writes_the_local_dataset(one_worker, tmp_path):
    """A sweep's points run as tasks; the Dataset written is the local one, bar wall times."""
    import xarray as xr

    ss.run_study(SWEEP, tmp_path / "local", progress=False, figures=False)
    ss.run_study(SWEEP, tmp_path / "dask", progress=False, figures=False, client=one_worker)
    with xr.open_dataset(tmp_path / "local" / "results.nc") as a:
        with xr.open_dataset(tmp_path / "dask" / "results.nc") as b:
            timings = {k for k in a.data_vars if k.startswith("seconds_")}
            assert set(a.data_vars) == set(b.data_vars)
            assert a.drop_vars(timings).equals(b.drop_vars(timings))
            assert dict(a.sizes) == dict(b.sizes) and 3 in a.sizes.values()


@pytest.mark.slow
def test_a_worker_killed_mid_ensemble_changes_no_number(model):
    """SIGKILL one worker process while it runs a block: the scheduler re-runs the block
    elsewhere (its nanny restarts the worker) and the ensemble is still the local one."""
    local = ss.simulate(model, 40000, dt=0.01, t_max=30, seed=7)
    with _cluster() as cluster, distributed.Client(cluster) as c:
        pids = c.run(os.getpid)
        killed = []

        def kill_a_busy_worker():
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline:
                busy = [a for a, keys in c.processing().items() if keys]
                if busy:
                    os.kill(pids[busy[0]], signal.SIGKILL)
                    killed.append(busy[0])
                    return
                time.sleep(0.005)

        killer = threading.Thread(target=kill_a_busy_worker)
        killer.start()
        remote = ss.simulate(model, 40000, dt=0.01, t_max=30, seed=7, client=c)
        killer.join()
        assert killed, "no worker was found busy"
        assert set(c.run(os.getpid).values()) != set(pids.values())  # one was replaced
    assert_same(local, remote, (*OUTPUTS, "immediate", "stuck"))


def test_unreachable_scheduler_is_one_line(model, monkeypatch, tmp_path):
    """The library and the command line (in this process: the timeout is patched here;
    the console script's exit code is tested in tests/test_study_errors.py)."""
    from stickslip import _distributed

    monkeypatch.setattr(_distributed, "CONNECT_TIMEOUT", 1.0)
    with pytest.raises(ss.ParameterError, match="cannot reach the Dask scheduler at"):
        ss.simulate(model, 100, 0.1, 5.0, client="tcp://127.0.0.1:9")
    with pytest.raises(ss.ParameterError, match="scheduler address or 'local'"):
        ss.simulate(model, 100, 0.1, 5.0, client=3)
    # the command line: one line, exit 2, nothing written
    out = tmp_path / "out"
    study = tmp_path / "s.yaml"
    import yaml

    study.write_text(yaml.safe_dump({k: v for k, v in SWEEP.items() if k != "sweep"}))
    proc = run_cli("run", study, "--out", out, "--dask", "tcp://127.0.0.1:9")
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "--dask" in lines[0] and "cannot reach" in lines[0], lines
    assert not out.exists()


def test_missing_dask_is_one_line(model, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(ss.ParameterError, match=r'pip install "stickslip\[dask\]"'):
        ss.simulate(model, 100, 0.1, 5.0, client="local")


@pytest.mark.skipif(
    not hasattr(os, "sched_setaffinity") or (os.cpu_count() or 1) < 2,
    reason="needs CPU affinity and two CPUs",
)
def test_a_process_held_to_one_cpu_uses_one():
    """`client="local"` starts one worker per CPU the process may use, not per core of the
    machine, and the exact refinement's threads follow the same count: a process held to
    one CPU (as a batch job's share of a node) starts one worker and refines in one thread."""
    code = (
        "import os\n"
        "os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})\n"
        "from stickslip import _distributed\n"
        "from stickslip._simulate import bridge\n"
        "print(os.cpu_count(), _distributed.local_workers(), bridge._threads())\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    machine, workers, threads = map(int, out.stdout.split())
    assert machine >= 2 and workers == 1 and threads == 1


@pytest.mark.slow
def test_command_line_sweep_on_a_local_cluster(tmp_path):
    """`stickslip sweep ... --dask local` starts a cluster, runs the points there and writes
    the Dataset of the local sweep."""
    import xarray as xr
    import yaml

    study = tmp_path / "s.yaml"
    study.write_text(yaml.safe_dump({k: v for k, v in SWEEP.items() if k != "sweep"}))
    args = [sys.executable, "-m", "stickslip.cli", "sweep", str(study), "-p",
            "model.params.D=0.2,0.6", "-q"]  # fmt: skip
    for out, extra in (("local", []), ("dask", ["--dask", "local"])):
        proc = subprocess.run(
            [*args, "--out", str(tmp_path / out), *extra], capture_output=True, text=True
        )
        assert proc.returncode == 0, proc.stderr
    with xr.open_dataset(tmp_path / "local" / "results.nc") as a:
        with xr.open_dataset(tmp_path / "dask" / "results.nc") as b:
            timings = {k for k in a.data_vars if k.startswith("seconds_")}
            assert a.drop_vars(timings).equals(b.drop_vars(timings))
