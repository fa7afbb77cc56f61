"""The registry of per-cycle quantities against the tables that give them: the columns each
table has, and each unit and dimension against physics the registry does not know (a period
is a slip and a stick; a force drop is the stiffness times the slip distance; a time in
model units is a time times omega0)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _force_traces import Rig, make_trace

import stickslip as ss
from stickslip import quantities

M, K, V, G = 0.0307, 168.0, 42e-6, 9.81
SLIDER = ss.Slider(
    mass=M, stiffness=K, v_b=V, static_friction=0.32 * M * G, kinetic_friction=0.3 * M * G,
    damping=1e-3, noise=1e-12, noise_time=1e-3,
)  # fmt: skip


@pytest.fixture(scope="module")
def slider_cycles():
    return SLIDER.simulate(n_paths=200, seed=1)


def test_a_sliders_columns_and_units(slider_cycles):
    assert tuple(slider_cycles.table) == quantities.names("slider")
    assert slider_cycles.units == {k: quantities.get(k).unit for k in slider_cycles.table}
    t = slider_cycles.table
    ok = np.isfinite(t["period"])
    assert ok.sum() > 100
    # a period (s) is a slip (s) and a stick (s); a force drop (N) is k times d (m); the
    # slider's own travel (m) is d plus the drive's V T_sl
    np.testing.assert_allclose(t["period"][ok], (t["slip_time"] + t["stick_time"])[ok], rtol=1e-9)
    np.testing.assert_allclose(t["force_drop"][ok], K * t["slip_distance"][ok], rtol=1e-9)
    np.testing.assert_allclose(
        t["slider_travel"][ok], (t["slip_distance"] + V * t["slip_time"])[ok], rtol=1e-9
    )


def test_dimensions_convert_as_the_physics_does(slider_cycles):
    # a model time is omega0 t (omega0 = sqrt(k/m)); a model length is over x0 = (F_s-F_k)/k
    omega0 = math.sqrt(K / M)
    x0 = (0.02 * M * G - SLIDER.damping * V) / K
    expected = {"time": 1 / omega0, "length": x0, "force": K * x0}
    ens = slider_cycles.ensemble
    t = slider_cycles.table
    for name in quantities.names("model"):
        factor = expected[quantities.get(name).dimension]
        np.testing.assert_allclose(t[name], np.asarray(getattr(ens, name)) * factor, rtol=1e-9)


def test_extracted_columns_are_the_registrys():
    t, force, _ = make_trace(3, duration=20.0, rig=Rig())
    cycles = ss.extract_cycles(t, force=force, stiffness=Rig().stiffness, v_b=Rig().v_b)
    assert tuple(cycles.table) == quantities.names("force")
    assert set(quantities.names("trace")) < set(cycles.table)
    for name in quantities.names("trace", positive=True):
        assert np.all(np.asarray(cycles[name]) >= 0), name  # (a stick may be too short to see)


def test_positive_durations_are_the_log_scaled_ones():
    # the durations a fit takes on a log scale are exactly the positive durations it reads
    assert quantities.names("fit", positive=True) == ("slip_time", "stick_time", "period")
    for q in quantities.QUANTITIES.values():
        assert not q.positive or q.dimension == "time", q.name


def test_an_unknown_name_lists_the_known():
    with pytest.raises(KeyError, match="known: release_time, slip_time"):
        quantities.get("slip_tme")
