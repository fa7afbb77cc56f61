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
    for page in ("index.html", "quickstart/index.html", "study_reference/index.html",
                 "tutorial/index.html", "api/index.html"):  # fmt: skip
        assert (site / page).is_file(), page
    # the API reference renders the docstrings: a signature and an `**Arguments:**` entry
    api = (site / "api" / "index.html").read_text(encoding="utf-8")
    assert "simulate_chain" in api and "n_paths" in api and "<strong>Arguments:</strong>" in api


def _api_directives() -> set[str]:
    text = (DOCS / "api.md").read_text(encoding="utf-8")
    return {line[4:].strip() for line in text.splitlines() if line.startswith("::: ")}


def test_the_api_reference_has_every_public_name():
    """Every name of `stickslip.__all__` and `stickslip.plugin.__all__` has its entry in
    docs/api.md, under the module that defines it (a new public name needs one)."""
    import stickslip
    import stickslip.plugin

    listed = _api_directives()
    missing = []
    for module, names in ((stickslip, stickslip.__all__), (stickslip.plugin,
                                                           stickslip.plugin.__all__)):  # fmt: skip
        for name in names:
            if name in ("__version__", "jax", "jnp"):  # (the version; JAX itself)
                continue
            where = getattr(getattr(module, name), "__module__", None) or "stickslip.friction"
            if f"{where}.{name}" not in listed:
                missing.append(f"{module.__name__}.{name} (::: {where}.{name})")
    assert not missing, f"public names without an entry in docs/api.md: {missing}"


def test_a_broken_api_reference_fails_the_build(tmp_path):
    """The site's own settings (strict, mkdocstrings) on a page that names an object that
    does not exist: the build stops, naming it."""
    pytest.importorskip("mkdocs")
    if importlib.util.find_spec("mkdocstrings_handlers") is None:
        pytest.skip("mkdocstrings-python is not installed (it comes with the 'docs' extra)")
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))
    python = config["plugins"][1]["mkdocstrings"]["handlers"]["python"]
    python["paths"] = [str(ROOT / p) for p in python["paths"]]
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "index.md").write_text(
        "# API\n\n::: stickslip._simulate.driver.simulate\n\n"
        "::: stickslip._simulate.driver.simulate_everything\n"
    )
    config.update(docs_dir=str(docs), nav=["index.md"], extra_javascript=[])
    config.pop("exclude_docs", None)
    (tmp_path / "mkdocs.yml").write_text(yaml.safe_dump(config))
    out = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
        cwd=tmp_path, capture_output=True, text=True, timeout=600,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )  # fmt: skip
    assert out.returncode != 0
    assert "simulate_everything could not be found" in out.stdout + out.stderr
