"""Live relighting in the lightmap page (``shprobe view --lightmap`` of a ``--transfer`` bake),
in headless Chromium (WebGL2 on SwiftShader): the page turns the bake's sky (rotation.js) and
sums Σ_j T_j L_j per texel on the GPU from the transfer textures it reads out of the .glb. The
relit texels and the float E at pixels equal the library's ``Lightmap.relight`` under the sky
turned by ``shprobe.sh.rotation`` to 1e-3 of the peak; at 0° the page shows the bake itself."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from shprobe.lightmaps import format as fmt
from shprobe.viewer.lightmap import load_lightmap_view
from tests.lightmaps.lightmap_files import bilinear, lightmap_page

SHOTS = Path(os.environ.get("SHPROBE_VIEWER_SHOTS", "/tmp"))
pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """A small transfer bake of the game scene (H6, sky only, one bounce)."""
    from shprobe.lightmaps import LightmapSettings, bake_lightmap, load_scene
    from shprobe.lightmaps.scenes import game_scene_path
    from shprobe.probes.presets import get_preset

    lm = bake_lightmap(load_scene(game_scene_path()), get_preset("grace"),
                       LightmapSettings(basis="h6", size=64, samples=16, bounces=1,
                                        transfer=True, seed=3))
    path = tmp_path_factory.mktemp("relight") / "courtyard_h6_transfer.glb"
    lm.save(path)
    return path


@pytest.fixture(scope="module")
def page(baked):
    with lightmap_page(baked, 900) as pg:
        yield pg


def _sky(baked):
    from shprobe.lightmaps import load_lightmap

    lm = load_lightmap(baked)
    return lm, np.asarray(lm.stats["sky"], np.float64)


def _turned(sky, degrees):
    from shprobe.sh.rotation import from_axis_angle, rotate

    return rotate(sky, from_axis_angle([0, 1, 0], degrees))  # +Y is up


def _pixels(page, n=300, seed=5):
    """Canvas pixels on the scene: (x, y) pairs, their uv1, normal-map normals and E."""
    rng = np.random.default_rng(seed)
    pts = np.stack([rng.integers(5, 955, n), rng.integers(5, 535, n)], 1).tolist()
    uv = np.array(page.evaluate("(p) => window.__shprobe.readback('uv1', p)", pts))
    hit = (uv[:, 2] == 0) & (uv[:, :2] > 0).all(axis=1) & (uv[:, :2] < 1).all(axis=1)
    pts = [pts[i] for i in np.flatnonzero(hit)]
    nrm = np.array(page.evaluate("(p) => window.__shprobe.readback('normal', p)", pts))
    e = np.array(page.evaluate("(p) => window.__shprobe.readback('irradiance', p)", pts))
    return pts, uv[hit, :2], nrm, e


def _shot(page, name):
    page.screenshot(path=str(SHOTS / f"lightmap_relight_{name}.png"))


def test_the_sky_control_shows_for_a_transfer_file(page):
    assert page.evaluate("() => window.__shprobe.lastError") is None
    assert page.errors == []
    head = page.evaluate("() => window.__shprobe.head")
    assert head["transfer"]["sky_source"] == "stored"
    assert page.is_visible("#skybox") and page.is_visible("#sky_azimuth")
    st = page.evaluate("() => window.__shprobe.set({layout: 'single', encoding: 'h6'})")
    assert st["relight"] and "sky turned 0° tilted 0°" in st["panels"][0]["label"]


def test_the_page_turns_the_sky_as_the_library_does(page, baked):
    _, sky = _sky(baked)
    page.evaluate("() => window.__shprobe.set({sky: {azimuth: 90}})")
    got = np.array(page.evaluate("() => window.__shprobe.turnedSky()"))
    np.testing.assert_allclose(got, _turned(sky, 90), atol=1e-9 * np.abs(sky).max())
    # the tilt after the turn, the band scales, the strength in stops
    page.evaluate("() => window.__shprobe.set({sky: {azimuth: 30, elevation: 40, l0: 0.8, "
                  "l1: 0.5, l2: 1.5, stops: 0.5}})")
    got = np.array(page.evaluate("() => window.__shprobe.turnedSky()"))
    from shprobe.sh.rotation import from_axis_angle, rotate

    scaled = sky * np.array([0.8] + [0.5] * 3 + [1.5] * 5)[:, None] * 2**0.5
    want = rotate(scaled, from_axis_angle([1, 0, 0], 40) @ from_axis_angle([0, 1, 0], 30))
    np.testing.assert_allclose(got, want, atol=1e-9 * np.abs(sky).max())
    page.evaluate("() => window.__shprobe.set({sky: {azimuth: 0, elevation: 0, l0: 1, l1: 1, "
                  "l2: 1, stops: 0}})")


def test_relit_texels_at_90_degrees_equal_the_librarys_relight(page, baked):
    """The GPU pass's output, texel by texel, unpacked by the file's own layout."""
    lm, sky = _sky(baked)
    st = page.evaluate("() => window.__shprobe.set({layout: 'single', encoding: 'h6', "
                       "sky: {azimuth: 90}})")
    _shot(page, "90")
    head = page.evaluate("() => window.__shprobe.head")
    h, w = head["height"], head["width"]
    got = np.zeros((h, w, 6, 3))
    for t, chans in enumerate(head["layouts"]["h6"]):
        tex = np.array(page.evaluate("(t) => window.__shprobe.relitTexels(t)", t))
        tex = tex.reshape(h, w, 4) * head["scale"]
        for ch, ic in enumerate(chans):
            if ic is not None:
                got[:, :, ic[0], ic[1]] = tex[:, :, ch]
    want = lm.relight(_turned(sky, 90)).coefficients("h6")
    peak = np.abs(want).max()
    assert np.abs(got - want).max() <= 1e-3 * peak
    assert np.abs(want - lm.coefficients("h6")).max() > 0.05 * peak  # the turn does relight
    assert "sky turned 90° tilted 0°" in st["panels"][0]["label"]


@pytest.mark.parametrize("encoding", ["h4", "plain"])
def test_implied_encodings_are_relit_as_the_library_derives_them(page, baked, encoding):
    """H4 and plain from the relit H6 (lightmaps.derive), texel by texel: the page relights
    them from the implied encodings of the transfer, which the server sends."""
    from shprobe.lightmaps.derive import implied_encodings

    lm, sky = _sky(baked)
    st = page.evaluate("(e) => window.__shprobe.set({layout: 'single', encoding: e, "
                       "sky: {azimuth: 90}})", encoding)
    assert "sky turned 90° tilted 0°" in st["panels"][0]["label"]
    head = page.evaluate("() => window.__shprobe.head")
    h, w = head["height"], head["width"]
    want = implied_encodings("h6", lm.relight(_turned(sky, 90)).coefficients("h6"))[encoding]
    got = np.zeros(want.shape)
    for t, chans in enumerate(head["layouts"][encoding]):
        tex = np.array(page.evaluate("([t, e]) => window.__shprobe.relitTexels(t, e)",
                                     [t, encoding])).reshape(h, w, 4) * head["scale"]
        for ch, ic in enumerate(chans):
            if ic is not None:
                got[:, :, ic[0], ic[1]] = tex[:, :, ch]
    assert np.abs(got - want).max() <= 1e-3 * np.abs(want).max()


def test_float_irradiance_at_90_degrees_equals_the_librarys(page, baked):
    lm, sky = _sky(baked)
    page.evaluate("() => window.__shprobe.set({layout: 'single', encoding: 'h6', "
                  "sky: {azimuth: 90}})")
    pts, uv, n, e = _pixels(page)
    assert len(pts) > 150
    relit = lm.relight(_turned(sky, 90)).coefficients("h6").astype(np.float64)
    want = fmt.evaluate("h6", bilinear(relit, uv), n)
    peak = np.abs(want).max()
    # the relit textures are float render targets, filtered at float precision: every pixel
    assert np.abs(e - want).max() <= 1e-3 * peak
    unrot = fmt.evaluate("h6", bilinear(lm.coefficients("h6").astype(np.float64), uv), n)
    assert np.abs(unrot - want).max() > 0.05 * peak


def test_at_0_degrees_the_page_shows_the_bake(page, baked):
    lm, _ = _sky(baked)
    page.evaluate("() => window.__shprobe.set({layout: 'single', encoding: 'h6', "
                  "sky: {azimuth: 0}})")
    _shot(page, "0")
    pts, uv, n, e = _pixels(page, seed=6)
    page.evaluate("() => window.__shprobe.set({relight: false})")
    stored = np.array(page.evaluate("(p) => window.__shprobe.readback('irradiance', p)", pts))
    page.evaluate("() => window.__shprobe.set({relight: true})")
    want = fmt.evaluate("h6", bilinear(lm.coefficients("h6").astype(np.float64), uv), n)
    peak = np.abs(want).max()
    assert np.abs(e - want).max() <= 1e-3 * peak  # the transfer's half floats: ~2e-4
    assert np.percentile(np.abs(e - stored).max(axis=1), 95) <= 1e-3 * peak


def test_sky_strength_and_band_scales_are_linear(page, baked):
    """One stop doubles E; band 1 and 2 at 0 leave the constant sky's transfer alone."""
    lm, sky = _sky(baked)
    page.evaluate("() => window.__shprobe.set({sky: {azimuth: 30, stops: 1}})")
    pts, uv, n, e2 = _pixels(page, seed=7)
    page.evaluate("() => window.__shprobe.set({sky: {stops: 0, l1: 0, l2: 0}})")
    e0 = np.array(page.evaluate("(p) => window.__shprobe.readback('irradiance', p)", pts))
    page.evaluate("() => window.__shprobe.set({sky: {azimuth: 0, l1: 1, l2: 1}})")
    k = sky * 0
    k[0] = sky[0]
    want0 = fmt.evaluate("h6", bilinear(lm.relight(k).coefficients("h6").astype(np.float64),
                                        uv), n)
    want2 = 2 * fmt.evaluate("h6", bilinear(lm.relight(_turned(sky, 30)).coefficients("h6")
                                            .astype(np.float64), uv), n)
    for got, want in ((e0, want0), (e2, want2)):
        assert np.abs(got - want).max() <= 1e-3 * np.abs(want).max()
    assert page.errors == []


def test_a_file_without_its_sky_gets_the_sky_that_reproduces_it(baked, tmp_path):
    """The transfer without ``"sky"``: the page relights from the least-squares sky, which is
    the bake's (no sun) to the half-float precision of the textures."""
    _, sky = _sky(baked)
    doc, binary = fmt.read_glb(baked)
    del doc["extensions"][fmt.EXTENSION]["transfer"]["sky"]
    fmt.write_glb(tmp_path / "nosky.glb", doc, binary)
    view = load_lightmap_view(tmp_path / "nosky.glb")
    fitted, source = view.sky
    assert source == "fitted"
    np.testing.assert_allclose(fitted, sky, atol=1e-3 * np.abs(sky).max())


def test_the_cli_serves_the_lightmap_page(baked):
    """``shprobe view --lightmap FILE``: the URL it prints opens the page, its data holds the
    transfer's sky."""
    import json
    import subprocess
    import sys

    import httpx

    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    proc = subprocess.Popen([sys.executable, "-m", "shprobe", "view", "--lightmap", str(baked),
                             "--no-browser", "--port", "0"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    try:
        line = proc.stdout.readline()
        assert line.startswith("shprobe view: http://") and "/lightmap?token=" in line, (
            line + proc.stderr.read() if proc.poll() is not None else line)
        url = line.split(": ", 1)[1].strip()
        base, token = url.split("/lightmap?token=")
        with httpx.Client(base_url=base, params={"token": token}, timeout=60) as c:
            assert c.get("/lightmap").status_code == 200
            r = c.get("/api/lightmap")
            assert r.status_code == 200
            n = int.from_bytes(r.content[:4], "little")  # pack_binary: length, JSON head
            head = json.loads(r.content[4:4 + n])
        assert head["transfer"]["sky_source"] == "stored"
    finally:
        proc.terminate()
        proc.wait(timeout=30)
