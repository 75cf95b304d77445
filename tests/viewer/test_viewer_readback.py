"""The page reads pixels back from the GPU only when asked: a normal session (load, edits, a
drag, the exposure) calls no ``readPixels`` and Chromium logs no "GPU stall due to
ReadPixels"; the benchmark's URL flag (``&bench=1``) turns the timed read-back on (each frame
it times is then finished).

Chromium's WebGL-fallback mode (``--use-angle=swiftshader-webgl``, software compositing) reads
every WebGL frame back to composite it and logs the stall for any page, even one that only
clears; the tests' mode (SwiftShader as the GL of everything) reports the page's own reads,
so that is where the console is checked."""

from __future__ import annotations

import pytest

from shprobe.viewer.session import Session
from tests.conftest import data_file
from tests.viewer.viewer_pages import opened, serving, set_state

pytestmark = [pytest.mark.browser, pytest.mark.filterwarnings("ignore::DeprecationWarning")]

#: counts the page's readPixels calls (installed before any script of the page runs)
COUNT_READS = """(() => {
  window.__reads = 0;
  for (const C of [WebGLRenderingContext, WebGL2RenderingContext]) {
    const orig = C.prototype.readPixels;
    C.prototype.readPixels = function (...a) { window.__reads += 1; return orig.apply(this, a); };
  }
})();"""


def _session_of_edits(page):
    set_state(page, {"lmax": 2, "scale_band": {"1": 0.5}})
    set_state(page, {"lmax": 4, "scale": {"1,0": 2}})
    page.locator("#exposure").fill("1")
    box = page.locator("#probe").bounding_box()
    page.mouse.move(box["x"] + 100, box["y"] + 100)
    page.mouse.down()
    for i in range(5):
        page.mouse.move(box["x"] + 100 + 8 * i, box["y"] + 100)
    page.mouse.up()
    page.evaluate("() => window.__shprobe.settled()")
    page.wait_for_timeout(500)  # late console messages (the GPU process sends them)




def test_no_readpixels_in_a_normal_session():
    with serving(Session(str(data_file("probes", "grace.hdr")))) as s, \
            opened(s, init_script=COUNT_READS) as page:
        assert page.evaluate("() => window.__shprobe.ready")
        _session_of_edits(page)
        assert page.evaluate("() => window.__shprobe.frames") > 3
        assert not page.evaluate("() => window.__shprobe.readback")
        assert page.evaluate("() => window.__reads") == 0
        msgs = [m for m in page.shprobe_console if "readpixels" in m.lower()]
        assert not msgs, msgs


def test_bench_flag_turns_the_timed_readback_on():
    with serving(Session(str(data_file("probes", "grace.hdr")))) as s:
        s.url += "&bench=1"
        with opened(s, init_script=COUNT_READS) as page:
            assert page.evaluate("() => window.__shprobe.readback")
            _session_of_edits(page)
            frames = page.evaluate("() => window.__shprobe.frames")
            # one read per frame timed, one at start-up (boot.js) and one for its programs
            assert page.evaluate("() => window.__reads") >= frames
            assert page.evaluate("() => window.__shprobe.firstFrameMs") > 0
