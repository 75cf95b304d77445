"""The grid page's first view shows what leak control does without any control touched: on a
grid with depth data the object starts where leak control on and off light it most
differently (beside a wall of the room, not inside the closed room where both are black), and
each shading answer carries the other setting's mean as well; without depth data it starts at
the volume's centre."""

from __future__ import annotations

import re

import numpy as np
import pytest

from shprobe.viewer.grid import GridView, parse_placement
from tests.viewer.test_viewer_grid import make_grid


@pytest.fixture(scope="module")
def room():
    from shprobe.grids import GridSettings, bake_grid
    from shprobe.grids.scenes import room_on_ground
    from shprobe.lighting.source import resolve_lighting
    from shprobe.prt.geometry import load_scene

    r = room_on_ground()
    g = bake_grid(load_scene(r.mesh(), albedo=0.5), resolve_lighting(preset="grace"),
                  GridSettings((7, 4, 7), bounds=r.bounds, bounces=0, samples=256))
    return r, g


def _means(view, pos, size):
    pts = view.local * size + np.asarray(pos)
    on = view.grid.irradiance(pts, view.normals, leak_control=True).mean(axis=0)
    off = view.grid.irradiance(pts, view.normals, leak_control=False).mean(axis=0)
    return on, off


def test_first_place_shows_the_leak_difference(room):
    r, g = room
    view = GridView(g, "room.npz")
    d = view.defaults()
    lo, hi = g.bounds
    assert np.all(np.asarray(d["position"]) - d["size"] >= lo - 1e-9)
    assert np.all(np.asarray(d["position"]) + d["size"] <= hi + 1e-9)
    on, off = _means(view, d["position"], d["size"])
    centre_on, centre_off = _means(view, 0.5 * (lo + hi), d["size"])
    print(f"first place {np.round(d['position'], 2)}: on {on.round(3)} off {off.round(3)}; "
          f"centre: on {centre_on.round(3)} off {centre_off.round(3)}")
    diff = np.abs(on - off).sum()
    assert diff > 0.25 * max(on.sum(), off.sum())  # a difference the eye sees
    assert diff > 3 * np.abs(centre_on - centre_off).sum()  # far more than at the centre
    assert not r.inside(np.asarray(d["position"])[None])[0]  # not inside the closed room
    # the shading answer of that place gives both settings
    p = parse_placement(d, g)
    e, leak = view.shade(p)
    assert leak and np.allclose(e.mean(axis=0), on)
    assert np.allclose(view.other_mean(p), off)


def test_without_depth_the_centre():
    g = make_grid(depth=False)
    view = GridView(g, "plain.npz")
    lo, hi = g.bounds
    assert np.allclose(view.defaults()["position"], 0.5 * (lo + hi))
    assert view.other_mean(parse_placement(view.defaults(), g)) is None


@pytest.mark.browser
def test_first_frame_in_the_browser_shows_both_settings(room, tmp_path):
    """The page as opened: the object in view (not hidden behind a probe: the pixel at its
    centre is lit, not the background), and its mean E with leak control on and off side by
    side, as the library computes them."""
    from tests.support.browser import chromium_page
    from tests.viewer.test_viewer_grid import GridServed

    r, g = room
    view = GridView(g, "room.npz", scene=r.mesh(), scene_name="room")
    served = GridServed(view)
    try:
        with chromium_page() as page:
            page.set_viewport_size({"width": 1400, "height": 900})
            page.goto(served.url)
            page.wait_for_function("() => window.__shprobe && (window.__shprobe.ready || "
                                   "window.__shprobe.lastError)", timeout=90000)
            assert page.evaluate("() => window.__shprobe.lastError") is None
            page.screenshot(path=str(tmp_path / "grid_first_view.png"))
            text = page.locator("#objmean").inner_text()
            d = view.defaults()
            on, off = _means(view, d["position"], d["size"])
            print(text)
            nums = [float(v) for v in re.findall(r"[-0-9.e+]+(?=[,)])", text)]
            assert "leak control on" in text and "off (plain trilinear)" in text
            np.testing.assert_allclose(nums, [*on, *off], rtol=5e-3)  # 3 digits shown
            w, h = page.evaluate("() => window.__shprobe.canvasSize()")
            assert w > 900  # the view fills the window beside the side column
            o = page.evaluate("() => window.__shprobe.objectScreen()")
            x, y = int(o["x"]), int(o["y"])
            assert 0 <= x < w and 0 <= y < h
            px = page.evaluate(f"() => window.__shprobe.readPixel({x}, {y})")
            assert max(px[:3]) > 60, px  # lit, not the dark background
    finally:
        served.close()
