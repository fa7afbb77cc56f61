"""The documentation site: the generated study reference is current, every page is in the
navigation, and `mkdocs build --strict` passes (when the `docs` extra is installed)."""

import difflib
import importlib.util
import os
import pathlib
import subprocess
import sys

import pytest
import yaml

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
GENERATOR = DOCS / "gen_study_reference.py"
REFERENCE = DOCS / "study_reference.md"


def _nav_pages(nav) -> list[str]:
    """The page paths of a mkdocs `nav` (nested sections flattened; external links dropped)."""
    pages: list[str] = []
    items = nav if isinstance(nav, list) else [nav]
    for item in items:
        if isinstance(item, str):
            pages.append(item)
        elif isinstance(item, dict):
            for value in item.values():
                pages += _nav_pages(value)
    return [p for p in pages if "://" not in p]


def test_study_reference_is_current():
    # A fresh interpreter: the page lists the installed models, not ones that other tests
    # registered at run time.
    out = subprocess.run(
        [sys.executable, str(GENERATOR), "--stdout"],
        cwd=ROOT,
        capture_output=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr.decode("utf-8", "replace")
    expected = out.stdout.decode("utf-8")
    committed = REFERENCE.read_text(encoding="utf-8")
    diff = "".join(
        difflib.unified_diff(
            committed.splitlines(keepends=True),
            expected.splitlines(keepends=True),
            "docs/study_reference.md (committed)",
            "docs/gen_study_reference.py (now)",
        )
    )
    assert committed == expected, (
        "docs/study_reference.md is stale: run `python docs/gen_study_reference.py`\n" + diff
    )


def test_nav_matches_pages():
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))
    assert config.get("docs_dir", "docs") == "docs"
    nav = _nav_pages(config["nav"])
    assert len(nav) == len(set(nav)), f"a page is in the nav twice: {nav}"
    missing = [p for p in nav if not (DOCS / p).is_file()]
    assert not missing, f"in the nav but not in docs/: {missing}"
    pages = sorted(p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md"))
    absent = [p for p in pages if p not in nav]
    assert not absent, f"in docs/ but not in the nav of mkdocs.yml: {absent}"


def test_mkdocs_build_strict(tmp_path):
    pytest.importorskip("mkdocs")
    if importlib.util.find_spec("material") is None:
        pytest.skip("mkdocs-material is not installed (it comes with the 'docs' extra)")
    site = tmp_path / "site"
    out = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert out.returncode == 0, out.stdout + out.stderr
    for page in ("index.html", "quickstart/index.html", "study_reference/index.html"):
        assert (site / page).is_file(), page
