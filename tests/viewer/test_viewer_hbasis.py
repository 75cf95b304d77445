"""The H-basis view in headless Chromium: labelled panels (reference, H6, H4, SH9 and each
basis's error), the errors as a heat map with its scale in % of ∫L dω — the numbers computed
here from the library's render — and an H-basis bake (`shprobe hbasis bake`) opened with
`shprobe view --hbasis FILE` and from the page's file loader; a bake given to --transfer
(and a transfer given to --hbasis) is one line saying which option opens it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.viewer.session import Session
from tests.conftest import data_file
from tests.viewer.viewer_pages import bake_ball, opened, serving, shot

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

PANELS = """() => [...document.querySelectorAll('#hbpanels figure')].map((f) => {
  const c = f.querySelector('canvas'), r = f.getBoundingClientRect();
  return { id: c ? c.id : null, w: c ? c.width : 0,
           caption: f.querySelector('figcaption').textContent,
           box: [r.left, r.top, r.right, r.bottom] }; })"""


def _errors(res, tot):
    """max over R, G, B of |E_basis − E_ref| / ∫L dω per pixel, for each basis."""
    ref = res.irradiance
    return {k: (np.abs(res.layers[k] - ref) / tot).max(axis=-1)
            for k in ("H6", "H4", "SH9") if k in res.layers}


def _check_panels(page, keys):
    panels = page.evaluate(PANELS)
    ids = [p["id"] for p in panels]
    assert ids == [*(f"hb-{k}" for k in keys), None, *(f"hb-err-{k}" for k in keys[1:])]
    for p in panels:
        assert p["caption"].strip(), p
        assert p["box"][2] <= page.viewport_size["width"] + 0.5, p  # not clipped
        if p["id"]:
            assert p["w"] > 0
    caps = {p["id"]: p["caption"] for p in panels}
    assert caps["hb-reference"].startswith("reference")
    for k in keys[1:]:
        assert caps[f"hb-{k}"].startswith(k) and f"|{k} − reference|" in caps[f"hb-err-{k}"]
        assert "% of ∫L dω" in caps[f"hb-err-{k}"]
    title = page.locator("#hblegendtitle").inner_text()
    assert "% of ∫L dω" in title
    return caps


@pytest.mark.browser
def test_hbasis_view_labelled_heat_map_in_percent():
    from shprobe.hbasis.rendering import render_normal_mapped
    from shprobe.lighting.projection import total_intensity
    from shprobe.probes.env import Env
    from shprobe.probes.layouts import LatLong

    probe = data_file("probes", "grace.hdr")
    with serving(Session(str(probe))) as s, opened(s) as page:
        page.select_option("#mode", "hbasis")
        page.wait_for_function("() => window.__shprobe.hbasisHead", timeout=120000)
        assert not page.locator("#view").is_visible()  # the panels take the view's place
        assert not page.locator("#lmax").is_visible()  # the H-basis view bakes at lmax 4
        caps = _check_panels(page, ["reference", "H6", "H4", "SH9"])
        # the numbers, from the library's render of the same lighting (no edits: the probe)
        dirs = LatLong().pixel_directions((64, 128))
        env = Env(np.asarray(s.session.source.env.sample(dirs), np.float32), LatLong())
        res = render_normal_mapped(s.session.mesh, env, size=160)
        errs = _errors(res, total_intensity(env))
        top = max(float(e.max()) for e in errs.values())
        assert page.locator("#hblegendmax").inner_text() == f"{100 * top:.3f} %"
        assert page.evaluate("() => window.__shprobe.hbasisErrMax") == pytest.approx(top,
                                                                                    rel=1e-6)
        for k, e in errs.items():
            assert f"max {100 * e.max():.3f} %" in caps[f"hb-err-{k}"]
        rows = page.evaluate("() => [...document.querySelectorAll('#hbtable tr')].slice(1)"
                             ".map((r) => [...r.cells].map((c) => c.textContent))")
        assert [r[0] for r in rows] == ["H6", "H4", "SH9"]
        for r in rows:
            assert r[1] == f"{100 * errs[r[0]].max():.3f} %"
            assert r[3] == f"{100 * res.info['rel_rms'][r[0]]:.3f} %"
        # the error panels are the heat map: the worst pixel of the worst basis is the scale's
        # top colour (white), a pixel off the object black
        worst = max(errs, key=lambda k: errs[k].max())
        i = np.unravel_index(np.argmax(errs[worst]), errs[worst].shape)
        px = page.evaluate("([id, y, x]) => Array.from(document.getElementById(id)"
                           ".getContext('2d').getImageData(x, y, 1, 1).data)",
                           [f"hb-err-{worst}", int(i[0]), int(i[1])])
        assert px[:3] == [255, 255, 255]
        shot(page, "hbasis_probe")
        assert not [m for m in page.shprobe_console if m.startswith(("error:", "pageerror:"))]


@pytest.fixture(scope="module")
def ball_bake(tmp_path_factory):
    """A small mesh and its H-basis bake under grace's SH (`shprobe hbasis bake`)."""
    from shprobe.cli.main import main
    from shprobe.lighting.projection import project
    from shprobe.probes.env import load_env
    from shprobe.scene.render import sphere_mesh

    d = tmp_path_factory.mktemp("hb")
    mesh = d / "ball.obj"
    sphere_mesh(3).export(mesh)
    np.save(d / "grace_L.npy", project(load_env(data_file("probes", "grace.hdr")), 8))
    out = d / "ball_h6.npz"
    assert main(["hbasis", "bake", str(mesh), str(d / "grace_L.npy"), "-o", str(out)]) == 0
    return mesh, out


@pytest.mark.browser
def test_hbasis_bake_opened_with_option_and_loader(ball_bake, tmp_path):
    from shprobe.hbasis.bakefile import load_bake
    from shprobe.hbasis.rendering import render_normal_mapped
    from shprobe.scene.mesh import load_mesh

    mesh, bake = ball_bake
    m = load_mesh(mesh)
    bk = load_bake(bake, m)
    res = render_normal_mapped(m, bk.lighting, size=160, baked=bk)
    tot = np.sqrt(4 * np.pi) * np.abs(bk.lighting[0])
    errs = _errors(res, tot)
    # `shprobe view --mesh ball.obj --hbasis ball_h6.npz`: the bake's view at once
    with serving(Session(mesh=str(mesh), hbasis=str(bake))) as s, opened(s) as page:
        page.wait_for_function("() => window.__shprobe.hbasisHead", timeout=120000)
        assert page.locator("#mode").input_value() == "hbasis"
        assert "(baked lighting)" in page.locator("#source").inner_text()
        head = page.evaluate("() => window.__shprobe.hbasisHead")
        assert head["baked"] and head["reference"] == "the lighting's SH expansion"
        assert head["rel_rms"] == pytest.approx(res.info["rel_rms"], rel=1e-9)
        for k, e in errs.items():
            assert head["max_frac"][k] == pytest.approx(float(e.max()), rel=1e-5)
        assert bake.name in page.locator("#hblabel").inner_text()
        assert "edits do not apply" in page.locator("#hblabel").inner_text()
        _check_panels(page, ["reference", "H6", "H4", "SH9"])
        shot(page, "hbasis_bake")
    # the page's loader: the same file through "H-basis bake"; a PRT transfer there is refused
    tp = bake_ball(tmp_path, lmax=2)
    with serving(Session(mesh=str(mesh))) as s, opened(s) as page:
        page.evaluate("() => { document.querySelector('#uphbasis').closest('details')"
                      ".open = true; }")
        page.evaluate("() => { window.__shprobe.lastError = null; }")
        page.set_input_files("#uphbasis", str(tp))
        page.wait_for_function("() => window.__shprobe.lastError", timeout=30000)
        msg = page.locator("#error").inner_text().strip()
        assert "\n" not in msg and "--transfer" in msg and tp.name in msg, msg
        page.set_input_files("#uphbasis", str(bake))
        page.wait_for_function("() => window.__shprobe.hbasisHead && "
                               "window.__shprobe.hbasisHead.baked", timeout=120000)
        assert page.locator("#error").is_hidden()
        assert page.locator("#mode").input_value() == "hbasis"
        assert page.evaluate("() => window.__shprobe.hbasis") == pytest.approx(
            res.info["rel_rms"], rel=1e-9)


def test_hbasis_files_given_to_the_wrong_option_are_one_line(ball_bake, tmp_path):
    mesh, bake = ball_bake
    tp = bake_ball(tmp_path, lmax=2)
    with pytest.raises(ShprobeError, match="--hbasis"):
        Session(preset="grace", transfer=str(bake))
    with pytest.raises(ShprobeError, match="--transfer"):
        Session(mesh=str(mesh), hbasis=str(tp))
    other = tmp_path / "other.obj"
    from shprobe.scene.render import sphere_mesh

    sphere_mesh(2).export(other)
    with pytest.raises(ShprobeError, match="another mesh"):
        Session(mesh=str(other), hbasis=str(bake))
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2] / "src"))
    for args, want in ((["--preset", "grace", "--transfer", str(bake)], "--hbasis"),
                       (["--mesh", str(mesh), "--hbasis", str(tp)], "--transfer")):
        r = subprocess.run([sys.executable, "-m", "shprobe", "view", *args, "--no-browser"],
                           capture_output=True, text=True, env=env, timeout=90)
        assert r.returncode == 1
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("shprobe: error:") and want in lines[0]
