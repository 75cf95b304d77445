"""The lightmap page (``shprobe view --lightmap``) in headless Chromium (WebGL2 on
SwiftShader): it loads without console errors; a pixel is the library's evaluation of the
stored lightmap (bilinear RGBA16F texels, format.evaluate at the normal-map normal, albedo / π,
exposure, sRGB) within 2/255; the float E the page's exported GLSL computes from the textures
it read out of the .glb equals the library's to 1e-3 of the peak; Fig. 1 and Fig. 5 layouts,
albedo off and the texel grid do what they say."""

from __future__ import annotations

import io
import math
import os
from pathlib import Path

import numpy as np
import pytest

from shprobe.lightmaps import format as fmt
from shprobe.viewer.lightmap import load_lightmap_view
from tests.lightmaps.lightmap_files import bilinear, floor_lightmap, lightmap_page
from tests.viewer.test_viewer import Served

SHOTS = Path(os.environ.get("SHPROBE_VIEWER_SHOTS", "/tmp"))
pytestmark = pytest.mark.browser  # the CLI test at the end needs no browser, but is cheap


def _srgb(v):
    v = np.clip(v, 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)


@pytest.fixture(scope="module")
def lightmap(tmp_path_factory):
    return floor_lightmap(tmp_path_factory.mktemp("lm") / "floor_h6.glb")


@pytest.fixture(scope="module")
def page(lightmap):
    with lightmap_page(lightmap, 820) as pg:
        yield pg


def _canvas(page, name: str) -> np.ndarray:
    import base64

    from PIL import Image

    page.screenshot(path=str(SHOTS / f"lightmap_page_{name}.png"))
    url = page.evaluate("() => document.getElementById('view').toDataURL('image/png')")
    raw = base64.b64decode(url.split(",", 1)[1])
    return np.asarray(Image.open(io.BytesIO(raw)).convert("RGB"))


def _floor_pixels(page, n=60, seed=0):
    """Canvas pixels on the floor (uv1 read back inside the map), as (x, y) pairs."""
    rng = np.random.default_rng(seed)
    pts = np.stack([rng.integers(20, 940, 4 * n), rng.integers(300, 530, 4 * n)], 1).tolist()
    uv = np.array(page.evaluate("(p) => window.__shprobe.readback('uv1', p)", pts))
    ok = (uv[:, 0] > 0.02) & (uv[:, 0] < 0.98) & (uv[:, 1] > 0.02) & (uv[:, 1] < 0.98)
    return [pts[i] for i in np.flatnonzero(ok)[:n]], uv[ok][:n, :2]


def test_page_loads_without_console_errors(page):
    assert page.evaluate("() => window.__shprobe.lastError") is None
    assert page.errors == []
    head = page.evaluate("() => window.__shprobe.head")
    assert head["encoding"] == "h6" and head["encodings"] == ["plain", "h4", "h6"]
    assert "transfer" not in head and not page.is_visible("#skybox")  # no transfer, no sky


def test_a_pixel_is_the_librarys_evaluation(page, lightmap):
    st = page.evaluate("() => window.__shprobe.set({layout: 'single', encoding: 'h6', "
                       "albedo: true, grid: false})")
    img = _canvas(page, "h6_albedo")
    pts, uv = _floor_pixels(page)
    assert len(pts) >= 40
    n = np.array(page.evaluate("(p) => window.__shprobe.readback('normal', p)", pts))
    alb = np.array(page.evaluate("(p) => window.__shprobe.readback('albedo', p)", pts))
    assert np.abs(np.linalg.norm(n, axis=1) - 1).max() < 1e-3
    assert np.mean(np.abs(n[:, 2]) < 0.995) > 0.2  # the normal map does tilt the normals
    doc, binary = fmt.read_glb(lightmap)
    stored = fmt.read_lightmap(doc, binary)
    e = fmt.evaluate("h6", bilinear(stored.coeffs.astype(np.float64), uv), n)
    want = _srgb(alb / math.pi * e * 2.0 ** st["exposure"]) * 255
    got = img[[y for _, y in pts], [x for x, _ in pts]]
    assert np.abs(got - want).max() <= 2.0, np.abs(got - want).max()


def _library_e(lightmap, encoding, uv, n):
    """E from the library: ``Lightmap.irradiance`` of the file's own encoding, the implied
    ones (lightmaps.derive) evaluated by format.evaluate."""
    from shprobe.lightmaps import load_lightmap
    from shprobe.lightmaps.derive import implied_encodings

    lm = load_lightmap(lightmap)
    if encoding == lm.basis:
        return lm.irradiance(np.asarray(uv, np.float64), n)
    c = implied_encodings(lm.basis, lm.coefficients())[encoding]
    return fmt.evaluate(encoding, bilinear(c, uv), n)


@pytest.mark.parametrize("encoding", ["h6", "h4", "plain"])
def test_float_irradiance_from_the_glb_equals_the_librarys(page, lightmap, encoding):
    """The page's E (the .glb's RGBA16F textures in three.js — h6 as read from the file,
    h4 and plain as the server derived them — shaded by the exported GLSL) at the read-back
    uv1 and normal, against the library's, to 1e-3 of the peak."""
    page.evaluate("(e) => window.__shprobe.set({layout: 'single', encoding: e})", encoding)
    pts, uv = _floor_pixels(page, seed=1)
    n = np.array(page.evaluate("(p) => window.__shprobe.readback('normal', p)", pts))
    got = np.array(page.evaluate("(p) => window.__shprobe.readback('irradiance', p)", pts))
    want = _library_e(lightmap, encoding, uv, n)
    if encoding == "plain":
        np.testing.assert_allclose(n, np.broadcast_to([0, 0, 1], n.shape), atol=1e-6)
    assert np.abs(got - want).max() <= 1e-3 * np.abs(want).max()


def test_fig1_panels_plain_h6_and_h6_with_albedo(page, lightmap):
    st = page.evaluate("() => window.__shprobe.set({layout: 'fig1'})")
    assert [p["label"] for p in st["panels"]] == [
        "plain lightmap (normal map ignored)", "H6, without albedo", "H6, with albedo"]
    img = _canvas(page, "fig1")
    # the same floor point in the middle and right panels: one without albedo, one with
    pts = [[320 + 100, 450], [640 + 100, 450]]
    e = np.array(page.evaluate("(p) => window.__shprobe.readback('irradiance', p)", pts))
    alb = np.array(page.evaluate("(p) => window.__shprobe.readback('albedo', p)", pts))
    for (x, y), ee, a, with_albedo in zip(pts, e, alb, (False, True), strict=True):
        want = _srgb((a if with_albedo else 1.0) / math.pi * ee * 2.0 ** st["exposure"]) * 255
        assert np.abs(img[y, x] - want).max() <= 2.0
    assert np.abs(e[0] - e[1]).max() < 1e-6  # one camera, one exposure: the same E


def test_fig5_h4_beside_h6(page, lightmap):
    """Two panels of one camera: the same pixel of each shows H4's and H6's E there, as the
    library evaluates them (the difference: H6's two quadratic terms)."""
    st = page.evaluate("() => window.__shprobe.set({layout: 'fig5', albedo: true})")
    assert [p["encoding"] for p in st["panels"]] == ["h4", "h6"]
    _canvas(page, "fig5")
    rng = np.random.default_rng(2)
    left = np.stack([rng.integers(10, 470, 200), rng.integers(330, 530, 200)], 1)
    right = left + np.array([480, 0])
    uv_l = np.array(page.evaluate("(p) => window.__shprobe.readback('uv1', p)", left.tolist()))
    uv_r = np.array(page.evaluate("(p) => window.__shprobe.readback('uv1', p)", right.tolist()))
    ok = (np.abs(uv_l - uv_r).max(axis=1) < 1e-6) & (uv_l[:, :2].min(axis=1) > 0.02)
    assert ok.sum() > 50
    pts_l, pts_r, uv = left[ok].tolist(), right[ok].tolist(), uv_l[ok, :2]
    n = np.array(page.evaluate("(p) => window.__shprobe.readback('normal', p)", pts_r))
    e4 = np.array(page.evaluate("(p) => window.__shprobe.readback('irradiance', p)", pts_l))
    e6 = np.array(page.evaluate("(p) => window.__shprobe.readback('irradiance', p)", pts_r))
    w4, w6 = _library_e(lightmap, "h4", uv, n), _library_e(lightmap, "h6", uv, n)
    peak = np.abs(w6).max()
    assert np.abs(e4 - w4).max() <= 1e-3 * peak and np.abs(e6 - w6).max() <= 1e-3 * peak
    assert np.abs(w6 - w4).max() > 10 * 1e-3 * peak  # the panels do differ


def test_texel_grid_overlay_marks_texel_edges(page):
    page.evaluate("() => window.__shprobe.set({layout: 'single', encoding: 'h6', grid: false})")
    plain = _canvas(page, "nogrid").astype(float)
    page.evaluate("() => window.__shprobe.set({grid: true})")
    grid = _canvas(page, "grid").astype(float)
    page.evaluate("() => window.__shprobe.set({grid: false})")
    changed = np.abs(grid - plain).max(axis=2) > 8
    # lines, not a wash: a few per cent of the floor's pixels, bluer than before
    floor = plain[300:].sum(axis=2) > 30
    frac = changed[300:][floor].mean()
    assert 0.005 < frac < 0.35, frac
    d = (grid - plain)[changed]
    assert (d[:, 2] - d[:, 0]).mean() > 0


def test_view_lightmap_refuses_bad_input_in_one_line(tmp_path, capsys):
    from shprobe.cli.main import main

    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"not a glb at all, just text")
    assert main(["view", "--lightmap", str(bad), "--no-browser"]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad.glb" in err and "binary glTF" in err
    assert main(["view", "--lightmap", str(bad), "--preset", "grace", "--no-browser"]) != 0
    assert "--lightmap shows the file's own" in capsys.readouterr().err
    plain = tmp_path / "scene.glb"  # a glTF without the extension
    from shprobe.lightmaps.scenes import game_scene_path

    plain.write_bytes(game_scene_path().read_bytes())
    assert main(["view", "--lightmap", str(plain), "--no-browser"]) != 0
    assert "has no SHPROBE_lightmap extension" in capsys.readouterr().err


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """A small real bake of the game scene (sky, one bounce), stored as L2 SH."""
    from shprobe.lightmaps import LightmapSettings, bake_lightmap, load_scene
    from shprobe.lightmaps.scenes import game_scene_path
    from shprobe.probes.presets import get_preset

    lm = bake_lightmap(load_scene(game_scene_path()), get_preset("grace"),
                       LightmapSettings(basis="sh9", size=128, samples=16, bounces=1))
    path = tmp_path_factory.mktemp("baked") / "courtyard_sh9.glb"
    lm.save(path)
    return path


def test_a_baked_scene_in_the_page_is_the_librarys_evaluation(page, baked):
    """Every surface of the game scene (five meshes, four materials, TANGENT frames, the
    bake's xatlas UVs): the page's float E (H6 implied by the stored L2 SH) and its pixels
    equal the library's at the read-back uv1 and normal-map normal."""
    served = Served(None, grid=load_lightmap_view(baked), page="/lightmap")
    errors: list[str] = []
    # a second page of the module's browser (one Playwright per thread)
    pg = page.context.browser.new_page(viewport={"width": 1500, "height": 820})
    try:
        pg.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        pg.on("pageerror", lambda e: errors.append(str(e)))
        pg.goto(served.url)
        pg.wait_for_function("() => window.__shprobe && (window.__shprobe.ready || "
                             "window.__shprobe.lastError)", timeout=90000)
        assert pg.evaluate("() => window.__shprobe.lastError") is None and errors == []
        st = pg.evaluate("() => window.__shprobe.set({layout: 'single', encoding: 'h6', "
                         "albedo: true})")
        assert st["panels"][0]["encoding"] == "h6"
        img = _canvas(pg, "baked_h6")
        rng = np.random.default_rng(5)
        pts = np.stack([rng.integers(5, 955, 300), rng.integers(5, 535, 300)], 1).tolist()
        uv = np.array(pg.evaluate("(p) => window.__shprobe.readback('uv1', p)", pts))
        hit = uv[:, 2] == 0  # the background clears to a grey with z = clear colour
        hit &= (uv[:, :2] > 0).all(axis=1) & (uv[:, :2] < 1).all(axis=1)
        pts = [pts[i] for i in np.flatnonzero(hit)]
        assert len(pts) > 150
        uv = uv[hit, :2]
        n = np.array(pg.evaluate("(p) => window.__shprobe.readback('normal', p)", pts))
        e = np.array(pg.evaluate("(p) => window.__shprobe.readback('irradiance', p)", pts))
        alb = np.array(pg.evaluate("(p) => window.__shprobe.readback('albedo', p)", pts))
    finally:
        pg.close()
        served.close()
    want = _library_e(baked, "h6", uv, n)
    peak = np.abs(want).max()
    err = np.abs(e - want).max(axis=1)
    # bilinear weights in 8 fractional bits on the GPU: beside a chart's seams, neighbouring
    # texels differ most; the bulk agrees to 1e-3 of the peak
    assert np.percentile(err, 95) <= 1e-3 * peak and err.max() <= 1e-2 * peak
    px = _srgb(alb / math.pi * want * 2.0 ** st["exposure"]) * 255
    got = img[[y for _, y in pts], [x for x, _ in pts]]
    assert np.percentile(np.abs(got - px).max(axis=1), 95) <= 2.0
