"""`analyse_run`: every regime of a measured run.

The public paper-on-paper grid (examples/data/slider_paper_on_paper, credit and licence in
its README) read as a physicist reads it: stick-slip at k = 168 and 1002 N/m (42 um/s) and at
k = 168 (1100 um/s, rounded slips), oscillation for the three 4300 um/s runs, their
frequencies within 10 % of the peak of a plain periodogram (numpy's FFT of the whole record,
not the Welch spectrum the code uses). The 1100 um/s run against independent peak detectors
(94-113 slips over 14.4 s, median period 0.12-0.15 s). Synthetic traces with known answers:
the independent generator's stick-slip, a sinusoid in noise, noise alone.
"""

import pathlib
import warnings

import numpy as np
import pytest
from conftest import benchmark_module

import stickslip as ss

ROOT = pathlib.Path(__file__).resolve().parents[1]
DATA = ROOT / "examples" / "data" / "slider_paper_on_paper"
MASS, G = 0.0307, 9.81


def _load(name):
    from scipy.io import loadmat

    raw = loadmat(DATA / name)
    return raw["t"].ravel(), raw["Fnorm"].ravel() * MASS * G


def _settings(name):
    k = float(name[1 : name.index("Nm")])
    v = float(name[name.index("_v") + 2 : -4]) * 1e-6
    return k, v


def _analyse(name):
    t, f = _load(name)
    k, v = _settings(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the loading slope against the nominal speed
        return ss.analyse_run(t, f, stiffness=k, v_b=v, mass=MASS, name=name), t, f


def _periodogram_peak(t, f):
    x = f - np.mean(f)
    power = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
    freq = np.fft.rfftfreq(x.size, d=float(np.median(np.diff(t))))
    usable = freq > 2.0  # above the drift
    return float(freq[usable][np.argmax(power[usable])])


@pytest.mark.parametrize("name", ["k168Nm_v4300.mat", "k1002Nm_v4300.mat", "k2254Nm_v4300.mat"])
def test_the_fast_runs_oscillate_at_their_spectral_peak(name):
    run, t, f = _analyse(name)
    assert run.regime == "oscillation", run.evidence
    assert run.cycles is None
    assert run.frequency == pytest.approx(_periodogram_peak(t, f), rel=0.10)
    from scipy.signal import medfilt

    assert run.amplitude == pytest.approx(np.std(medfilt(f, 5)), rel=0.2)  # spikes out
    assert "Hz" in run.evidence and "skewed" in run.evidence
    # extract_cycles refuses it naming the regime's evidence, not the units
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(ss.DataError, match="rises and falls alike") as err:
            k, v = _settings(name)
            ss.extract_cycles(t, force=f, stiffness=k, v_b=v)
    assert "units" not in str(err.value)


def test_the_rounded_stick_slip_at_1100_um_s_is_read():
    run, t, _ = _analyse("k168Nm_v1100.mat")
    assert run.regime == "stick-slip", run.evidence
    c = run.cycles
    assert 94 <= len(c) <= 113 + 5  # independent peak detectors: 94-113 slips
    assert 0.12 <= np.median(c["period"]) <= 0.15
    assert run.settings["stiffness"] == 168.0 and run.settings["mass"] == MASS


@pytest.mark.slow
@pytest.mark.parametrize("name", ["k168Nm_v42.mat", "k1002Nm_v42.mat"])
def test_the_slow_runs_are_stick_slip(name):
    run, _, _ = _analyse(name)
    assert run.regime == "stick-slip" and len(run.cycles) > 200, run.evidence


def _generator():
    return benchmark_module("independent_slider")


def test_synthetic_runs_of_each_regime():
    gen = _generator()
    rig = gen.Rig()
    t, f, truth = gen.make_trace(4, 60.0, rig)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = ss.analyse_run(t, f, stiffness=rig.stiffness, v_b=rig.v_b)
    assert run.regime == "stick-slip" and len(run.cycles) > 30
    rng = np.random.default_rng(8)
    t = np.arange(8000) / 2000.0
    wave = 0.1 + 0.01 * np.sin(2 * np.pi * 23.0 * t + 0.3) + rng.normal(0, 3e-4, t.size)
    run = ss.analyse_run(t, wave, stiffness=500.0, v_b=4e-3, mass=0.02)
    assert run.regime == "oscillation"
    assert run.frequency == pytest.approx(23.0, rel=0.02)
    assert run.amplitude == pytest.approx(0.01 / np.sqrt(2), rel=0.05)
    flat = 0.1 + rng.normal(0, 3e-4, t.size)
    run = ss.analyse_run(t, flat, stiffness=500.0, v_b=4e-3)
    assert run.regime == "steady sliding"
    assert run.mean_force == pytest.approx(0.1, abs=3e-5)
    assert run.noise_sd == pytest.approx(3e-4, rel=0.1)
    assert "steady sliding" in repr(run)


def test_bad_arguments_are_named():
    t = np.arange(1000) / 2000.0
    f = 0.1 + 0.0 * t
    with pytest.raises(ss.ParameterError, match="stiffness"):
        ss.analyse_run(t, f, stiffness=-1.0, v_b=1e-3)
    with pytest.raises(ss.ParameterError, match="mass"):
        ss.analyse_run(t, f, stiffness=1.0, v_b=1e-3, mass=0.0)


def test_the_cycles_command_names_the_regime_of_a_run_without_cycles(tmp_path):
    from conftest import run_cli

    t, f = _load("k168Nm_v4300.mat")
    np.savetxt(tmp_path / "fast.csv", np.c_[t, f / (MASS * G)], delimiter=",",
               header="t,Fnorm", comments="")  # fmt: skip
    done = run_cli("cycles", "fast.csv", "--force-column", "Fnorm", "--force-scale",
                   MASS * G, "--stiffness", 168, "--v-b", 4.3e-3, cwd=tmp_path)  # fmt: skip
    assert done.returncode == 2
    assert "the run is an oscillation" in done.stderr and "Hz" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
