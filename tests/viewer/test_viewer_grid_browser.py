"""The grid page in a real headless Chromium (Debian's /usr/bin/chromium, Playwright's Python
client, WebGL2 on SwiftShader): it loads without console errors, draws one sphere per probe,
a probe sphere's pixel is its own SH irradiance under the page's exposure, and moving the
object with its slider lights it with ProbeGrid.irradiance at the new place."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.grids.scenes import room_on_ground
from shprobe.lighting.irradiance import irradiance
from shprobe.viewer.grid import GridView
from tests.viewer.test_viewer import FLAGS, _need_browser
from tests.viewer.test_viewer_grid import GridServed, make_grid

pytestmark = pytest.mark.browser


def _srgb(v):
    v = np.clip(v, 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)


@pytest.fixture(scope="module")
def grid():
    return make_grid()


@pytest.fixture(scope="module")
def page(grid, tmp_path_factory):
    _need_browser()
    from playwright.sync_api import sync_playwright

    served = GridServed(GridView(grid, "room.npz", scene=room_on_ground().mesh(),
                                 scene_name="room.obj"))
    errors: list[str] = []
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path="/usr/bin/chromium", headless=True, args=FLAGS)
        try:
            pg = b.new_page(viewport={"width": 1250, "height": 900})
            pg.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            pg.on("pageerror", lambda e: errors.append(str(e)))
            pg.goto(served.url)
            pg.wait_for_function("() => window.__shprobe && (window.__shprobe.ready || "
                                 "window.__shprobe.lastError)", timeout=60000)
            pg.errors = errors
            pg.shot = tmp_path_factory.mktemp("grid") / "grid_page.png"
            pg.screenshot(path=str(pg.shot), full_page=True)
            yield pg
        finally:
            b.close()
            served.close()


def test_page_loads_and_draws_every_probe(page, grid):
    assert page.evaluate("() => window.__shprobe.lastError") is None
    assert page.errors == []
    st = page.evaluate("() => window.__shprobe.state()")
    assert st["probesDrawn"] == st["probes"] == int(np.prod(grid.resolution))
    assert not st["hasDepth"] and not st["leakControl"]
    # nothing clips: the brightest probe irradiance maps to at most white
    head = page.evaluate("() => window.__shprobe.head")
    assert head["brightest"] / np.pi * 2 ** st["exposure"] <= 1.0
    assert head["brightest"] / np.pi * 2 ** st["exposure"] > 0.5
    assert page.shot.stat().st_size > 10000


def test_probe_pixel_is_its_sh_irradiance(page, grid):
    # only the probes: the scene, the box and the object hidden with the page's checkboxes
    for box in ("#showscene", "#showbox", "#showobject"):
        page.uncheck(box)
    # the largest spheres: more pixels per degree of normal
    page.eval_on_selector("#radius", "(el) => { el.value = '0.45'; "
                          "el.dispatchEvent(new Event('input')); }")
    st = page.evaluate("() => window.__shprobe.state()")
    n = st["probes"]
    val = grid.validity.reshape(n)
    moved = np.linalg.norm(grid.probe_positions() - grid.centres(), axis=-1).reshape(n) > 0
    scr = [page.evaluate(f"() => window.__shprobe.probeScreen({i})") for i in range(n)]
    # the nearest probes are drawn over nothing; skip the marked ones (cages, lines)
    order = [i for i in np.argsort([s["depth"] for s in scr]) if val[i] == 1 and not moved[i]]
    coeffs = grid.coeffs.reshape(n, 9, 3).astype(np.float64)
    checked = 0
    w, h = page.evaluate("() => window.__shprobe.canvasSize()")
    for i in order[:3]:
        s = scr[i]
        if not (0 <= s["x"] < w and 0 <= s["y"] < h):
            continue
        px = np.array(page.evaluate(f"() => window.__shprobe.readPixel({s['x']}, {s['y']})"))
        e = np.maximum(irradiance(coeffs[i], np.array(s["normal"])), 0.0)
        want = 255 * _srgb(e / np.pi * 2 ** st["exposure"])
        assert np.all(np.abs(px[:3] - want) <= 2.0), (i, px, want)  # 8-bit steps
        checked += 1
    assert checked >= 2
    for box in ("#showscene", "#showbox", "#showobject"):
        page.check(box)


def test_canvas_follows_the_window(page):
    """The view fills the space left of the side column (no fixed 720×540 leaving a gap) and
    its drawing buffer follows the canvas's size on the page, one pixel for one."""
    size = page.viewport_size
    try:
        for width, height in ((1400, 900), (1000, 700)):
            page.set_viewport_size({"width": width, "height": height})
            page.wait_for_timeout(300)
            box = page.locator("#view").bounding_box()
            right = page.locator("#right").bounding_box()
            w, h = page.evaluate("() => window.__shprobe.canvasSize()")
            cw, ch = page.evaluate("() => [document.getElementById('view').clientWidth, "
                                   "document.getElementById('view').clientHeight]")
            assert (w, h) == (cw, ch)
            assert right["x"] - (box["x"] + box["width"]) < 40  # no empty band between
            assert box["width"] > 0.5 * width and box["height"] > 0.5 * height
    finally:
        page.set_viewport_size(size)


def test_slider_moves_the_object_and_the_library_lights_it(page, grid):
    page.evaluate("() => window.__shprobe.settled()")
    before = page.evaluate("() => window.__shprobe.lastShade")
    # the X slider dragged to 4.5: its value set and its input event fired, as a drag does
    page.eval_on_selector("#posX", "(el) => { el.value = '4.5'; "
                          "el.dispatchEvent(new Event('input')); }")
    page.wait_for_function("() => window.__shprobe.lastShade && "
                           "window.__shprobe.lastShade.request.position[0] > 4", timeout=30000)
    page.evaluate("() => window.__shprobe.settled()")
    shade = page.evaluate("() => window.__shprobe.lastShade")
    assert shade["request"]["position"][0] != before["request"]["position"][0]
    data = page.evaluate("() => window.__shprobe.objectIrradiance")
    head = page.evaluate("() => window.__shprobe.state()")
    req = shade["request"]
    assert head["placement"]["position"] == req["position"]
    # the same vertices as the server placed: its own view's, in the unit bounding sphere
    view = GridView(grid, "x")
    pts = view.local * req["size"] + np.array(req["position"])
    want = grid.irradiance(pts, view.normals, leak_control=False)
    assert np.allclose(np.array(data).reshape(-1, 3), want, rtol=1e-5, atol=1e-6)


def test_shift_drag_moves_the_object(page, grid):
    page.evaluate("() => window.__shprobe.settled()")
    eye = page.evaluate("() => window.__shprobe.state().eye")
    before = page.evaluate("() => window.__shprobe.state().placement.position")
    o = page.evaluate("() => window.__shprobe.objectScreen()")
    box = page.locator("#view").bounding_box()
    x, y = box["x"] + o["x"], box["y"] + o["y"]
    page.keyboard.down("Shift")
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x - 40, y + 10, steps=4)
    page.mouse.up()
    page.keyboard.up("Shift")
    page.evaluate("() => window.__shprobe.settled()")
    st = page.evaluate("() => window.__shprobe.state()")
    after = st["placement"]["position"]
    assert st["eye"] == eye  # the camera did not orbit
    assert np.linalg.norm(np.subtract(after, before)) > 0.1
    lo, hi = grid.bounds
    assert np.all(np.array(after) >= lo - 1e-9) and np.all(np.array(after) <= hi + 1e-9)
    # the object followed the pointer: its centre is where the pointer let go
    o2 = page.evaluate("() => window.__shprobe.objectScreen()")
    assert abs(o2["x"] - (o["x"] - 40)) < 2 and abs(o2["y"] - (o["y"] + 10)) < 2
    assert page.evaluate("() => window.__shprobe.lastShade.request.position") == after
