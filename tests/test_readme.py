"""Every README tour line and the README's Python snippet run as written, in order, in a folder
holding the files they name (the shared probes and bunny under the README's names)."""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import numpy as np
import pytest

from shprobe.cli.main import main

from .conftest import data_file

README = Path(__file__).resolve().parents[1] / "README.md"


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
    for src, name in ((grace, "probe.hdr"), (grace, "grace.hdr"), (ennis, "ennis.hdr"),
                      (bunny, "bunny.obj")):
        shutil.copy(src, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_the_tour_has_the_commands_it_promises():
    names = {shlex.split(ln)[1] for ln in tour_lines()}
    assert {"prefilter", "irradiance", "error", "render", "basis-images", "edit", "window",
            "sh", "hbasis", "prt", "fit", "report", "batch"} <= names


@pytest.mark.slow
def test_every_tour_line_runs_as_written(tour_dir, capsys):
    for line in tour_lines():
        rc = main(shlex.split(line)[1:])
        out = capsys.readouterr()
        assert rc == 0, f"{line}\n{out.err}"
        assert "Traceback" not in out.err
    # what the lines say they write is there
    for name in ("c.json", "irr.exr", "bunny.png", "basis/basis.png", "edited.json", "h.npz",
                 "nm.png", "t.npz", "frames/f_000.png", "frames/f_035.png", "ball.png",
                 "fitted.json", "report.html", "probes.parquet"):
        assert (tour_dir / name).is_file(), name


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
