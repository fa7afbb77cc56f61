"""`stickslip cache info` and `stickslip cache clear`, and `stickslip --version`, on a cache
folder of their own (never the one the other tests use)."""

from __future__ import annotations

import json

import pytest
from conftest import run_cli

import stickslip as ss
from stickslip import _cache, _cpu


@pytest.fixture
def folder(tmp_path, monkeypatch):
    """A cache folder as the simulator leaves it: traces, executables of this CPU kind and
    of another, a queued job, one of JAX's own entries; and a file of the user's."""
    where = tmp_path / "cache"
    files = {
        "stickslip-exported/a.bin": 300,
        "stickslip-exported/b.bin": 200,
        f"stickslip-executable/{_cpu.KIND}/x.bin": 1000,
        "stickslip-executable/0123456789abcdef/y.bin": 4000,
        f"stickslip-queue/{_cpu.KIND}/1.job": 10,
        "jit__segment-953b-cache": 50,
        "notes.txt": 7,
    }
    for name, size in files.items():
        (where / name).parent.mkdir(parents=True, exist_ok=True)
        (where / name).write_bytes(b"x" * size)
    monkeypatch.delenv("JAX_COMPILATION_CACHE_DIR", raising=False)
    monkeypatch.setenv("STICKSLIP_CACHE_DIR", str(where))
    return where


def test_info_says_where_how_big_and_per_cpu_kind(folder):
    done = run_cli("cache", "info", "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["directory"] == str(folder) and report["source"] == "STICKSLIP_CACHE_DIR"
    assert (report["bytes"], report["files"]) == (5567, 7)
    assert report["traces"] == {"bytes": 500, "files": 2}
    mine = report["executables"][_cpu.KIND]
    assert (mine["bytes"], mine["queued"], mine["this_machine"]) == (1000, 1, True)
    other = report["executables"]["0123456789abcdef"]
    assert (other["bytes"], other["queued"], other["this_machine"]) == (4000, 0, False)
    assert report["jax_entries"] == {"bytes": 50, "files": 1}
    shipped = report["shipped"]
    assert shipped["traces"] > 0 and set(shipped["made_with"]) == {
        "jax", "jaxlib", "diffrax", "equinox"
    }  # fmt: skip
    text = run_cli("cache", "info").stdout
    assert str(folder) in text and "(this machine)" in text and "1 queued" in text
    assert "shipped traces:" in text


def test_clear_removes_the_compiled_code_only(folder):
    done = run_cli("cache", "clear")
    assert done.returncode == 0, done.stderr
    assert "removed 5.6 kB in 6 files" in done.stdout
    left = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*"))
    assert left == ["notes.txt"]
    again = run_cli("cache", "clear")
    assert "removed 0 B in 0 files" in again.stdout


def test_off_and_absent_folders(tmp_path, monkeypatch):
    monkeypatch.delenv("JAX_COMPILATION_CACHE_DIR", raising=False)
    monkeypatch.setenv("STICKSLIP_CACHE_DIR", "off")
    assert _cache.directory()[0] is None
    assert "not kept between runs" in run_cli("cache", "info").stdout
    assert "nothing to clear" in run_cli("cache", "clear").stdout
    monkeypatch.setenv("STICKSLIP_CACHE_DIR", str(tmp_path / "none"))
    assert "not created yet" in run_cli("cache", "info").stdout
    assert "nothing to clear" in run_cli("cache", "clear").stdout
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("STICKSLIP_CACHE_DIR", str(tmp_path / "file"))
    done = run_cli("cache", "clear")
    assert done.returncode == 2 and "is not a folder" in done.stderr
    assert (tmp_path / "file").exists()


def test_the_default_folder_and_jaxs_own(tmp_path, monkeypatch):
    monkeypatch.delenv("STICKSLIP_CACHE_DIR", raising=False)
    monkeypatch.delenv("JAX_COMPILATION_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert _cache.directory() == (tmp_path / "stickslip" / "jax", "default")
    monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", str(tmp_path / "jax"))
    assert _cache.directory()[0] == tmp_path / "jax"


def test_version():
    done = run_cli("--version")
    assert done.returncode == 0 and done.stdout.split()[-1] == ss.__version__
