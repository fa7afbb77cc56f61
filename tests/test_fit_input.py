"""Bad input to `fit` and to `stickslip fit` (issue 42): refused before anything is simulated,
as one line that names the field and states the evidence, never quoting the data file; the
data file is left as it was and nothing is written."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

import stickslip as ss
from stickslip._inference import data as fit_data
from stickslip._inference import likelihood, params
from stickslip.cli import main
from stickslip.extract import Cycles
from stickslip.study import fitting

BASE = dict(omega0=1.0, zeta=0.1, v_b=1.0, x0=1.0)
FIXED = BASE | {"tau": 0.1}
GOOD = np.random.default_rng(42).exponential(1.0, 300)  # 300 distinct positive durations


@pytest.fixture(autouse=True)
def no_simulation(monkeypatch):
    """Every case here must be refused before the first simulation."""

    def refuse(*args, **kwargs):
        raise AssertionError("fit simulated: the bad input was not refused up front")

    monkeypatch.setattr(likelihood, "simulate_values", refuse)


def refused(cls, data, free=None, fixed=FIXED, **kwargs) -> str:
    """The message of the `cls` error `fit` raises, checked to be one short line, with any
    warning (NumPy's RuntimeWarnings among them) turned into a failure."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(cls) as err:
            ss.fit("langevin", data, free or {"D": (0.1, 1.0)}, fixed, **kwargs)
    text = str(err.value)
    assert isinstance(err.value, ss.StickSlipError)
    assert "\n" not in text and len(text) <= 300 and text.isprintable(), text
    return text


# -- degenerate data: the Python API -----------------------------------------------------
def test_constant_data_is_refused_with_the_evidence():
    text = refused(ss.DataError, {"slip_time": np.full(10, 2.5)})
    assert "slip_time" in text and "constant" in text
    assert "10 cycles" in text and "1 distinct value" in text


def test_too_few_cycles_states_the_minimum():
    text = refused(ss.DataError, {"slip_time": GOOD[:9]})
    assert "too few cycles" in text and "9 cycles" in text and f"{fit_data.MIN_CYCLES}" in text


def test_too_few_distinct_values():
    x = np.repeat(GOOD[:4], 25)  # 100 cycles on 4 levels
    text = refused(ss.DataError, {"period": x})
    assert "100 cycles" in text and "4 distinct values" in text


def test_distinct_values_are_counted_to_nine_digits():
    """Values that differ in the 12th digit are one level; at the 6th they are distinct."""
    x = 1.0 + 1e-12 * np.arange(50)
    assert "1 distinct value" in refused(ss.DataError, {"slip_time": x})
    y = 1.0 + 1e-6 * np.arange(50)
    np.testing.assert_array_equal(fit_data.check_data({"slip_time": y})["slip_time"], y)


def test_a_stick_time_column_of_zeros_has_no_positive_values():
    text = refused(ss.DataError, {"stick_time": np.zeros(50)})
    assert "too few positive values" in text and "0 of them positive" in text


def test_a_two_dimensional_column_is_not_counted_twice():
    text = refused(ss.DataError, {"slip_time": np.c_[GOOD, GOOD]})
    assert "(300, 2)" in text and "1-D" in text


@pytest.mark.parametrize(
    "value, says",
    [
        ([f"{v:.4f}" for v in GOOD], "strings"),
        ("1.0, 2.0", "strings"),
        (None, "NoneType"),
        ([1.0, "2.0"] * 20, "strings"),
        (np.array([1.0, None] * 20, dtype=object), "other objects"),
        ([[1.0, 2.0], [3.0]], "ragged"),
        (GOOD > 1, "booleans"),
    ],
)
def test_data_that_are_not_numbers(value, says):
    text = refused(ss.DataError, {"slip_time": value})
    assert says in text and "data['slip_time']" in text


def test_non_finite_values_are_refused_with_their_rows():
    x = GOOD.copy()
    x[[3, 17, 250]] = [np.nan, np.inf, -np.inf]
    text = refused(ss.DataError, {"slip_time": x})
    assert "3 non-finite values" in text and "rows 3, 17, 250" in text
    y = GOOD.copy()
    y[np.arange(0, 300, 30)] = np.nan
    assert "rows 0, 30, 60, 90, 120 and 5 more" in refused(ss.DataError, {"period": y})


def test_slip_distances_too_large_to_take_a_spread_of():
    text = refused(ss.DataError, {"slip_distance": GOOD * 1e300})
    assert "slip_distance" in text and "overflow" in text


INFO = dict(input="x", sampling_interval=0.01, noise_sd=0.01, min_stick=2, tol_rule="given",
            tol=0.05)  # fmt: skip


def test_a_cycles_object_is_checked_as_its_columns_are_fitted():
    """A `Cycles`' release times are not fitted (a constant column there is no matter); its
    slip distances are, through the measurement: a constant one is refused."""
    table = {k: np.full(20, 2.0) for k in ("release_time", "slip_distance")}
    table |= {"slip_time": GOOD[:20], "stick_time": GOOD[:20], "period": 2 * GOOD[:20]}
    text = refused(ss.DataError, Cycles(table, INFO))
    assert "'data['slip_distance']' is constant" in text


# -- arguments named as fit names them ---------------------------------------------------
def test_huge_n_sim_is_a_resource_error_with_the_figure():
    text = refused(ss.ResourceError, {"slip_time": GOOD}, n_sim=10**12)
    assert "'n_sim'" in text and "GiB" in text and "limit" in text


def test_memory_limit_boundary(monkeypatch):
    """The estimate is linear in n_sim: at the limit it passes (and the constant data are
    what is refused next), one cycle above it it is refused."""
    per_cycle = params.SIM_BYTES_PER_STATE * 3  # langevin: x, v, eta
    monkeypatch.setenv("STICKSLIP_MEMORY_LIMIT", str(5000 * per_cycle))
    refused(ss.DataError, {"slip_time": np.ones(20)}, n_sim=5000)
    text = refused(ss.ResourceError, {"slip_time": np.ones(20)}, n_sim=5001)
    assert "take at most 5e+03" in text


@pytest.mark.parametrize(
    "free, parameter",
    [
        ({"tau": (-1.0, 1.0)}, "free['tau']"),  # the centre, 0, is refused
        ({"tau": (0.0, 1.0)}, "free['tau']"),  # an end is refused
        ({"D": (-2.0, 1.0)}, "free['D']"),
        ({"tua": (0.01, 1.0)}, "free['tua']"),
        ({"D": (1.0, 0.1)}, "free['D']"),
        ({"D": (0.1, float("inf"))}, "free['D']"),
    ],
)
def test_a_bad_box_names_its_free_entry(free, parameter):
    fixed = {k: v for k, v in (FIXED | {"D": 0.4}).items() if k not in free}
    with pytest.raises(ss.ParameterError) as err:
        ss.fit("langevin", {"slip_time": GOOD}, free, fixed)
    assert err.value.owner == "fit" and err.value.parameter == parameter, str(err.value)


def test_a_bad_fixed_value_names_it():
    with pytest.raises(ss.ParameterError) as err:
        ss.fit("langevin", {"slip_time": GOOD}, {"D": (0.1, 1.0)}, FIXED | {"omega0": -1.0})
    assert err.value.parameter == "fixed['omega0']"


def test_cycles_without_their_extraction_settings_are_refused_naming_data():
    """A `Cycles` from an older file (only its sampling interval) cannot have its
    measurement modelled: refused up front, naming what it lacks."""
    table = dict(release_time=np.cumsum(GOOD + 1.0), slip_time=GOOD + 0.5,
                 slip_distance=GOOD, stick_time=GOOD + 0.5, period=2 * GOOD + 1.0)  # fmt: skip
    with pytest.raises(ss.ParameterError) as err:
        ss.fit("langevin", Cycles(table, {"sampling_interval": 0.1}), {"D": (0.1, 1.0)}, FIXED)
    assert err.value.parameter == "data" and "lacks input" in str(err.value)


@pytest.mark.parametrize(
    "kwargs, parameter",
    [
        (dict(trace="yes", sampling=0.1), "trace"),
        (dict(dt="abc"), "dt"),
        (dict(t_max=-1.0), "t_max"),
        (dict(t_max=1e308), "t_max"),  # 5e308 steps
        (dict(dt=1e-300), "t_max"),  # the default t_max over that step
        (dict(dt=1e6), "dt"),  # past the default t_max
        (dict(seed=-1), "seed"),
        (dict(seed=2**70), "seed"),
        (dict(n_sim=10.5), "n_sim"),
    ],
)
def test_bad_settings_name_themselves(kwargs, parameter):
    with pytest.raises(ss.ParameterError) as err:
        ss.fit("langevin", {"slip_time": GOOD}, {"D": (0.1, 1.0)}, FIXED, **kwargs)
    assert err.value.owner == "fit" and err.value.parameter == parameter, str(err.value)


def test_data_in_the_wrong_time_unit_name_the_default_t_max():
    with pytest.raises(ss.ParameterError, match="by default 3 x the data's longest") as err:
        ss.fit("langevin", {"slip_time": GOOD * 1e300}, {"D": (0.1, 1.0)}, FIXED)
    assert err.value.parameter == "t_max"


def test_a_chain_model_is_refused():
    with pytest.raises(ss.ParameterError, match="chain of blocks"):
        ss.fit("burridge-knopoff", {"slip_time": GOOD}, {"D": (0.1, 1.0)})


def test_a_wrong_signature_is_still_a_type_error():
    with pytest.raises(TypeError) as err:
        ss.fit("langevin", {"slip_time": GOOD})  # no free
    assert not isinstance(err.value, ss.StickSlipError)
    with pytest.raises(TypeError):
        ss.fit("langevin", {"slip_time": GOOD}, {"D": (0.1, 1.0)}, FIXED, nsim=5000)


# -- the data file: read_cycles_csv ------------------------------------------------------
def write_csv(path, x, header="slip_time", prefix=""):
    path.write_text(prefix + header + "\n" + "".join(f"{float(v)!r}\n" for v in x))
    return path


def test_a_byte_order_mark_is_accepted(tmp_path):
    plain = fitting.read_cycles_csv(write_csv(tmp_path / "a.csv", GOOD))
    marked = fitting.read_cycles_csv(write_csv(tmp_path / "b.csv", GOOD, prefix="\ufeff"))
    np.testing.assert_array_equal(marked["slip_time"], GOOD)
    np.testing.assert_array_equal(plain["slip_time"], marked["slip_time"])


def test_only_the_columns_asked_for_must_be_numbers(tmp_path):
    path = tmp_path / "c.csv"
    path.write_text(
        "label,slip_time\n" + "".join(f"cycle {i},{float(v)!r}\n" for i, v in enumerate(GOOD))
    )
    data = fitting.read_cycles_csv(path)
    assert list(data) == ["slip_time"]
    np.testing.assert_array_equal(data["slip_time"], GOOD)


def test_the_size_cap_is_checked_before_reading(tmp_path, monkeypatch):
    path = write_csv(tmp_path / "big.csv", GOOD)
    monkeypatch.setattr(fitting, "MAX_DATA_BYTES", path.stat().st_size - 1)
    with pytest.raises(ss.StudyError, match="past the limit of .* MiB"):
        fitting.read_cycles_csv(path)
    monkeypatch.setattr(fitting, "MAX_DATA_BYTES", path.stat().st_size)
    assert fitting.read_cycles_csv(path)["slip_time"].size == GOOD.size


# -- stickslip fit: one line, exit 2, the data intact, nothing written -------------------
def study(tmp_path, data="cycles.csv", free=None, **fit):
    spec = {
        "model": {"name": "langevin", "params": {**FIXED, "D": 0.4}},
        "fit": {"data": str(data), "free": free or {"D": [0.05, 2.0]}, "n_sim": 5000, **fit},
    }
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def fit_command(tmp_path, data_path=None) -> str:
    """Run `stickslip fit`; check exit 2, one printable line, the data file unchanged and no
    output; return the line."""
    before = data_path.read_bytes() if data_path is not None and data_path.is_file() else None
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["fit", str(tmp_path / "study.yaml"), "--out", str(out)])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    lines = result.stderr.strip().splitlines()
    assert result.exit_code == 2, result.stderr
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert len(lines[0]) <= 300 and lines[0].isprintable(), lines[0]
    assert not lines[0].endswith("..."), lines[0]  # the whole reason fits
    assert not out.exists()
    if before is not None:
        assert data_path.read_bytes() == before
    return lines[0]


def test_cli_constant_data(tmp_path):
    csv = write_csv(tmp_path / "cycles.csv", [2.5] * 10)
    study(tmp_path)
    line = fit_command(tmp_path, csv)
    assert "fit.data" in line and "column slip_time" in line and "constant" in line


def test_cli_non_finite_rows_are_reported_with_their_lines(tmp_path):
    x = [repr(float(v)) for v in GOOD[:40]]
    for i, bad in zip((3, 10, 20), ("nan", "inf", "-inf"), strict=True):
        x[i] = bad
    csv = tmp_path / "cycles.csv"
    csv.write_text("# cycles\nslip_time\n" + "\n".join(x) + "\n")  # data from line 3
    study(tmp_path)
    line = fit_command(tmp_path, csv)
    assert "fit.data" in line and "3 rows with nan or inf" in line
    assert "lines 6, 13, 23" in line


def test_cli_a_byte_order_mark_reaches_the_fit(tmp_path, monkeypatch):
    """The marked file is read (the fit then refuses an n_sim past the memory limit)."""
    monkeypatch.setenv("STICKSLIP_MEMORY_LIMIT", str(2**30))
    csv = write_csv(tmp_path / "cycles.csv", GOOD, prefix="\ufeff")
    study(tmp_path, n_sim=10**9)
    line = fit_command(tmp_path, csv)
    assert "fit.n_sim" in line and "GiB" in line and "limit of 1 GiB" in line


def test_cli_huge_n_sim_names_n_sim(tmp_path):
    csv = write_csv(tmp_path / "cycles.csv", GOOD)
    study(tmp_path, n_sim=10**12)
    line = fit_command(tmp_path, csv)
    assert "fit.n_sim" in line and "n_paths" not in line


def test_cli_a_bad_box_names_the_free_entry(tmp_path):
    csv = write_csv(tmp_path / "cycles.csv", GOOD)
    study(tmp_path, free={"tau": [-1.0, 1.0]})
    line = fit_command(tmp_path, csv)
    assert "fit.free.tau:" in line and "tau must be > 0" in line


def test_cli_trace_with_a_plain_table_names_trace(tmp_path):
    """The deprecated `trace: true` on a table without the cycles header: its measurement
    cannot be modelled, said at fit.trace."""
    csv = write_csv(tmp_path / "cycles.csv", GOOD)
    study(tmp_path, trace=True, sampling=0.1)
    with pytest.warns(DeprecationWarning, match="trace and sampling are deprecated"):
        line = fit_command(tmp_path, csv)
    assert "fit.trace:" in line and "stickslip cycles" in line


def test_cli_a_file_that_is_not_a_table_is_not_quoted(tmp_path):
    secret = tmp_path / "passwd"
    secret.write_text("root:x:0:0:hunter2:/root:/bin/bash\ndaemon:x:1:1::/:/bin/false\n")
    study(tmp_path, data=secret)
    line = fit_command(tmp_path, secret)
    assert "has no column" in line and "its first line has 1 field" in line
    assert "root" not in line.replace(str(tmp_path), "") and "hunter2" not in line


def test_cli_a_header_of_plain_names_is_not_quoted_either(tmp_path):
    csv = tmp_path / "cycles.csv"
    csv.write_text("hunter2,password\n1,2\n")
    study(tmp_path)
    line = fit_command(tmp_path, csv)
    assert "2 fields" in line and "hunter2" not in line and "password" not in line


def test_cli_a_trace_is_recognised_by_its_columns(tmp_path):
    csv = tmp_path / "cycles.csv"
    csv.write_text("t,x,v\n0,0,1\n")
    study(tmp_path)
    assert "stickslip cycles" in fit_command(tmp_path, csv)


@pytest.mark.parametrize(
    "content, says",
    [
        ("slip_time\n1.5\ncaf\xe9\n".encode("latin-1"), "not UTF-8 text"),
        (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(range(256)), "binary"),
        ("slip_time\n1.0\n".encode("utf-16"), "UTF-16"),
        ("slip_time,slip_time\n1,2\n", "2 times"),
        ("slip_time\n1\nabc\n", "line 3, column slip_time"),
        ("slip_time,period\n1,2\n3\n", "line 3 has 1 value,"),
        ("slip_time\n1\n0\n-2\n", "2 values <= 0"),
        ("", "is empty"),
    ],
)
def test_cli_unreadable_files_are_one_line_without_their_bytes(tmp_path, content, says):
    csv = tmp_path / "cycles.csv"
    if isinstance(content, bytes):
        csv.write_bytes(content)
    else:
        csv.write_text(content)
    study(tmp_path)
    line = fit_command(tmp_path, csv)
    assert "fit.data" in line and says in line, line
    assert "caf" not in line and "PNG" not in line and "abc" not in line
    assert line.isascii()


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="no /dev/zero")
@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_cli_an_endless_device_is_not_read(tmp_path, device):
    study(tmp_path, data=device)
    assert "not a regular file" in fit_command(tmp_path)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes")
def test_cli_a_named_pipe_is_not_opened(tmp_path):
    """Opening a pipe with no writer would block forever: it is refused from its type."""
    os.mkfifo(tmp_path / "cycles.csv")
    study(tmp_path)
    assert "not a regular file" in fit_command(tmp_path)


def test_cli_a_folder_or_a_missing_file(tmp_path):
    (tmp_path / "cycles").mkdir()
    study(tmp_path, data="cycles")
    assert "is a folder" in fit_command(tmp_path)
    study(tmp_path, data="missing.csv")
    assert "does not exist" in fit_command(tmp_path)
