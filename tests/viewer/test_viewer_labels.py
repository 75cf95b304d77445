"""Every panel of the page labelled, every colour scale with its units, the same units in
legend and table (headless Chromium): the error view's scale and table in % of ∫L dω — the
library's error_report as `shprobe error` prints it — for the degree chosen; the "SH lmax N"
views mark their own degree's row and show no heat scale (they are not heat maps)."""

from __future__ import annotations

import pytest

from shprobe.viewer.session import Session
from tests.conftest import data_file
from tests.viewer.viewer_pages import opened, serving, shot

pytestmark = [pytest.mark.browser, pytest.mark.filterwarnings("ignore::DeprecationWarning")]

LABELS = """() => [...document.querySelectorAll('canvas')].filter((c) => c.offsetParent)
  .map((c) => { let e = c.closest('#viewwrap') || c, l = e.previousElementSibling;
    if (c.closest('figure')) l = c.closest('figure').querySelector('figcaption');
    const r = (l || c).getBoundingClientRect();
    return { id: c.id, label: l ? l.textContent.trim() : '',
             box: [r.left, r.top, r.right, r.bottom] }; })"""


def _table(page):
    return page.evaluate("""() => [...document.querySelectorAll('#errtable tbody tr')].map((tr) =>
      ({ lmax: Number(tr.dataset.lmax), current: tr.classList.contains('current'),
         cells: [...tr.cells].map((c) => c.textContent) }))""")


def _in_view(page, sel):
    box = page.locator(sel).bounding_box()
    vp = page.viewport_size
    return (box is not None and box["x"] >= 0 and box["y"] >= 0
            and box["x"] + box["width"] <= vp["width"] + 0.5
            and box["y"] + box["height"] <= vp["height"] + 0.5)


def test_panels_labelled_and_errors_in_percent_everywhere():
    from shprobe.lighting.reference import error_report
    from shprobe.probes.env import load_env

    probe = data_file("probes", "grace.hdr")
    rep = error_report(load_env(probe), (1, 2, 3, 4))
    pct = {r.lmax: (f"{100 * r.mean_frac:.3f} %", f"{100 * r.max_frac:.3f} %") for r in rep.rows}
    with serving(Session(str(probe))) as s, opened(s) as page:
        assert page.evaluate("() => window.__shprobe.lastError") is None
        for p in page.evaluate(LABELS):  # the object, the probe, the irradiance map
            assert len(p["label"]) > 10, p
        assert {p["id"] for p in page.evaluate(LABELS)} == {"view", "probe", "irrmap"}
        assert "E(n)" in page.locator("#irrlabel").inner_text()
        assert "Probe (lat-long" in page.locator("#probelabel").inner_text()
        page.select_option("#mode", "error")
        page.wait_for_function("() => window.__shprobe.compare", timeout=90000)
        for lmax in (2, 3, 1):
            page.select_option("#errlmax", str(lmax))
            title = page.locator("#legendtitle").inner_text()
            assert f"SH lmax {lmax}" in title and "% of ∫L dω" in title
            # the scale's ends and the table: one unit, the library's numbers
            assert page.locator("#legendmin").inner_text() == "0 %"
            assert page.locator("#legendmax").inner_text() == pct[lmax][1]
            rows = _table(page)
            assert [r["lmax"] for r in rows] == [1, 2, 3, 4]
            for r in rows:
                assert r["cells"][1:] == list(pct[r["lmax"]]), r
                assert r["current"] == (r["lmax"] == lmax)
            heads = page.evaluate("() => [...document.querySelectorAll('#errtable th')]"
                                  ".map((e) => e.textContent)")
            assert heads[1:] == ["mean (% of ∫L dω)", "max (% of ∫L dω)"]
            assert page.locator("#legendbar").is_visible()
            assert _in_view(page, "#legendscale") and _in_view(page, "#errtable")
        shot(page, "labels_error")
        # "SH lmax 1": its own row marked, no heat scale (the object is shaded, not a heat map)
        page.select_option("#mode", "sh1")
        assert not page.locator("#legendbar").is_visible()
        assert not page.locator("#errlmax").is_visible()
        assert "SH lmax 1" in page.locator("#legendtitle").inner_text()
        assert [r["lmax"] for r in _table(page) if r["current"]] == [1]
        assert _in_view(page, "#errtable")
        shot(page, "labels_sh1")
        page.select_option("#mode", "exact")
        assert not page.locator("#legendbar").is_visible()
        assert [r for r in _table(page) if r["current"]] == []
        assert "brute-force" in page.locator("#viewlabel").inner_text()
        page.select_option("#mode", "design")
        assert not page.locator("#legend").is_visible()
        for p in page.evaluate(LABELS):  # labels on screen, not clipped
            assert p["box"][0] >= 0 and p["box"][1] >= 0 and p["box"][2] <= 1280, p
        assert not [m for m in page.shprobe_console if m.startswith(("error:", "pageerror:"))]
