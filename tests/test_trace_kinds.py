"""Kinds of trace as classes (`stickslip.trace_kinds`): the built-in kinds found through
their entry points, a user's kind (an encoder's whole counts) registered at run time and
read by `extract_cycles`, `Measurement.from_cycles` and the forward measurement with no
change to stickslip, checked against a trace built by hand and against the built-in
position measurement it reduces to when the counts are fine."""

from __future__ import annotations

import warnings
from importlib.metadata import EntryPoint

import numpy as np
import pytest

import stickslip as ss
from stickslip import _registry, _trace_kind
from stickslip._inference.measurement import Measurement, measured_cycles, measured_trace
from stickslip.trace_kinds import ForceTrace, MotionTrace

LANGEVIN = dict(omega0=1.0, zeta=0.1, v_b=0.3, x0=1.0, D=0.02, tau=0.1)


class EncoderTrace(MotionTrace):
    """A position read by an incremental encoder: whole counts of `resolution`."""

    name = "encoder"
    signals = ("encoder counts",)
    inputs = ("counts",)
    options = ("resolution", "tol", "min_stick")
    info_keys = (*MotionTrace.info_keys, "resolution")
    default = False

    def extract(self, t, given, v_b, options):
        options = dict(options)
        resolution = options.pop("resolution", None)
        if resolution is None:
            raise ss.ParameterError("extract_cycles", "resolution", "is required with counts")
        x = np.asarray(given["counts"], float) * resolution
        cycles = super().extract(t, {"x": x, "v": None}, v_b, options)
        cycles.info.update(input="encoder counts", resolution=resolution)
        return cycles

    def measurement(self, info, columns, scales):
        m = super().measurement({**info, "input": "x"}, columns, scales)
        # the rounding is part of the noise the extraction measured: not added twice
        rounding = info["resolution"] / np.sqrt(12.0)
        noise = np.sqrt(max(m["noise_sd"] ** 2 - rounding**2, 0.0))
        return {**m, "signal": "encoder counts", "noise_sd": noise,
                "options": {"resolution": info["resolution"]}}  # fmt: skip

    def settings(self, measurement, v_b):
        return {**super().settings(measurement, v_b), **dict(measurement.options)}

    def record(self, measurement, t, x, v, noise, rng):
        resolution = dict(measurement.options)["resolution"]
        return dict(t=t, counts=np.round((x + measurement.noise_sd * noise) / resolution))


@pytest.fixture
def encoder():
    ss.register_trace_kind("encoder-test", EncoderTrace)
    try:
        yield EncoderTrace
    finally:
        _trace_kind.TRACE_KINDS.runtime.pop("encoder-test", None)


def _hand_made(resolution, n=12, h=0.01, v_b=0.5, seed=1):
    """A stick-slip position built by hand: sticks at v_b, slips whose velocity dips
    below v_b as a half sine (amplitude 2 v_b), slip and stick times drawn; sampled at h."""
    rng = np.random.default_rng(seed)
    slip = rng.uniform(0.4, 0.8, n)
    stick = rng.uniform(0.6, 1.2, n)
    t = np.arange(0.0, float(np.sum(slip + stick)) + 0.5, h)
    v = np.full(t.size, v_b)
    start = 0.3
    for s, st in zip(slip, stick, strict=True):
        inside = (t >= start) & (t < start + s)
        v[inside] -= 2 * v_b * np.sin(np.pi * (t[inside] - start) / s)
        start += s + st
    x = np.r_[0.0, np.cumsum(0.5 * (v[1:] + v[:-1]) * h)]
    return t, np.round(x / resolution), slip, stick


def test_the_built_in_kinds_come_from_their_entry_points():
    kinds = ss.list_trace_kinds()
    assert kinds["force"] is ForceTrace and kinds["position-velocity"] is MotionTrace
    assert ss.get_trace_kind("force") is ForceTrace
    with pytest.raises(ss.PluginError, match=r"unknown trace kind 'nope'.*force"):
        ss.get_trace_kind("nope")
    with pytest.raises(TypeError):
        ss.register_trace_kind("bad", dict)


def test_a_broken_kind_plugin_warns_and_is_skipped():
    group = _registry.TRACE_KIND_GROUP
    with pytest.warns(_registry.PluginWarning, match=r"trace kind plugin 'x'.*not a subclass"):
        found = _trace_kind.TRACE_KINDS.load([EntryPoint("x", "collections:OrderedDict", group)])
    assert found == {}


def test_a_users_kind_reads_a_trace_built_by_hand(encoder):
    """The encoder's counts of a trace whose slips are known: every complete cycle found,
    each slip and stick time within a sampling interval of the construction."""
    t, counts, slip, stick = _hand_made(resolution=1e-5)
    found = ss.extract_cycles(t, counts=counts, resolution=1e-5, v_b=0.5)
    assert found.info["input"] == "encoder counts" and found.info["resolution"] == 1e-5
    # the first slip starts the record (its release is seen), the last stick runs out
    assert len(found) == slip.size - 1
    np.testing.assert_allclose(found["slip_time"], slip[:-1], atol=0.01)
    np.testing.assert_allclose(found["stick_time"], stick[:-1], atol=0.01)


def test_a_users_kinds_inputs_and_settings_are_checked(encoder):
    t, counts, _, _ = _hand_made(resolution=1e-5)
    with pytest.raises(ss.ParameterError, match="'resolution' is required with counts"):
        ss.extract_cycles(t, counts=counts, v_b=0.5)
    with pytest.raises(ss.ParameterError, match="'counts' goes alone: give encoder or x/v"):
        ss.extract_cycles(t, x=counts, counts=counts, resolution=1e-5, v_b=0.5)
    with pytest.raises(ss.ParameterError, match="'window' applies to force traces only"):
        ss.extract_cycles(t, counts=counts, resolution=1e-5, v_b=0.5, window=11)
    with pytest.raises(ss.ParameterError, match="'pressure' is not an input or setting"):
        ss.extract_cycles(t, pressure=counts, v_b=0.5)
    with pytest.raises(ss.ParameterError, match="'resolution' applies to encoder traces only"):
        ss.extract_cycles(t, x=counts * 1e-5, v_b=0.5, resolution=1e-5)


def test_measurement_fields_belong_to_their_kind():
    with pytest.raises(ss.ParameterError, match="'tol' applies to x/v traces only"):
        Measurement(sampling_interval=0.1, signal="force", tol=0.1)
    with pytest.raises(ss.ParameterError, match="'lines' applies to force traces only"):
        Measurement(sampling_interval=0.1, signal="v", lines=(0.5,))
    with pytest.raises(ss.ParameterError, match="peak_force needs a force trace"):
        Measurement(sampling_interval=0.1, signal="x", columns=("slip_time", "peak_force"))
    with pytest.raises(ss.ParameterError, match="'signal' must be one of 'force', 'x'"):
        Measurement(sampling_interval=0.1, signal="pressure")
    assert Measurement(sampling_interval=0.1, signal="force").kind.name == "force"


def test_a_users_kind_through_the_forward_measurement(encoder):
    """At counts far finer than the noise, the encoder's measurement gives the cycles of
    the built-in position measurement of the same seed (the same keyed grid and noise),
    to the extraction's rounding; at coarse counts each recorded count lies within half a
    count of the noisy position."""
    model = ss.get_model("langevin")(**LANGEVIN)
    fine = Measurement(sampling_interval=0.05, signal="encoder counts", noise_sd=1e-3,
                       min_stick=2, options={"resolution": 1e-9})  # fmt: skip
    plain = Measurement(sampling_interval=0.05, signal="x", noise_sd=1e-3, min_stick=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = measured_cycles(model, fine, 200, 3)
        b = measured_cycles(model, plain, 200, 3)
    assert a["slip_time"].size == b["slip_time"].size > 150
    for k in plain.columns:
        np.testing.assert_allclose(a[k], b[k], rtol=0, atol=1e-6)
    coarse = Measurement(sampling_interval=0.05, signal="encoder counts", noise_sd=1e-3,
                         min_stick=2, options={"resolution": 0.01})  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        counts = measured_trace(model, coarse, 100, 3).traces[0]
        x = measured_trace(model, plain, 100, 3).traces[0]
    np.testing.assert_array_equal(counts["t"], x["t"])
    assert np.all(counts["counts"] == np.round(counts["counts"]))
    assert np.max(np.abs(counts["counts"] * 0.01 - x["x"])) <= 0.005 + 1e-12


def test_the_measurement_of_a_users_kind_is_read_back(encoder):
    t, counts, _, _ = _hand_made(resolution=1e-5)
    found = ss.extract_cycles(t, counts=counts, resolution=1e-5, v_b=0.5)
    m = Measurement.from_cycles(found)
    assert m.signal == "encoder counts" and dict(m.options) == {"resolution": 1e-5}
    assert isinstance(m.kind, EncoderTrace)
    assert m.extract_settings(0.5) == dict(v_b=0.5, tol=None, min_stick=2, resolution=1e-5)
    again = ss.read_cycles(_written(found))
    assert Measurement.from_cycles(again) == m


def _written(cycles):
    import tempfile

    with tempfile.NamedTemporaryFile("w", suffix=".csv", delete=False) as f:
        f.write(cycles.to_csv())
    return f.name


def test_the_cycles_command_reads_a_users_kind(encoder, tmp_path):
    from conftest import run_cli

    t, counts, slip, _ = _hand_made(resolution=1e-5)
    lines = ["t,counts"] + [f"{a:.17g},{c:.17g}" for a, c in zip(t, counts, strict=True)]
    (tmp_path / "enc.csv").write_text("\n".join(lines) + "\n")
    done = run_cli("cycles", "enc.csv", "--kind", "encoder-test", "--option", "resolution=1e-5",
                   "--v-b", "0.5", "--out", "c.csv", cwd=tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    found = ss.read_cycles(tmp_path / "c.csv")
    assert found.info["input"] == "encoder counts" and len(found) == slip.size - 1
    for args, said in (
        (("--option", "resolution=1e-5"), "--option: applies with --kind only"),
        (("--kind", "force"), "names a plugin's kind"),
        (("--kind", "nope"), "unknown trace kind 'nope'"),
        (("--kind", "encoder-test", "--tol", "0.1"), "--tol: applies to the built-in kinds"),
    ):
        done = run_cli("cycles", "enc.csv", "--v-b", "0.5", *args, cwd=tmp_path)
        assert done.returncode == 2 and said in done.stderr, done.stderr


def test_an_unset_setting_of_another_kind_is_no_setting():
    """An empty list of lines on a position measurement is no setting (as before); a
    kind that lists a field `Measurement` does not have breaks no measurement."""
    assert Measurement(sampling_interval=0.1, signal="x", lines=[]).lines == ()

    class Odd(MotionTrace):
        name, signals, inputs, fields, default = "odd", ("odd",), ("odd_x",), ("nope",), False

    ss.register_trace_kind("odd-test", Odd)
    try:
        assert Measurement(sampling_interval=0.1, signal="force").kind.name == "force"
    finally:
        _trace_kind.TRACE_KINDS.runtime.pop("odd-test", None)


def test_a_law_error_lists_the_parameters_plainly():
    law = ss.get_model("random-threshold")
    with pytest.raises(ss.ParameterError, match=r"'threshold_params.sd' is required by the "
                       r"normal law \(it takes mean, sd\)"):  # fmt: skip
        law(omega0=1.0, zeta=0.1, D=0.1, v_b=1.0, threshold="normal",
            threshold_params={"mean": 1.0})  # fmt: skip
