"""Exported files are named ``<source>-<edit>-lmax<N><suffix>`` by one function
(:func:`shprobe.lighting.filenames.export_name`): the page's download is named as the file
``shprobe edit`` writes by default for the same edit, with the same bytes; the names tell
sources, edits and degrees apart and stay safe file names."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from shprobe.errors import ShprobeError
from shprobe.lighting.edits import EditSpec
from shprobe.lighting.filenames import edit_tag, export_name, source_stem
from tests.conftest import data_file
from tests.viewer import test_viewer as tv

# the browser, the served session (the grace probe, the packaged bunny) and its page
browser, served, page, probe_path = tv.browser, tv.served, tv.page, tv.probe_path
set_state = tv._state

# ----------------------------------------------------------------------------- the names


def test_source_stems():
    assert source_stem("/data/probes/grace.hdr") == "grace"
    assert source_stem("grace.hdr") == "grace"
    assert source_stem("C:\\probes\\ennis.exr") == "ennis"
    assert source_stem("preset:stpeters") == "preset-stpeters"
    assert source_stem("") == source_stem(None) == "darkness"
    assert source_stem("procedural sky") == "procedural-sky"
    assert source_stem("/a/px.hdr … /a/nz.hdr (cube faces)") == "px-cube"
    assert source_stem("sky.hdr.gz") == "sky"
    assert source_stem('we"ird;name$(x).hdr') == "we-ird-name-x"
    assert len(source_stem("x" * 500 + ".hdr")) == 48


def test_edit_tags_tell_edits_apart_and_name_the_steps():
    plain = EditSpec.from_text(["--lmax", "4"])
    assert edit_tag(plain) == "sh"
    a = EditSpec.from_text(["--rotate", "0,1,0:30", "--window", "hann:0.5"])
    b = EditSpec.from_text(["--rotate", "0,1,0:31", "--window", "hann:0.5"])
    assert edit_tag(a).startswith("rotated_window_") and len(edit_tag(a)) == 21
    assert edit_tag(a) != edit_tag(b)
    assert edit_tag(a) == edit_tag(EditSpec.from_text(["--rotate", "0,1,0:30", "--window",
                                                       "hann:0.5", "--lmax", "5"]))
    full = EditSpec.from_text(["--weight", "2", "--blend", "preset:grace:0.5", "--sky", "1",
                               "--scale-band", "1=0", "--negate", "1,1"])
    assert edit_tag(full).startswith("weight_blend_lights_coeffs_")
    # a blended file is named by its file name: the CLI's path and the viewer's upload agree
    f = EditSpec.from_text(["--blend", "/x/y/ennis.hdr:0.3"])
    assert edit_tag(f) == edit_tag(EditSpec.from_text(["--blend", "ennis.hdr:0.3"]))
    viewer = EditSpec.from_json({"blends": [{"probe": "p1.0", "weight": 0.3}]})
    assert edit_tag(viewer, {"p1.0": "ennis.hdr"}) == edit_tag(f)
    with pytest.raises(ShprobeError, match="not loaded"):
        edit_tag(viewer, {})


def test_export_names():
    spec = EditSpec.from_text(["--lmax", "3"])
    assert export_name("probes/grace.hdr", spec, "json") == "grace-sh-lmax3.json"
    assert export_name("preset:grace", EditSpec(), "cmgen") == "preset-grace-sh-lmax2_sh.txt"
    assert export_name(None, EditSpec(), "three") == "darkness-sh-lmax2.three.json"
    with pytest.raises(ShprobeError, match="unknown export format"):
        export_name("g.hdr", spec, "png")


def test_cli_default_output_and_folder(tmp_path, monkeypatch, grace_path):
    """`shprobe edit` without -o writes the named file here; -o FOLDER puts it there;
    `shprobe export -o FOLDER` too (without -o it prints, as before)."""
    from shprobe.cli.main import main

    monkeypatch.chdir(tmp_path)
    args = ["--rotate", "0,1,0:30", "--lmax", "3"]
    assert main(["edit", str(grace_path), *args]) == 0
    want = export_name(str(grace_path), EditSpec.from_text(args), "json")
    assert [p.name for p in tmp_path.iterdir()] == [want]
    (tmp_path / "out").mkdir()
    assert main(["edit", str(grace_path), *args, "-o", "out"]) == 0
    assert (tmp_path / "out" / want).read_bytes() == (tmp_path / want).read_bytes()
    assert main(["edit", str(grace_path), *args]) == 1  # never replaced without --force
    assert main(["export", "--preset", "grace", "--format", "glsl", "-o", "out"]) == 0
    assert (tmp_path / "out" / "preset-grace-sh-lmax2.glsl").is_file()


# ----------------------------------------------------------------------------- the page

CASES = [  # (edit state, format)
    ({}, "json"),
    ({"lmax": 3, "rotation": {"axis": [0.0, 1.0, 0.0], "degrees": 30.0}, "window": "hann:0.5"},
     "json"),
    ({"scale_band": {"1": 0.8}, "blends": [{"preset": "stpeters", "weight": 0.25}],
      "directional": [{"dir": [0.3, 0.8, -0.5], "rgb": [2.0, 1.5, 1.0]}]}, "glsl"),
    ({"weight": 1.5, "window": "auto"}, "cmgen"),
]


@pytest.mark.parametrize("state,fmt", CASES)
@pytest.mark.browser
def test_download_is_named_as_the_cli_names_it(page, served, probe_path, tmp_path, monkeypatch,
                                               state, fmt):
    from shprobe.cli.main import main
    from shprobe.viewer.design import read_state

    set_state(page, state)
    with page.expect_download() as dl:
        page.click(f"#export-{fmt}")
    got = dl.value.suggested_filename
    monkeypatch.chdir(tmp_path)
    assert main(["edit", str(probe_path), *read_state(state).to_text(), "--format", fmt]) == 0
    files = [p.name for p in tmp_path.iterdir()]
    assert files == [got]
    assert Path(dl.value.path()).read_bytes() == (tmp_path / got).read_bytes()
    assert got.startswith(f"{Path(probe_path).stem}-") and f"-lmax{read_state(state).lmax}" in got
    set_state(page, {})


@pytest.mark.browser
def test_download_names_an_uploaded_blend_as_the_cli_names_the_file(page, served, probe_path,
                                                                    tmp_path, monkeypatch):
    """A probe blended through the page (an upload) and the same file given to
    `shprobe edit --blend PATH:W` give the same name and bytes."""
    from shprobe.cli.main import main

    other = data_file("probes", "ennis.hdr")
    set_state(page, {"lmax": 3})
    page.fill("#bweight", "0.3")
    page.set_input_files("#upblend", str(other))
    page.wait_for_function("() => window.__shprobe.getState().blends.length === 1")
    page.evaluate("() => window.__shprobe.settled()")
    with page.expect_download() as dl:
        page.click("#export-json")
    monkeypatch.chdir(tmp_path)
    assert main(["edit", str(probe_path), "--lmax", "3", "--blend", f"{other}:0.3"]) == 0
    assert [p.name for p in tmp_path.iterdir()] == [dl.value.suggested_filename]
    assert Path(dl.value.path()).read_bytes() == (tmp_path / dl.value.suggested_filename
                                                  ).read_bytes()
    assert "-blend_" in dl.value.suggested_filename
    set_state(page, {})


def test_export_header_names_the_file(served):
    """The server's answer carries the name (the page's download attribute takes it)."""
    import httpx

    r = httpx.post(served.base + "/api/export/three", params={"token": served.token},
                   content='{"lmax": 2, "scale_band": {"2": 0}}', timeout=60)
    name = export_name(served.session.source.name,
                       EditSpec.from_json({"scale_band": {"2": 0}}), "three")
    assert r.headers["content-disposition"] == f'attachment; filename="{name}"'
    assert name.startswith(os.path.splitext(os.path.basename(served.session.source.name))[0])
