"""Studies end to end: the runner's dataset, the files it writes, atomic writes, library
parity with the CLI, and every example study in a reduced form."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

import stickslip as ss
from stickslip.cli import main

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"
PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)


def small_study(**extra):
    study = {
        "title": "small",
        "model": {"name": "langevin", "params": dict(PUBLIC)},
        "simulation": {"n_paths": 4000, "dt": 0.005, "t_max": 20.0, "seed": 3},
        "analytic": [{"method": "decoupling", "order": 1}],
        "outputs": ["slip_time", "period", "slip_distance", "n1"],
        "grid": {"slip_time": {"start": 0, "stop": 12, "bins": 60}, "n1": {"stop": 12, "bins": 60}},
    }
    study.update(extra)
    return study


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    out = tmp_path_factory.mktemp("small") / "results"
    ds = ss.run_study(small_study(), out, progress=False)
    return ds, out


def test_dataset_layout(small):
    ds, _ = small
    assert ds.sizes["slip_time"] == 60 and ds.sizes["slip_time_edge"] == 61
    assert list(ds["method"].values) == ["Fg1"]
    for name in ("mc_slip_time", "mc_slip_time_se", "theory_slip_time", "l1_slip_time",
                 "mc_period", "theory_period", "mc_slip_distance", "theory_n1", "mc_n1",
                 "fraction_stuck", "mean_slip_time", "seconds_simulation"):  # fmt: skip
        assert name in ds, name
    assert ds.attrs["stickslip_version"] == ss.__version__
    assert "langevin" in ds.attrs["study"]
    assert ds["slip_time"].attrs["units"] == "time units"
    # the histogram integrates to the share of paths that stuck with a slip in the window
    e = ds["slip_time_edges"].values
    ens_mass = float(np.sum(ds["mc_slip_time"].values * np.diff(e)))
    assert 0.9 < ens_mass <= 1.0


def test_n1_matches_exact_theory(small):
    """Exact Rice n1 against the simulated upcrossings, cell by cell: a chi-square statistic
    from the standard errors (cells with fewer than 20 counts are left out)."""
    from scipy import stats

    ds, _ = small
    mc, se, th = ds["mc_n1"].values, ds["mc_n1_se"].values, ds["theory_n1"].values
    width = np.diff(ds["n1_edges"].values)
    counts = mc * 4000 * width
    ok = np.isfinite(mc) & (counts >= 20)
    chi2 = float(np.sum(((mc - th) / se)[ok] ** 2))
    assert stats.chi2.sf(chi2, ok.sum()) > 1e-3, (chi2, ok.sum())


def test_files_written(small):
    ds, out = small
    names = {p.name for p in out.iterdir()}
    assert {"results.nc", "summary.md", "study.yaml", "slip_time.png", "period.png",
            "slip_distance.png", "n1.png"} <= names  # fmt: skip
    back = xr.open_dataset(out / "results.nc", engine="h5netcdf")
    np.testing.assert_array_equal(back["mc_slip_time"].values, ds["mc_slip_time"].values)
    assert back.attrs["study"] == ds.attrs["study"]
    back.close()
    summary = (out / "summary.md").read_text()
    assert "| `Fg1`" in summary and "L1" in summary and "Wall time" in summary
    # the study as run reproduces itself
    again = ss.load_study(out / "study.yaml")
    assert again.model.instance.params() == ss.load_study(small_study()).model.instance.params()
    assert not list(out.parent.glob(".results.partial-*"))


def test_results_file_is_the_one_xarray_writes(small, tmp_path):
    """`results.nc` goes through the h5netcdf store directly (not `to_netcdf`, which would
    import `distributed` to ask Dask for its scheduler): the bytes `to_netcdf` writes for the
    same Dataset, booleans stored as int8; a Dask-backed Dataset is computed and written."""
    from stickslip.study.write import save_netcdf

    ds, _ = small
    ds = ds.assign(flag=("slip_time", np.arange(ds.sizes["slip_time"]) % 3 == 0))
    save_netcdf(ds, tmp_path / "ours.nc")
    ds.assign(flag=ds["flag"].astype(np.int8)).to_netcdf(
        tmp_path / "xarray.nc", engine="h5netcdf", invalid_netcdf=False
    )
    assert (tmp_path / "ours.nc").read_bytes() == (tmp_path / "xarray.nc").read_bytes()
    pytest.importorskip("dask")  # Dask-backed variables: computed and written all the same
    chunked = ds.chunk({"slip_time": 7})
    save_netcdf(chunked, tmp_path / "ours_chunked.nc")
    chunked.assign(flag=chunked["flag"].astype(np.int8)).to_netcdf(
        tmp_path / "xarray_chunked.nc", engine="h5netcdf", invalid_netcdf=False
    )
    # (Dask writes the chunks in no fixed order: the same Dataset, not the same bytes)
    ours = xr.load_dataset(tmp_path / "ours_chunked.nc", engine="h5netcdf")
    assert ours.identical(xr.load_dataset(tmp_path / "xarray_chunked.nc", engine="h5netcdf"))
    np.testing.assert_array_equal(ours["mc_slip_time"].values, ds["mc_slip_time"].values)


def test_cli_run_matches_library(small, tmp_path):
    ds, _ = small
    import yaml

    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(small_study()))
    res = CliRunner().invoke(
        main, ["run", str(path), "--out", str(tmp_path / "cli"), "-q", "--no-figures"]
    )  # (the figures: test_files_written)
    assert res.exit_code == 0, res.output
    back = xr.open_dataset(tmp_path / "cli" / "results.nc", engine="h5netcdf")
    for name in ("mc_slip_time", "theory_slip_time", "mc_n1", "theory_n1"):
        np.testing.assert_allclose(back[name].values, ds[name].values, rtol=1e-12, atol=0)
    back.close()


def test_overrides_and_force(tmp_path):
    out = tmp_path / "r"
    out.mkdir()
    (out / "old.txt").write_text("old")
    (out / ".stickslip-results").write_text(  # earlier results: the marker lists old.txt
        '{"written_by": "stickslip", "files": ["old.txt"]}'
    )
    study = small_study(outputs=["slip_time"], analytic=[])
    with pytest.raises(ss.OutputError, match="use --force"):
        ss.run_study(study, out, progress=False)
    assert (out / "old.txt").read_text() == "old"
    ds = ss.run_study(study, out, overrides=["simulation.n_paths=500"], force=True,
                      progress=False, figures=False)  # fmt: skip
    assert int(ds.n_paths) == 500
    assert not (out / "old.txt").exists() and (out / "results.nc").exists()
    assert not list(tmp_path.glob(".r.*"))


def test_failure_while_writing_leaves_nothing(tmp_path, monkeypatch):
    """A run that fails while writing leaves the old results intact and no partial files."""
    from stickslip.study import plots

    out = tmp_path / "r"
    out.mkdir()
    (out / "old.txt").write_text("old")
    (out / ".stickslip-results").write_text(  # earlier results: the marker lists old.txt
        '{"written_by": "stickslip", "files": ["old.txt"]}'
    )

    def broken(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(plots, "make_figures", broken)
    study = small_study(outputs=["slip_time"], analytic=[])
    study["simulation"]["n_paths"] = 200
    with pytest.raises(RuntimeError, match="disk full"):
        ss.run_study(study, out, force=True, progress=False)
    assert sorted(p.name for p in out.iterdir()) == [".stickslip-results", "old.txt"]
    assert not list(tmp_path.glob(".r.*"))


def test_cli_failure_exit_1(tmp_path, monkeypatch):
    from stickslip.study import run as runner

    def broken(*args, **kwargs):
        raise FloatingPointError("overflow in the solver")

    monkeypatch.setattr(runner, "_compute", broken)
    path = tmp_path / "s.yaml"
    import yaml

    path.write_text(yaml.safe_dump(small_study()))
    res = CliRunner().invoke(main, ["run", str(path), "--out", str(tmp_path / "o"), "-q"])
    assert res.exit_code == 1
    assert res.stderr.strip().splitlines() == [
        "error: run failed: FloatingPointError: overflow in the solver (--debug shows the "
        "traceback)"
    ]
    res = CliRunner().invoke(main, ["run", str(path), "--out", str(tmp_path / "o"), "--debug"])
    assert res.exit_code == 1 and isinstance(res.exception, FloatingPointError)
    assert not (tmp_path / "o").exists()


def test_theory_only_study():
    study = small_study(simulation=None, outputs=["slip_time", "slip_distance"])
    study.pop("grid")
    ds = ss.run_study(study, progress=False)
    assert "mc_slip_time" not in ds
    e = ds["slip_time_edges"].values
    mass = float(np.sum(ds["theory_slip_time"].values[0] * np.diff(e)))
    assert 0.95 < mass < 1.0001  # the automatic grid covers the density


def test_sweep_dataset(tmp_path):
    study = small_study(
        outputs=["slip_time"], sweep={"parameters": {"model.params.v_b": [0.8, 1.2]}}
    )
    study["simulation"]["n_paths"] = 1000
    ds = ss.run_study(study, tmp_path / "s", progress=False)
    assert ds.sizes["point"] == 2
    assert list(ds["model.params.v_b"].values) == [0.8, 1.2]
    assert ds["mc_slip_time"].dims == ("point", "slip_time")
    assert ds["slip_time_edges"].dims == ("slip_time_edge",)
    assert (tmp_path / "s" / "sweep.png").exists()
    # each point is the study run alone at that value
    alone = ss.run_study(
        small_study(outputs=["slip_time"]),
        overrides=["model.params.v_b=1.2", "simulation.n_paths=1000"],
        progress=False,
    )
    np.testing.assert_array_equal(alone["mc_slip_time"].values, ds["mc_slip_time"].values[1])


def test_schema_round_trip():
    import json

    schema = ss.Study.model_json_schema()
    assert set(schema["required"]) == {"model"}
    assert "Simulation" in schema["$defs"]
    res = CliRunner().invoke(main, ["schema"])
    assert res.exit_code == 0 and json.loads(res.stdout) == json.loads(json.dumps(schema))
    res = CliRunner().invoke(main, ["schema", "--model", "langevin"])
    params = json.loads(res.stdout)
    assert set(params["required"]) == {"omega0", "zeta", "D", "v_b", "x0"}
    # every description is there, so the schema documents the study file
    for name, sub in schema["$defs"].items():
        for field, spec in sub.get("properties", {}).items():
            assert spec.get("description"), f"{name}.{field}"


def test_one_e_minus_four_is_a_float():
    """YAML 1.1 reads `1e-4` as a string; studies read it as a number."""
    from stickslip.study.load import read_yaml

    assert read_yaml("a: 1e-4\nb: 2.5E3\nc: '1e-4'\n") == {"a": 1e-4, "b": 2500.0, "c": "1e-4"}


# -- every example study runs, reduced ----------------------------------------------------
REDUCED = {
    "burridge_knopoff": ["simulation.t_max=400"],
    "sweep_driving_speed": [
        "simulation.n_paths=500",
        "simulation.t_max=30",
        "sweep.parameters={model.params.v_b: [0.5, 1.25, 2.0]}",
    ],
    "fig7": ["simulation.n_paths=1000", "simulation.cycles.t_max=100"],
    # The period and slip-distance mixtures (14 s here) are tested in test_random_threshold.py.
    "random_threshold": ["simulation.n_paths=2000", "outputs=[slip_time, stick_time]"],
    "public_auto": ["tolerance=0.1"],  # method: auto sizes the run itself
    "ou_exact_theory": ["simulation.n_paths=1000", "simulation.t_max=10"],
    # Free runs recording upcrossings: the cost is paths x t_max / dt.
    "fig4_left": ["simulation.n_paths=1000", "simulation.t_max=10"],
    "fig4_right": ["simulation.n_paths=1000", "simulation.t_max=10"],
}


# Slow tier (8-18 s each from a cold cache, the default tier's budget): the random-threshold
# example (its model and mixtures are tested in test_random_threshold.py), the exact theory
# (test_estimator.py) and fig. 6C (a Langevin run as in the other examples).
# In `slow`: the long ones, and public_reference, fig6d and the sweep (10-14 s each on a cold
# cache; the main job runs in the default tier through tests/test_examples.py and the README's
# snippets, a sweep through test_sweep_dataset and tests/test_distributed.py).
SLOW_EXAMPLES = {
    "random_threshold", "ou_exact_theory", "fig6c", "public_reference", "fig6d",
    "sweep_driving_speed",
}  # fmt: skip


@pytest.mark.parametrize(
    "path",
    [
        pytest.param(p, marks=pytest.mark.slow) if p.stem in SLOW_EXAMPLES else p
        for p in sorted(EXAMPLES.glob("*.yaml"))
    ],
    ids=lambda p: p.stem,
)
def test_example_study(path, tmp_path):
    overrides = REDUCED.get(path.stem, ["simulation.n_paths=2000"])
    out = tmp_path / "out"
    ds = ss.run_study(path, out, overrides=overrides, progress=False)
    files = {p.name for p in out.iterdir()}
    assert {"results.nc", "summary.md", "study.yaml"} <= files
    study = ss.load_study(path, overrides=overrides)
    assert study.description, "each example states its choices (x0, noise)"
    for q in study.resolved_outputs():  # one figure per output
        assert f"{q}.png" in files, (q, files)
    if study.sweep is not None:
        assert "sweep.png" in files
    for name in ds.data_vars:
        if name.startswith("theory_") and name != "theory_n2":
            assert np.isfinite(ds[name].values).all(), name


def test_documented_study_is_valid():
    """The annotated study in docs/studies.md is a valid study (and its sweep block too)."""
    import re

    from stickslip.study.load import read_yaml

    text = (EXAMPLES.parent / "docs" / "studies.md").read_text()
    blocks = re.findall(r"^```yaml\n(.*?)^```", text, re.S | re.M)
    full = read_yaml(blocks[0])
    study = ss.load_study(full)
    assert len(study.analytic) == 3 and study.simulation.cycles.n_paths == 2
    sweep = read_yaml(blocks[1])
    full["outputs"] = ["slip_time", "period"]
    assert len(ss.load_study({**full, **sweep}).points()) == 6
