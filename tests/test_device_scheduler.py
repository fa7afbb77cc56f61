"""The device scheduler (`stickslip._simulate.device`): one compiled program per chunk.

Checked against things it did not produce: the host scheduler's sticks path by path (the
host scheduler is itself checked against the depth-first refinement and the reference in
tests/test_exact_detection.py), the independent reference histograms, and the count of
compiled calls against the number of chunks. The runs use chunks of at most 1024 paths:
one program serves them all. They are in the slow tier: that program is a compilation of
7-19 s on 2 cores (every stepping and refinement buffer of a chunk inlined), for a
scheduler that `auto` never chooses on a CPU; the default tier keeps the checks of its
arguments and ladders.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_exact_detection import PUBLIC, SECOND, _against_reference

import stickslip as ss
from stickslip._errors import ParameterError
from stickslip._simulate import buffers, config, device

T_MAX = {"public": 30.0, "second": 40.0}
PARAMS = {"public": PUBLIC, "second": SECOND}


def _same_sticks(host, dev):
    """The same stick decisions path by path, located times and positions to 1e-9."""
    np.testing.assert_array_equal(dev.stuck, host.stuck)
    np.testing.assert_array_equal(dev.immediate, host.immediate)
    s = host.stuck
    np.testing.assert_allclose(dev.slip_time[s], host.slip_time[s], rtol=0, atol=1e-9)
    np.testing.assert_allclose(dev.stick_position[s], host.stick_position[s], rtol=0, atol=1e-9)
    np.testing.assert_allclose(dev.onset_state, host.onset_state, rtol=0, atol=0)
    assert np.all(np.isnan(dev.slip_time[~s]))
    # The same candidates were refined before each stick: the same miss bound.
    assert dev.stats["miss_bound"] == pytest.approx(host.stats["miss_bound"], rel=1e-9)
    assert dev.stats["unresolved"] == host.stats["unresolved"]


@pytest.mark.slow
@pytest.mark.parametrize("dt", [0.8, 0.1])
@pytest.mark.parametrize("name", ["public", "second"])
def test_device_scheduler_finds_the_host_sticks(Langevin, name, dt):
    """Two chunk sizes (1000 and 700 paths: chunk boundaries in different places, one
    program; with 1000 the last chunk, 100 paths, starts in the smaller stepping buffer)
    against the host scheduler in one chunk."""
    m = Langevin(**PARAMS[name])
    n, t_max = 2100, T_MAX[name]
    host = ss.simulate(m, n, dt, t_max, seed=5, scheduler="host")
    assert host.fraction_stuck > 0.99
    for chunk in (1000, 700):
        dev = ss.simulate(m, n, dt, t_max, seed=5, scheduler="device", chunk_size=chunk)
        _same_sticks(host, dev)
        assert dev.stats["dispatches"] == 1 + math.ceil(n / chunk)


@pytest.mark.slow
def test_device_scheduler_matches_the_reference(Langevin, reference):
    """The public set at a coarse step against the independent reference (chi-square of
    the slip-time and slip-distance histograms, means within 4 standard errors)."""
    ens = ss.simulate(
        Langevin(**PUBLIC), 40_000, 0.8, 30.0, seed=23, scheduler="device", chunk_size=1000
    )
    _against_reference(ens, reference)
    assert ens.stats["unresolved"] == 0


@pytest.mark.slow
@pytest.mark.parametrize("dt", [0.2, 0.8])
def test_device_scheduler_matches_the_reference_full_size(Langevin, reference, dt):
    ens = ss.simulate(Langevin(**PUBLIC), 200_000, dt, 30.0, seed=24, scheduler="device")
    _against_reference(ens, reference)


@pytest.mark.slow
def test_dispatches_do_not_grow_with_paths_or_steps(Langevin):
    """One compiled call per chunk besides one per run (the next onsets; the slip's
    description, NumPy in `langevin`, takes none), and one copy of its results, whatever
    the number of paths and the step; the host scheduler's calls grow with both."""
    m = Langevin(**PUBLIC)
    chunk = 1000
    counts = {}
    for n, dt in ((10_000, 0.8), (10_000, 0.1), (1_000, 0.8)):
        ens = ss.simulate(m, n, dt, 30.0, seed=7, scheduler="device", chunk_size=chunk)
        chunks = math.ceil(n / chunk)
        assert ens.stats["dispatches"] == 1 + chunks
        counts[n, dt] = ens.stats["transfers"] - chunks  # the per-run copies
    assert len(set(counts.values())) == 1
    host = ss.simulate(m, 10_000, 0.1, 30.0, seed=7, scheduler="host", chunk_size=chunk)
    assert host.stats["dispatches"] > 2 * (1 + math.ceil(10_000 / chunk))


@pytest.mark.slow
def test_dispatches_at_a_million_paths(Langevin):
    """10^6 paths in one chunk: the same two calls as 10^4."""
    m = Langevin(**PUBLIC)
    for n in (10_000, 1_000_000):
        ens = ss.simulate(m, n, 0.8, 30.0, seed=8, scheduler="device")
        assert ens.stats["dispatches"] == 2, n
    assert ens.fraction_stuck > 0.999


@pytest.mark.slow
def test_device_scheduler_finds_the_host_sticks_in_large_buffers(Langevin):
    """A chunk of 40 000 paths (the host steps without stepping past candidates there)."""
    m = Langevin(**PUBLIC)
    host = ss.simulate(m, 40_000, 0.8, 30.0, seed=9, scheduler="host")
    _same_sticks(host, ss.simulate(m, 40_000, 0.8, 30.0, seed=9, scheduler="device"))


def test_scheduler_is_checked(Langevin):
    m = Langevin(**PUBLIC)
    with pytest.raises(ParameterError, match="scheduler"):
        ss.simulate(m, 10, 0.8, 30.0, scheduler="gpu")
    with pytest.raises(ParameterError, match="scheduler.*bridge detector"):
        ss.simulate(m, 10, 0.8, 30.0, scheduler="device", monitor="grid")


def test_auto_keeps_the_host_scheduler_on_a_cpu():
    """Measured on 2 cores (benchmarks/gpu_check.py): the host scheduler is the faster there."""
    backend = config.jax.default_backend()
    expected = "host" if backend == "cpu" else "device"
    assert config.choose_scheduler("simulate", "auto", "bridge") == expected
    assert config.choose_scheduler("simulate", "auto", "grid") == "host"


def test_buffer_ladders():
    """Each buffer an eighth of the one before, at most `MAX_SIZES`; the refinement's first
    holds the two halves of every candidate of a full queue (a small queue's only one)."""
    assert (device.MIN_STEPPING, device.FINE) == (buffers.MIN_BUFFER, buffers.FINE_BUFFER)
    assert device.stepping_sizes(1024) == (1024, 128)
    assert device.stepping_sizes(2**20) == (2**20, 2**17, 2**14, 2**11)
    assert device.interval_sizes(1024) == (2048,)
    assert device.interval_sizes(2**17) == (2**18, 2**17, 2**14, 2**11)
    assert device.interval_sizes(128) == (256,)
