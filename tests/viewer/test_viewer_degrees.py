"""Every degree the data has is editable in the page (headless Chromium): an lmax-6 PRT
transfer gives the design lmax menu every degree 0..DESIGN_LMAX with 6 chosen, band sliders
l = 0..6, per-coefficient sliders 2l+1 per band (bands above 2 collapsed), a PRT lmax menu
0..6; a high-band slider edits the library's coefficients; the controls of other modes are
hidden (Bounces outside the interreflected model, the error degree outside the error view)."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.viewer.design import DESIGN_LMAX
from shprobe.viewer.session import Session
from tests.viewer.viewer_pages import bake_ball, opened, serving, settle, shot

pytestmark = [pytest.mark.browser, pytest.mark.filterwarnings("ignore::DeprecationWarning")]

SLIDERS = """() => {
  const count = (sel) => { const n = {}; for (const e of document.querySelectorAll(sel))
    n[e.dataset.band] = (n[e.dataset.band] || 0) + 1; return n; };
  const open = {}; for (const d of document.querySelectorAll('#sliders details.band'))
    open[d.dataset.band] = d.open;
  return { bands: count('#bandsliders input[data-kind=band]'),
           coeffs: count('#sliders input[data-kind=coeff]'), open };
}"""


def _options(page, sel):
    return page.evaluate(f"() => [...document.querySelectorAll('{sel} option')].map(o => o.value)")


def test_lmax6_transfer_every_degree_editable(tmp_path):
    from shprobe.lighting.design import edit_lighting
    from shprobe.lighting.edits import EditSpec
    from shprobe.lighting.source import resolve_lighting

    tp = bake_ball(tmp_path, lmax=6, mode="interreflected", bounces=1)
    with serving(Session(preset="grace", transfer=str(tp))) as s, opened(s) as page:
        assert page.evaluate("() => window.__shprobe.lastError") is None
        assert "preset:grace has no image" in page.locator("#probelabel").inner_text()
        # the design's degree: every degree a design may have, the transfer's chosen
        assert _options(page, "#lmax") == [str(l) for l in range(DESIGN_LMAX + 1)]
        assert page.locator("#lmax").input_value() == "6"
        assert "6 (the transfer's)" in page.locator("#lmax").inner_text()
        assert _options(page, "#prtlmax") == [str(l) for l in range(7)]
        got = page.evaluate(SLIDERS)
        assert got["bands"] == {str(l): 1 for l in range(7)}
        assert got["coeffs"] == {str(l): 2 * l + 1 for l in range(7)}
        assert got["open"] == {str(l): l <= 2 for l in range(7)}
        # the interreflected model shows its bounces; the shadowed one hides them
        assert page.locator("#prtbounces").is_visible()
        shot(page, "degrees_interreflected")
        page.select_option("#prtmode", "shadowed")
        page.wait_for_function("() => window.__shprobe.prt.head.mode === 'shadowed'")
        assert not page.locator("#prtbounces").is_visible()
        assert not page.locator("#errlmax").is_visible()  # the error view's control
        # a band-5 coefficient slider (in its collapsed band) edits the library's L_5,-3
        page.evaluate("() => { document.querySelector('#sliders details[data-band=\"5\"]')"
                      ".open = true; }")
        inp = page.locator('#sliders input[data-band="5"][data-m="-3"]')
        inp.fill("2")
        inp.dispatch_event("change")
        settle(page)
        st = page.evaluate("() => window.__shprobe.getState()")
        assert st["scale"] == {"5,-3": 2} and st["lmax"] == 6
        L = np.array(page.evaluate("() => window.__shprobe.coeffs"))
        base = resolve_lighting(preset="grace", lmax=None).coeffs
        want = edit_lighting(base, EditSpec.from_json(st, max_lmax=DESIGN_LMAX),
                             lambda b, lm: None).coeffs
        np.testing.assert_allclose(L, want, rtol=1e-12, atol=1e-12)
        shot(page, "degrees_shadowed")
        # a degree picked in the menu rebuilds the sliders to it
        page.select_option("#lmax", "8")
        settle(page)
        got = page.evaluate(SLIDERS)
        assert got["bands"] == {str(l): 1 for l in range(9)}
        assert got["coeffs"] == {str(l): 2 * l + 1 for l in range(9)}
        assert np.array(page.evaluate("() => window.__shprobe.coeffs")).shape == (81, 3)
        assert not [m for m in page.shprobe_console if m.startswith(("error:", "pageerror:"))]


def test_probe_source_offers_every_design_degree(tmp_path):
    """Without a transfer the menu still offers 0..DESIGN_LMAX (a probe projects to any);
    the compare views hide the design's degree, the error view shows its own 1..4."""
    from tests.conftest import data_file

    with serving(Session(str(data_file("probes", "grace.hdr")))) as s, opened(s) as page:
        assert _options(page, "#lmax") == [str(l) for l in range(DESIGN_LMAX + 1)]
        assert page.locator("#lmax").is_visible() and not page.locator("#errlmax").is_visible()
        assert not page.locator("#prtbox").is_visible()  # no transfer: no PRT controls
        page.select_option("#mode", "error")
        page.wait_for_function("() => window.__shprobe.compare", timeout=90000)
        assert page.locator("#errlmax").is_visible() and not page.locator("#lmax").is_visible()
        assert _options(page, "#errlmax") == ["1", "2", "3", "4"]
