"""A campaign of measured runs: the public grid's short runs read from a campaign file,
the table, its files and the regime map; bad entries named in one line."""

import pathlib

import numpy as np
import pytest
import xarray as xr

import stickslip as ss
from stickslip.study import StudyError
from stickslip.study.campaign import Campaign

DATA = pathlib.Path(__file__).resolve().parents[1] / "examples" / "data" / "slider_paper_on_paper"
SCALE = 0.0307 * 9.81  # Fnorm = F / (m g)


def _yaml(tmp_path, entries) -> pathlib.Path:
    lines = ["runs:"]
    for e in entries:
        lines.append("  - " + "{" + ", ".join(f"{k}: {v}" for k, v in e.items()) + "}")
    path = tmp_path / "runs.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def _run(name, k, v):
    return dict(file=str(DATA / name), force="Fnorm", scale=SCALE, stiffness=k, v_b=v,
                mass=0.0307)  # fmt: skip


def test_a_campaign_reads_every_run_and_writes_its_table(tmp_path):
    path = _yaml(tmp_path, [_run("k168Nm_v1100.mat", 168, 1.1e-3),
                            _run("k168Nm_v4300.mat", 168, 4.3e-3),
                            _run("k2254Nm_v4300.mat", 2254, 4.3e-3)])  # fmt: skip
    c = Campaign.from_yaml(path)
    rows = c.table()
    assert [r["regime"] for r in rows] == ["stick-slip", "oscillation", "oscillation"]
    assert rows[0]["cycles"] == len(c.runs[0].cycles) > 90
    assert np.isnan(rows[1]["stick_time_median"]) and rows[1]["frequency"] > 10
    assert rows[0]["stick_time_p10"] <= rows[0]["stick_time_median"] <= rows[0]["stick_time_p90"]
    paths = c.write(tmp_path / "out", model=ss.get_model("rate-and-state").example())
    assert all(pathlib.Path(p).stat().st_size > 0 for p in paths)
    ds = xr.open_dataset(tmp_path / "out" / "runs.nc")
    assert list(ds["regime"].values) == ["stick-slip", "oscillation", "oscillation"]
    assert ds["stiffness"].values.tolist() == [168.0, 168.0, 2254.0]
    text = (tmp_path / "out" / "runs.csv").read_text().splitlines()
    assert text[0].startswith("# stickslip campaign") and text[1].startswith("name,stiffness")


def test_bad_campaign_entries_are_named(tmp_path):
    good = _run("k168Nm_v4300.mat", 168, 4.3e-3)
    with pytest.raises(StudyError, match=r"runs\.0\.stifness: is not a known key"):
        Campaign.from_yaml(_yaml(tmp_path, [{**good, "stifness": 1}]))
    with pytest.raises(StudyError, match=r"runs\.0\.v_b"):
        Campaign.from_yaml(_yaml(tmp_path, [{**good, "v_b": -1.0}]))
    with pytest.raises(StudyError, match=r"runs\.0\.file: .*no such file"):
        Campaign.from_yaml(_yaml(tmp_path, [{**good, "file": str(tmp_path / "none.mat")}]))
    with pytest.raises(StudyError, match=r"runs\.0\.file: .*must include t and F"):
        Campaign.from_yaml(_yaml(tmp_path, [{**good, "force": "F"}]))
    with pytest.raises(StudyError, match="no such file"):
        Campaign.from_yaml(tmp_path / "missing.yaml")


def test_the_campaign_command(tmp_path):
    from conftest import run_cli

    path = _yaml(tmp_path, [_run("k168Nm_v4300.mat", 168, 4.3e-3),
                            _run("k2254Nm_v4300.mat", 2254, 4.3e-3)])  # fmt: skip
    done = run_cli("campaign", path, "--out", "out", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "oscillation at" in done.stdout
    assert {p.name for p in (tmp_path / "out").iterdir()} >= {
        "runs.csv",
        "runs.nc",
        "regime_map.png",
        "runs.png",
    }
    again = run_cli("campaign", path, "--out", "out", cwd=tmp_path)
    assert again.returncode == 2 and "--force" in again.stderr
    assert run_cli("campaign", path, "--out", "out", "--force", cwd=tmp_path).returncode == 0
    (tmp_path / "bad.yaml").write_text("runs:\n  - {file: x.mat, stifness: 1, v_b: 1}\n")
    bad = run_cli("campaign", "bad.yaml", "--out", "out2", cwd=tmp_path)
    assert bad.returncode == 2 and "stifness" in bad.stderr and len(bad.stderr.splitlines()) == 1
    assert not (tmp_path / "out2").exists()
