"""Hostile or mistaken study files: each is answered at once with one short line naming the
field and the reason, exit 2, never echoing the file, and the file is left as it was.

The cases of issue 42: a sweep too large to build, a YAML alias bomb, thousands of nested
lists, binary and Latin-1 files, a byte-order mark (accepted), step counts t_max / dt past
the simulator's bound, parameters that overflow the model's formulas.
"""

from __future__ import annotations

import os
import random

import pytest
import yaml
from click.testing import CliRunner

from stickslip.cli import main
from stickslip.study import StudyError, load_study
from stickslip.study.load import MAX_DEPTH, MAX_NODES
from stickslip.study.schema import MAX_SWEEP_POINTS, Study, Sweep

STUDY = """\
title: hostile input
model:
  name: langevin
  params: {omega0: 1.0, zeta: 0.1, D: 0.4, v_b: 1.0, x0: 1.0, tau: 0.1}
simulation: {n_paths: 200, dt: 0.01, t_max: 30}
outputs: [slip_time]
"""


@pytest.fixture(autouse=True)
def _no_points(monkeypatch):
    """A refused study must not be expanded into its sweep points first."""
    calls = []
    original = Study.points

    def counted(self):
        calls.append(self)
        return original(self)

    monkeypatch.setattr(Study, "points", counted)
    return calls


def check_refused(
    tmp_path, content: bytes | str, *argv, field: str, words=(), partial: bool = False
) -> str:
    """`stickslip validate` of a study with `content`: exit 2, one short printable line
    naming `field` (or a field under it, if `partial`), the file unchanged."""
    path = tmp_path / "study.yaml"
    raw = content if isinstance(content, bytes) else content.encode("utf-8")
    path.write_bytes(raw)
    result = CliRunner().invoke(main, ["validate", str(path), *argv])
    assert "Traceback" not in result.stderr, result.stderr
    assert isinstance(result.exception, SystemExit | None), repr(result.exception)
    assert result.exit_code == 2, (result.exit_code, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    line = lines[0]
    assert line.isprintable() and len(line) <= 310, line
    prefix = f"error: {path}: {field}"
    if not field:
        prefix = f"error: {path}:"
    assert line.startswith(prefix) and line[len(prefix)] in (":." if partial else ": "), line
    for w in words:
        assert w in line, line
    assert result.stdout == ""
    assert path.read_bytes() == raw
    return line


# -- sweeps: counted before anything is built ---------------------------------------------------
def test_a_sweep_of_a_million_points_is_refused_at_once(tmp_path, _no_points):
    values = ", ".join(str(1 + i / 1000) for i in range(1000))
    text = STUDY + (
        f"sweep:\n  parameters:\n    model.params.v_b: [{values}]\n    model.params.D: [{values}]\n"
    )
    check_refused(
        tmp_path, text, field="sweep.parameters", words=["1000000 points", f"{MAX_SWEEP_POINTS}"]
    )
    assert _no_points == []


def test_sweep_size_limit_is_the_product_or_the_common_length():
    ok = Sweep(parameters={"a": list(range(100)), "b": list(range(100))})
    assert ok.size() == MAX_SWEEP_POINTS == len(ok.points())
    with pytest.raises(ValueError, match="10100 points .100 x 101 values. is past the limit"):
        Sweep(parameters={"a": list(range(100)), "b": list(range(101))})
    zipped = {"a": list(range(MAX_SWEEP_POINTS + 1)), "b": list(range(MAX_SWEEP_POINTS + 1))}
    with pytest.raises(ValueError, match="10001 points .values side by side."):
        Sweep(parameters=zipped, mode="zip")


def test_sweep_command_counts_its_points(tmp_path, _no_points):
    (tmp_path / "s.yaml").write_text(STUDY)
    values = ",".join(str(1 + i / 1000) for i in range(200))
    result = CliRunner().invoke(
        main,
        ["sweep", str(tmp_path / "s.yaml"), "-p", f"model.params.v_b={values}", "-p",
         f"model.params.D={values}", "-p", f"model.params.zeta={values[:40]}", "--out",
         str(tmp_path / "out")],
    )  # fmt: skip
    assert result.exit_code == 2, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert "past the limit of 10000 points" in line and len(line) <= 310, line
    assert not (tmp_path / "out").exists() and _no_points == []


# -- YAML bombs and deep nesting ----------------------------------------------------------------
def _alias_bomb(levels: int = 7) -> str:
    """A 'billion laughs': each anchor is nine uses of the one before (9**8 values)."""
    text = STUDY + "sweep:\n  parameters:\n    model.params.v_b: [&a0 [0.1, 0.1, 0.1, 0.1, 0.1, "
    text += "0.1, 0.1, 0.1, 0.1]"
    for i in range(1, levels + 1):
        text += f", &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]"
    return text + "]\n"


def test_an_alias_bomb_is_refused_without_expanding_it(tmp_path):
    text = _alias_bomb()
    assert len(text) < 1000
    line = check_refused(
        tmp_path, text, field="sweep.parameters.model.params.v_b",
        words=[f"expands to more than {MAX_NODES} values"],
    )  # fmt: skip
    assert "0.1" not in line, line


def test_a_recursive_alias_is_refused(tmp_path):
    check_refused(tmp_path, STUDY + "description: &r [1, *r]\n", field="", words=["refers to"])


def test_aliases_nested_past_the_depth_limit_are_refused(tmp_path):
    text = STUDY + "x0: &d0 " + "[" * 10 + "1" + "]" * 10 + "\n"
    for i in range(1, 8):
        text += f"x{i}: &d{i} " + "[" * 10 + f"*d{i - 1}" + "]" * 10 + "\n"
    check_refused(tmp_path, text, field="x7", words=[f"nested deeper than {MAX_DEPTH} levels"])


def test_ten_thousand_nested_lists_are_refused(tmp_path):
    """Was a RecursionError (exit 1)."""
    text = STUDY + "description: " + "[" * 10_000 + "]" * 10_000 + "\n"
    check_refused(tmp_path, text, field="", words=[f"nested deeper than {MAX_DEPTH} levels"])


def test_an_ordinary_nesting_is_accepted():
    deep = STUDY + "analytic:\n  - {method: decoupling, order: 1}\n"
    assert load_study(yaml.safe_load(deep)).analytic[0].order == 1


def test_set_value_bomb_is_refused(tmp_path):
    (tmp_path / "s.yaml").write_text(STUDY)
    bomb = "[" * 5000 + "]" * 5000
    result = CliRunner().invoke(
        main, ["validate", str(tmp_path / "s.yaml"), "--set", f"title={bomb}"]
    )
    assert result.exit_code == 2, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("error: --set: title: ") and len(line) <= 310, line


# -- encodings -------------------------------------------------------------------------------------
def test_a_binary_file_is_refused_without_its_bytes(tmp_path):
    rng = random.Random(42)
    raw = bytes(rng.randrange(256) for _ in range(4000)) + b"\xff"
    line = check_refused(tmp_path, raw, field="", words=["is not a UTF-8 text file"])
    assert line.isascii()


def test_a_latin1_file_is_refused_without_its_text(tmp_path):
    raw = STUDY.replace("hostile input", "caf\xe9 cr\xe8me").encode("latin-1")
    line = check_refused(tmp_path, raw, field="", words=["is not a UTF-8 text file"])
    assert "caf" not in line and "cr" not in line.split(":")[-1], line


def test_control_characters_are_refused_in_one_line(tmp_path):
    raw = ("title: a\x00b\x1b[2J\n" + STUDY.split("\n", 1)[1]).encode()
    line = check_refused(tmp_path, raw, field="")
    assert "\x1b" not in line and "\x00" not in line


def test_a_byte_order_mark_is_accepted(tmp_path):
    path = tmp_path / "bom.yaml"
    path.write_bytes(b"\xef\xbb\xbf" + STUDY.encode())
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 0, result.stderr
    assert load_study(path).title == "hostile input"


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_an_endless_file_is_refused():
    result = CliRunner().invoke(main, ["validate", "/dev/zero"])
    assert result.exit_code == 2
    assert result.stderr.strip().splitlines() == [
        "error: /dev/zero: is larger than 10 MiB: not a study file"
    ]


# -- limits of the numbers -------------------------------------------------------------------
@pytest.mark.parametrize(
    "old, new, field",
    [
        ("dt: 0.01", "dt: 1e-300", "simulation.t_max"),
        ("t_max: 30", "t_max: 1e308", "simulation.t_max"),
        ("t_max: 30", "t_max: 30, cycles: {dt: 1e-12}", "simulation.cycles.t_max"),
    ],
    ids=["dt-1e-300", "t_max-1e308", "cycles-dt"],
)
def test_step_counts_past_the_simulator_bound_are_refused(tmp_path, old, new, field):
    """Passed `validate` and failed in `run`."""
    line = check_refused(
        tmp_path, STUDY.replace(old, new), field=field, words=["t_max / dt", "2**30"]
    )
    assert "raise dt or lower t_max" in line


def test_step_count_in_a_sweep_names_the_value(tmp_path):
    text = STUDY + "sweep:\n  parameters:\n    simulation.dt: [0.01, 1e-300]\n"
    check_refused(tmp_path, text, field="sweep.parameters.simulation.dt.1", words=["2**30"])


def test_step_count_bound_is_the_simulators():
    """A study at the bound's edge validates; one step more is refused (as simulate does)."""
    data = yaml.safe_load(STUDY)
    data["simulation"] = {"n_paths": 200, "dt": 1.0, "t_max": float(2**30 - 1)}
    load_study(data)
    data["simulation"]["t_max"] = float(2**30)
    with pytest.raises(StudyError, match="simulation.t_max: t_max / dt = 1.07e\\+09"):
        load_study(data)


def test_step_too_fine_for_float64_is_refused(tmp_path):
    """Was a LinAlgError (dt = 5e-324) or every path stuck in its first step (dt = 1e-8)."""
    fine = "dt: 1e-8, t_max: 1e-6, cycles: {t_max: 1e-6}"
    line = check_refused(
        tmp_path, STUDY.replace("dt: 0.01, t_max: 30", fine), field="simulation.dt",
        words=["too fine", "take dt >= 1e-06"],
    )  # fmt: skip
    assert "1e-08" in line


def test_omega0_that_overflows_is_refused(tmp_path):
    """Was an OverflowError from `validate` (exit 1)."""
    check_refused(
        tmp_path, STUDY.replace("omega0: 1.0", "omega0: 1e300"), field="model.params",
        words=["omega0", "1e+300"], partial=True,
    )  # fmt: skip


def test_a_model_whose_formulas_overflow_is_refused_where_it_is_built(tmp_path, monkeypatch):
    """Whatever a plugin's own checks miss: an arithmetic error in its formulas is bad
    input located at model.params (naming the largest value), not a crash of validate."""
    from stickslip._registry import list_models

    def overflow(self):
        raise OverflowError(34, "Numerical result out of range")

    monkeypatch.setattr(list_models()["langevin"], "linear_gaussian", overflow)
    check_refused(
        tmp_path, STUDY.replace("x0: 1.0", "x0: 12345.0"), field="model.params",
        words=["overflow langevin's formulas (OverflowError)", "largest is x0 = 12345"],
    )  # fmt: skip


def test_fit_n_sim_past_the_simulator_is_named(tmp_path):
    text = STUDY + "fit: {data: c.csv, free: {D: [0.1, 1]}, n_sim: 1000000000000}\n"
    check_refused(tmp_path, text, field="fit.n_sim", words=["<= 4294967295"])


def test_fit_intervals_other_than_wald_or_profile_are_named(tmp_path):
    text = STUDY + "fit: {data: c.csv, free: {D: [0.1, 1]}, intervals: exact}\n"
    check_refused(tmp_path, text, field="fit.intervals", words=["wald", "profile"])


# -- messages stay short and do not echo the file ------------------------------------------------
def test_a_huge_value_is_cut_in_the_message(tmp_path):
    text = STUDY.replace("zeta: 0.1", "zeta: '" + "z" * 20_000 + "'")
    line = check_refused(tmp_path, text, field="model.params.zeta")
    assert "z" * 100 not in line and "..." in line, line


def test_a_huge_sweep_value_is_cut_in_the_message(tmp_path):
    text = STUDY + "sweep:\n  parameters:\n    model.params.v_b: [1, '" + "v" * 20_000 + "']\n"
    line = check_refused(tmp_path, text, field="sweep.parameters.model.params.v_b.1")
    assert "v" * 100 not in line, line


RANDOM_THRESHOLD = {
    "model": {
        "name": "random-threshold",
        "params": {"omega0": 1.0, "zeta": 0.1, "D": 0.4, "v_b": 1.0, "tau": 0.1,
                   "threshold": "normal", "threshold_params": {"mean": 1.0, "sd": 0.3}},
    },
    "simulation": {"n_paths": 300, "dt": 0.2, "t_max": 10},
}  # fmt: skip


def test_a_nested_free_parameter_is_checked_against_the_model_params():
    """`fit.free.threshold_params.sd` is a parameter of the threshold law (fit takes dotted
    names); a misspelt entry is named with the entries there are."""
    fit = {"data": "cycles.csv", "n_sim": 1000}
    Study.model_validate(
        RANDOM_THRESHOLD | {"fit": fit | {"free": {"threshold_params.sd": [0.05, 1]}}}
    )
    with pytest.raises(StudyError, match=r"fit\.free\.threshold_params\.sdx.*entries: mean, sd"):
        load_study(RANDOM_THRESHOLD | {"fit": fit | {"free": {"threshold_params.sdx": [0.05, 1]}}})


def test_a_yaml_merge_key_is_named_not_called_a_syntax_error(tmp_path):
    text = STUDY + "base: &p {v_b: 1.0}\nmore:\n  <<: *p\n  D: 0.4\n"
    line = check_refused(tmp_path, text, field="", words=["merge key '<<'", "line 9"])
    assert "syntax error" not in line
