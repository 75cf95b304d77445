"""The object's view in headless Chromium: an orbit camera that starts on the object from
above the horizon (elevation > 0, the object whole and large in the frame: checked by
projecting the object's own vertices, here, through the camera the page reads back), orbit,
zoom and a reset back to the start; a PRT scene's ground seen as a floor, not an edge-on
sliver; the canvas fills the space it is given and follows the window (1280×800, 1920×1080)."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.viewer.session import Session
from tests.conftest import data_file
from tests.viewer.viewer_pages import bake_ball, opened, serving, shot

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def _ndc(cam, points):
    """``points`` (N, 3) through the page's camera (three.js column-major matrices) → NDC
    (N, 2) and whether each is in front of the camera."""
    V = np.array(cam["view"]).reshape(4, 4).T
    P = np.array(cam["projection"]).reshape(4, 4).T
    h = np.c_[points, np.ones(len(points))] @ (P @ V).T
    return h[:, :2] / h[:, 3:], h[:, 3] > 0


def _layout(page):
    return page.evaluate("""() => {
      const r = (id) => { const b = document.getElementById(id).getBoundingClientRect();
                          return [b.left, b.top, b.right, b.bottom]; };
      const d = document.documentElement;
      return { view: r('view'), row: r('viewrow'), side: r('right'), w: innerWidth,
               h: innerHeight, scrollW: d.scrollWidth, scrollH: d.scrollHeight }; }""")


@pytest.mark.browser
def test_view_framed_from_above_and_follows_the_window():
    with serving(Session(str(data_file("probes", "grace.hdr")))) as s, opened(s) as page:
        assert page.evaluate("() => window.__shprobe.lastError") is None
        mesh = s.session.mesh
        verts = np.asarray(mesh.vertices) if mesh is not None else np.array(
            [[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) / np.sqrt(3)
        cam = page.evaluate("() => window.__shprobe.cameraState()")
        assert 10 < cam["elevation"] < 60  # above the horizon, not a plan view
        xy, front = _ndc(cam, verts)
        assert front.all()
        assert np.abs(xy).max() <= 1.0  # the whole object is in the frame ...
        span = xy.max(axis=0) - xy.min(axis=0)
        assert span.max() >= 1.0  # ... and fills at least half of it one way
        # the canvas fills the space left of the side column, its drawing buffer follows it
        lay = _layout(page)
        assert lay["scrollW"] <= lay["w"] and lay["scrollH"] <= lay["h"]  # no page scrolling
        assert lay["view"][2] <= lay["side"][0] and lay["row"][3] <= lay["h"]
        assert (cam["width"], cam["height"]) == (cam["clientWidth"], cam["clientHeight"])
        assert cam["width"] > 0.55 * 1280 and cam["height"] > 0.7 * 800
        assert cam["aspect"] == pytest.approx(cam["width"] / cam["height"])
        shot(page, "camera_1280x800")
        page.set_viewport_size({"width": 1920, "height": 1080})
        page.wait_for_function("() => window.__shprobe.cameraState().width > 1100")
        big = page.evaluate("() => window.__shprobe.cameraState()")
        assert big["width"] > 0.6 * 1920 and big["height"] > 0.75 * 1080
        assert big["aspect"] == pytest.approx(big["width"] / big["height"])
        lay = _layout(page)
        assert lay["scrollW"] <= lay["w"] and lay["scrollH"] <= lay["h"]
        assert lay["view"][2] <= lay["side"][0] and lay["row"][3] <= lay["h"]
        xy, _ = _ndc(big, verts)
        assert np.abs(xy).max() <= 1.0 and (xy.max(axis=0) - xy.min(axis=0)).max() >= 1.0
        shot(page, "camera_1920x1080")
        # a tall, narrow window: the object still fits across (the vertical fov widens)
        page.set_viewport_size({"width": 900, "height": 1000})
        page.wait_for_function("() => window.__shprobe.cameraState().width < 700")
        tall = page.evaluate("() => window.__shprobe.cameraState()")
        xy, _ = _ndc(tall, verts)
        assert tall["aspect"] < 1 and np.abs(xy).max() <= 1.0
        page.set_viewport_size({"width": 1280, "height": 800})
        page.wait_for_function("() => window.__shprobe.cameraState().width > 700")
        # orbit (drag), zoom (wheel), then Reset view: back where it started
        start = page.evaluate("() => window.__shprobe.cameraState()")
        box = page.locator("#view").bounding_box()
        cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        page.mouse.move(cx, cy)
        page.mouse.down()
        for i in range(1, 11):
            page.mouse.move(cx + 12 * i, cy + 6 * i)
        page.mouse.up()
        moved = page.evaluate("() => window.__shprobe.cameraState()")
        assert np.linalg.norm(np.subtract(moved["position"], start["position"])) > 1e-3
        assert moved["elevation"] > start["elevation"] + 5  # dragged down: seen from higher
        d0 = np.linalg.norm(np.subtract(moved["position"], moved["target"]))
        page.mouse.wheel(0, -400)
        page.wait_for_timeout(300)
        z = page.evaluate("() => window.__shprobe.cameraState()")
        assert np.linalg.norm(np.subtract(z["position"], z["target"])) < 0.95 * d0
        page.click("#resetview")
        back = page.evaluate("() => window.__shprobe.cameraState()")
        np.testing.assert_allclose(back["position"], start["position"], atol=1e-9)
        np.testing.assert_allclose(back["target"], start["target"], atol=1e-9)
        v = page.evaluate("() => window.__shprobe.viewCamera")
        np.testing.assert_allclose(back["position"], v["eye"], atol=1e-9)
        assert not [m for m in page.shprobe_console if m.startswith(("error:", "pageerror:"))]


@pytest.mark.browser
def test_prt_scene_framed_with_its_ground(tmp_path):
    """A PRT bake on a ground plane: the camera looks down on the object (elevation > 0),
    the object is whole and large in the frame, and the ground around it is a floor: its
    part within the framed radius covers a good part of the frame's height."""
    from shprobe.prt import load_transfer

    tp = bake_ball(tmp_path, lmax=3)
    t = load_transfer(tp)
    with serving(Session(preset="grace", transfer=str(tp))) as s, opened(s) as page:
        page.wait_for_function("() => window.__shprobe.objectBounds")
        cam = page.evaluate("() => window.__shprobe.cameraState()")
        ng = page.evaluate("() => window.__shprobe.objectBounds.ground")
        assert ng == 81  # the 8×8-cell ground plane's vertices, found from the file
        obj, ground = t.vertices[:-ng], t.vertices[-ng:]
        assert cam["elevation"] > 10
        xy, front = _ndc(cam, obj)
        assert front.all() and np.abs(xy).max() <= 1.0
        assert (xy.max(axis=0) - xy.min(axis=0)).max() >= 0.6
        # the ground under and around the object: a disc of twice the object's radius
        c = obj.mean(axis=0)
        r = np.sqrt(((obj - c) ** 2).sum(axis=1).max())
        ring = np.array([[c[0] + 2 * r * np.cos(a), ground[0, 1], c[2] + 2 * r * np.sin(a)]
                         for a in np.linspace(0, 2 * np.pi, 64)])
        gxy, gfront = _ndc(cam, ring)
        assert gfront.all()
        assert gxy[:, 1].max() - gxy[:, 1].min() > 0.5  # seen from above: not a sliver
        shot(page, "camera_prt")


def test_refined_bake_ground_found_wherever_its_vertices_are():
    """A refined bake splits the ground's triangles and appends their new vertices after the
    object's: the ground is still found (every vertex of the plane, none of the ball's), so
    the object is framed on the ball alone (its bounding radius, 1, not the ground's)."""
    import trimesh

    from shprobe.prt import bake
    from shprobe.viewer.payloads import ground_mask

    t = bake(trimesh.creation.icosphere(2), mode="shadowed", lmax=2, samples=64, ground=True,
             refine="quick")
    v = np.asarray(t.vertices)
    flat = ground_mask(v, t.normals, True)
    assert np.nonzero(~flat)[0].max() > np.nonzero(flat)[0].min()  # interleaved
    assert flat.sum() >= 65 * 65  # the 64×64-cell plane's own vertices, and its splits
    foot = np.linalg.norm(v[:, [0, 2]], axis=1) < 0.5  # where the ball touches the plane
    on_plane = np.isclose(v[:, 1], v[:, 1].min()) & ~foot
    assert np.all(flat[on_plane])
    obj = v[~flat]
    c = 0.5 * (obj.min(axis=0) + obj.max(axis=0))
    assert np.sqrt(((obj - c) ** 2).sum(axis=1).max()) == pytest.approx(1.0, abs=1e-6)
