"""The manual (mkdocs.yml; .ci/run builds it with --strict): every page of docs/ is in it, every
public name has the docstring its API page is made from, and the version shown is the one
source's."""

from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

import shprobe

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"


def nav_pages() -> set[str]:
    text = (REPO / "mkdocs.yml").read_text(encoding="utf-8")
    nav = text[text.index("\nnav:"):]
    return set(re.findall(r":\s*([\w/-]+\.md)\s*$", nav, re.M))


def test_every_page_is_in_the_manual_and_every_nav_entry_exists():
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md")}
    assert nav_pages() == pages


def test_every_public_name_has_a_docstring():
    missing = []
    for name, mod in shprobe._EXPORTS.items():
        obj = getattr(importlib.import_module(f"shprobe.{mod}"), name)
        if isinstance(obj, (dict, tuple, list)):
            continue  # a constant: documented by its module's comment (#:) and page
        if not (getattr(obj, "__doc__", None) or "").strip():
            missing.append(f"shprobe.{mod}.{name}")
    assert missing == []


def test_each_package_has_its_api_page():
    pkgs = {p.parent.name for p in (REPO / "src" / "shprobe").glob("*/__init__.py")} - {"cli"}
    base = (DOCS / "api" / "base.md").read_text(encoding="utf-8")
    for pkg in pkgs:
        if f"<!-- members: shprobe.{pkg} " in base:  # a base module that grew into a package
            continue
        page = DOCS / "api" / f"{pkg}.md"
        assert page.is_file() and f"::: shprobe.{pkg}" in page.read_text(encoding="utf-8"), pkg


def test_the_manual_shows_the_one_version():
    sys.path.insert(0, str(REPO / "tools"))
    try:
        import mkdocs_hooks
    finally:
        sys.path.pop(0)
    assert mkdocs_hooks.version() == shprobe.__version__
    assert set(mkdocs_hooks.exports()) == set(shprobe._EXPORTS)
    assert "{{ version }}" in (DOCS / "index.md").read_text(encoding="utf-8")
