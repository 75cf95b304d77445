"""The README as a new user reads it: its two commands are what CI runs, the system packages the
skipping tests need are named with their apt line, and its Python snippet runs. Every tour line
runs as written in a fresh venv, in a shell that activated it: tests/packaging/test_packaging.py."""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import data_file

README = Path(__file__).resolve().parents[2] / "README.md"


def _blocks(lang: str, after: str) -> list[str]:
    text = README.read_text(encoding="utf-8")
    text = text[text.index(after):]
    return re.findall(rf"```{lang}\n(.*?)```", text, re.S)


def tour_lines() -> list[str]:
    block = _blocks("sh", "## A tour")[0]
    lines = [ln.split(" #")[0].strip() for ln in block.splitlines()]  # comments start " #"
    return [ln for ln in lines if ln.startswith("shprobe ")]


@pytest.fixture
def tour_dir(tmp_path, monkeypatch):
    grace, ennis, bunny = (data_file("probes", "grace.hdr"), data_file("probes", "ennis.hdr"),
                           data_file("meshes", "bunny.obj"))
    # exactly the files the tour's setup sentence names
    for src, name in ((grace, "grace.hdr"), (ennis, "ennis.hdr"), (bunny, "bunny.obj")):
        shutil.copy(src, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_the_tour_has_the_commands_it_promises():
    names = {shlex.split(ln)[1] for ln in tour_lines()}
    assert all(ln.startswith("shprobe ") for ln in tour_lines())
    assert {"prefilter", "irradiance", "error", "render", "basis-images", "edit", "window",
            "sh", "hbasis", "prt", "fit", "report", "batch"} <= names


def test_the_two_commands_are_what_ci_runs():
    first, second = [ln.strip() for ln in _blocks("sh", "# shprobe")[0].strip().splitlines()]
    assert "pip install -e '.[all,dev]'" in first and first.endswith("shprobe demo --force")
    assert second == ".venv/bin/python -m pytest -n 2 -q"
    ci = (README.parent / ".ci" / "run").read_text(encoding="utf-8")
    assert first in ci and second in ci


def test_the_optional_system_packages_have_one_apt_line():
    (apt,) = [b for b in _blocks("text", "# shprobe") if "apt-get install" in b]
    pkgs = set(apt.split("install", 1)[1].split())
    assert {"chromium", "glslang-tools", "spirv-cross", "nodejs", "npm"} <= pkgs
    ci = (README.parent / ".ci" / "run").read_text(encoding="utf-8")
    for pkg in pkgs:  # CI installs what the README names
        assert pkg in ci, pkg


def test_the_tour_says_how_to_reach_the_command():
    text = README.read_text(encoding="utf-8")
    tour = text[text.index("## A tour"):text.index("```sh", text.index("## A tour"))]
    assert ". .venv/bin/activate" in tour and ".venv/bin/shprobe" in tour
    # the files the tour's lines read are the ones its setup sentence names
    named = set(re.findall(r"`(\w+\.(?:hdr|obj))`", tour))
    used = {w for ln in tour_lines() for w in shlex.split(ln)
            if re.fullmatch(r"\w+\.(?:hdr|obj)", w)}
    assert used <= named == {"grace.hdr", "ennis.hdr", "bunny.obj"}, (used, named)


def test_every_workflow_is_linked():
    text = README.read_text(encoding="utf-8")
    for page in ("prefilter", "render", "sh", "hbasis", "prt", "fitting", "report", "batch",
                 "viewer", "grids", "grid-exports", "splats", "tensors", "lightmaps",
                 "contributing", "install"):
        assert f"(docs/{page}.md)" in text, page
    extras = text[text.index("### Installing only what you need"):text.index("## A tour")]
    for extra in ("viewer", "batch", "splats", "torch", "jax", "all"):
        assert f"shprobe[{extra}]" in extras, extra


def test_readme_python_snippet_runs(tour_dir):
    import shprobe

    (code,) = _blocks("python", "As a library")
    ns: dict = {}
    exec(compile(code, str(README), "exec"), ns)
    L, E, normals, R = ns["L"], ns["E"], ns["normals"], ns["R"]
    assert L.shape == (9, 3) and E.shape == (2, 3)
    np.testing.assert_allclose(E, shprobe.irradiance_quadratic(L, normals), rtol=1e-9)
    # the turned lighting's irradiance at R n equals the original's at n
    np.testing.assert_allclose(shprobe.irradiance(ns["L2"], normals @ R.T), E, rtol=1e-9,
                               atol=1e-12)
