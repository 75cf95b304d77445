"""The grid page's leak-control checkbox in a real headless Chromium: each answer is
ProbeGrid.irradiance with that leak_control (its own browser, apart from the module-scoped page
of test_viewer_grid_browser.py: Playwright's sync API runs one at a time)."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.viewer.grid import GridView
from tests.viewer.test_viewer import FLAGS, _need_browser
from tests.viewer.test_viewer_grid import GridServed, make_grid

pytestmark = pytest.mark.browser


def test_leak_control_toggle(tmp_path):
    """On a grid with depth data the page's checkbox switches the library's interpolation:
    each answer is ProbeGrid.irradiance with that leak_control, and the two differ."""
    _need_browser()
    from playwright.sync_api import sync_playwright

    g = make_grid(depth=True)
    served = GridServed(GridView(g, "depth.npz"))
    try:
        with sync_playwright() as pw:
            b = pw.chromium.launch(executable_path="/usr/bin/chromium", headless=True,
                                   args=FLAGS)
            pg = b.new_page()
            pg.goto(served.url)
            pg.wait_for_function("() => window.__shprobe && (window.__shprobe.ready || "
                                 "window.__shprobe.lastError)", timeout=60000)
            assert pg.evaluate("() => window.__shprobe.lastError") is None
            assert pg.is_checked("#leak") and pg.is_enabled("#leak")
            got = {}
            for leak in (True, False):
                pg.set_checked("#leak", leak)
                pg.wait_for_function(f"() => window.__shprobe.lastShade.leak_control === "
                                     f"{'true' if leak else 'false'}", timeout=30000)
                pg.evaluate("() => window.__shprobe.settled()")
                req = pg.evaluate("() => window.__shprobe.lastShade.request")
                got[leak] = np.array(pg.evaluate("() => window.__shprobe.objectIrradiance"))
            b.close()
    finally:
        served.close()
    view = GridView(g, "x")
    pts = view.local * req["size"] + np.array(req["position"])
    for leak, e in got.items():
        want = g.irradiance(pts, view.normals, leak_control=leak)
        assert np.allclose(e.reshape(-1, 3), want, rtol=1e-5, atol=1e-6)
    assert np.max(np.abs(got[True] - got[False])) > 1e-3 * np.max(got[False])
