"""Successive cycles: time series for plots and return maps."""

import numpy as np
import pytest

import stickslip as ss
from stickslip._simulate.cycles import _RECORD_STEPS

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)


@pytest.fixture(scope="module")
def series(Langevin):
    return ss.simulate_cycles(Langevin(**PUBLIC), 3, 0.005, 60.0, seed=4)


def test_cycles_chain_up(series):
    c = series.cycles
    for p in range(3):
        rows = c["path"] == p
        release = c["release_time"][rows]
        assert release[0] == 0.0 and release[-1] < 60.0
        assert release[-1] + c["period"][rows][-1] >= 60.0
        np.testing.assert_allclose(np.diff(release), c["period"][rows][:-1])
        np.testing.assert_array_equal(c["cycle"][rows], np.arange(rows.sum()))
        np.testing.assert_array_equal(series.periods(p), c["period"][rows])


def test_trajectories(series):
    c = series.cycles
    for p in range(3):
        t, X, slipping = series.trajectory(p)
        assert X.shape == (t.size, 3)
        assert np.all(np.diff(t) >= -1e-12)
        assert np.all(X[slipping, 1] <= 1.0 + 1e-12)  # v <= v_b while slipping
        sticks = ~slipping
        assert sticks.sum() == np.sum(c["path"] == p)
        np.testing.assert_allclose(X[sticks, 1], 1.0, atol=1e-6)  # at the stick v = v_b
        np.testing.assert_allclose(X[sticks, 0], c["stick_position"][c["path"] == p])
        # every slip starts at the threshold, with v = v_b
        starts = np.r_[0, np.nonzero(sticks)[0][:-1] + 1]
        np.testing.assert_allclose(X[starts, :2], [[1.0, 1.0]] * starts.size)
        # The recording re-runs each slip with its noise: its last sample is the detector's
        # path less than one step before the stick (travel <= dt |v|, v <= v_b), also for
        # the slips longer than one recording solve (continued from where it ended).
        end = np.nonzero(sticks)[0]
        gap = np.abs(X[end, 0] - X[end - 1, 0])
        assert np.all(gap <= 0.005 * np.maximum(1.0, np.abs(X[end - 1, 1])) + 1e-12)
    assert np.max(c["slip_time"]) > 0.005 * _RECORD_STEPS  # (such slips are in the test)


def test_a_longer_run_records_on_a_compiled_size(series, Langevin, monkeypatch, rent_held):
    """Five times the t_max: about 180 slips to record where the fixture recorded about 36
    (on 128 slots), so the recording solve wants 256 slots. A compiled size stands in
    (`_record_size` searches the powers of two; on the simulator's buffer sizes, steps of
    8, it found none and compiled 256): nothing is traced or compiled, and the slips both
    runs hold are recorded alike, whatever solve and column each ran in. A stand-in asks
    the background compiler for the size itself (under its policy), as the stepping does."""
    from stickslip import _rng
    from stickslip._simulate import cycles, host

    monkeypatch.setenv("STICKSLIP_COMPILE", "reuse")
    counts = {k: ss.cache_info()[k] for k in ("traces", "compiles")}
    longer = ss.simulate_cycles(Langevin(**PUBLIC), 3, 0.005, 300.0, seed=4)
    assert {k: ss.cache_info()[k] for k in counts} == counts
    for p in range(3):
        t, X, slipping = series.trajectory(p)
        t2, X2, _ = longer.trajectory(p)
        n = np.nonzero(~slipping)[0][-2] + 1  # the fixture's cycles but its last (t_max cuts)
        np.testing.assert_array_equal(t2[:n], t[:n])
        np.testing.assert_array_equal(X2[:n], X[:n])
    # The search itself, on a run whose recording solve is compiled at the sizes given.
    root = _rng.stream_key(_rng.seed_key(0), _rng.SERIES)
    run = host.HostRun("simulate_cycles", Langevin(**PUBLIC), "auto", "continuous", 0.005,
                      300.0, root)  # fmt: skip

    class Compiled:
        fn, fixed = cycles._record, ()

        def __init__(self, *sizes):
            self.sizes = sizes

        def ready(self, *args, paths):
            return paths in self.sizes

    asked = []  # what the background compiler is asked for (under its policy)
    monkeypatch.setattr(cycles._background, "request", lambda *a, paths: asked.append(paths))

    def size(count, *compiled):
        return cycles._record_size(run, Compiled(*compiled), 3, count, 1 << 20)

    assert size(557, 256) == 256 and size(557, 128, 512) == 512  # smaller, in more solves
    assert size(557, 2048, 8192) == 2048  # larger, padded, up to 8 times
    assert asked == [1024] * 3  # the size itself, for later runs
    assert size(557, 16384) == size(557) == 1024  # none within 8 times: compiled at the call
    assert size(557, 1024) == 1024 and asked == [1024] * 3


def test_cycles_are_distributed_like_single_slips(series, Langevin):
    """Every cycle starts afresh (the paper's sharp reset): cycle slip times follow the
    one-cycle distribution (means within 4 standard errors)."""
    longer = ss.simulate_cycles(Langevin(**PUBLIC), 20, 0.005, 200.0, seed=5, record=False)
    one = ss.simulate(Langevin(**PUBLIC), 20_000, 0.005, 30.0, seed=6)
    a = longer.cycles["slip_time"]
    m1, se1 = one.mean("slip_time")
    assert abs(a.mean() - m1) < 4 * np.hypot(a.std() / np.sqrt(a.size), se1)
    assert longer.traces is None
    with pytest.raises(ValueError, match="record=False"):
        longer.trajectory(0)


def test_zero_length_cycles_warn(Langevin):
    white = Langevin(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)
    with pytest.warns(UserWarning, match="did not reach t_max"):
        s = ss.simulate_cycles(white, 2, 0.01, 10.0, max_cycles=40, record=False)
    assert np.all(s.cycles["period"] == 0)


def test_bad_arguments(Langevin):
    m = Langevin(**PUBLIC)
    with pytest.raises(ss.ParameterError, match="'n_paths' must be <="):
        ss.simulate_cycles(m, 10_000, 0.01, 1.0)
    with pytest.raises(ss.ParameterError, match="'max_cycles'"):
        ss.simulate_cycles(m, 1, 0.01, 1.0, max_cycles=0)
    with pytest.raises(IndexError):
        ss.simulate_cycles(m, 1, 0.01, 5.0).trajectory(3)


def test_counted_cycles_are_the_series_first_cycles(series, Langevin):
    """`counted_cycles` (a number of cycles a path, in one round for a memoryless model)
    runs the same slots with the same keys as `simulate_cycles`' rounds: the fixture's
    cycles, but its last, are its first cycles, to the bit, their recorded slips too; a
    cycle's slip followed up to the horizon only (t_max bounds a slip, not the series)."""
    from stickslip._simulate.cycles import counted_cycles

    c = series.cycles
    count = int(np.min(np.bincount(c["path"]))) - 1
    seen = []
    counted = counted_cycles(Langevin(**PUBLIC), 3, 0.005, 30.0, 4, count,
                             check=lambda table: seen.append(table["period"].size))  # fmt: skip
    assert seen == [3 * count]  # (checked before the slips are recorded)
    k = counted.cycles
    np.testing.assert_array_equal(np.bincount(k["path"]), [count] * 3)
    for p in range(3):
        rows, mine = c["path"] == p, k["path"] == p
        for name in ("release_time", "slip_time", "stick_time", "slip_distance"):
            np.testing.assert_array_equal(k[name][mine], c[name][rows][:count], err_msg=name)
        t, X, slipping = series.trajectory(p)
        t2, X2, slipping2 = counted.trajectory(p)
        np.testing.assert_array_equal(t2, t[: t2.size])
        np.testing.assert_array_equal(X2, X[: t2.size])
        assert np.sum(~slipping2) == count
