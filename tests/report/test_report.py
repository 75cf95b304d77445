"""`shprobe report`: the page is self-contained, says what the library computes, and loads in
a real browser (Debian chromium via Playwright) with no console errors, no network request
and every image decoded."""

from __future__ import annotations

import base64
import io
import os
import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from shprobe.cli.main import main

CHROMIUM = Path("/usr/bin/chromium")


@pytest.fixture(scope="module")
def page(tmp_path_factory, request):
    """One small report of grace on the bunny, written by the command."""
    from tests.conftest import data_file

    grace, bunny = data_file("probes", "grace.hdr"), data_file("meshes", "bunny.obj")
    out = tmp_path_factory.mktemp("report") / "report.html"
    rc = main(["report", str(grace), "--mesh", str(bunny), "--render-size", "48",
               "--map-size", "12", "-o", str(out)])
    assert rc == 0
    return out, grace


def images(text: str) -> list[Image.Image]:
    out = []
    for data in re.findall(r'src="data:image/png;base64,([^"]+)"', text):
        im = Image.open(io.BytesIO(base64.b64decode(data)))
        im.load()
        out.append(im)
    return out


def test_page_is_self_contained_and_every_image_decodes(page):
    path, _ = page
    text = path.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    assert "http://" not in text and "https://" not in text and "<script" not in text
    srcs = re.findall(r'src="([^"]*)"', text)
    assert len(srcs) == 4 and all(s.startswith("data:image/png;base64,") for s in srcs)
    ims = images(text)
    assert [im.format for im in ims] == ["PNG"] * 4
    # the irradiance figure: SH, exact and the error map; the basis sheet's nine panels
    for im in ims:
        a = np.asarray(im.convert("RGB"))
        assert a.std() > 10  # something is drawn, not a blank page


def test_page_shows_the_library_numbers(page):
    from shprobe.lighting import (
        auto_window,
        error_report,
        irradiance_matrix,
        min_irradiance,
        project,
    )
    from shprobe.probes.env import load_env

    path, grace = page
    text = path.read_text(encoding="utf-8")
    env = load_env(grace)
    L = project(env, 2)
    for lab, k in (("L00", 0), ("L1-1", 1), ("L22", 8)):
        cells = "".join(f"<td>{v:+.4f}</td>" for v in L[k])
        assert f"<td>{lab}</td>{cells}" in text
    M = irradiance_matrix(L)
    assert f"<td>{M[0, 3, 3]:+.4f}</td>" in text and f"<td>{M[2, 1, 3]:+.4f}</td>" in text
    mn = min_irradiance(L)
    assert all(f"<td>{v:.4g}</td>" in text for v in mn.minimum)
    assert ("E ≥ 0 everywhere: certified" in text) == bool(mn.nonnegative)
    win = auto_window(L)
    assert ("none needed" in text) == (win.kind == "none")
    # the error table: R&H's metric on the 24x12 normals of the exact map, computed afresh
    rep = error_report(env, (1, 2, 3, 4), normal_grid=12)
    for lm in (1, 2, 4):
        assert f"<td>{100 * rep.row(lm).max_frac:.3f} %</td>" in text
    assert "= lmax 2 (Â_3 = 0)" in text


def test_report_refuses_bad_outputs_and_sources(tmp_path, page, capsys):
    path, grace = page
    assert main(["report", str(grace), "-o", str(path)]) == 1  # exists, no --force
    assert "exists" in capsys.readouterr().err
    assert main(["report", str(grace), "-o", str(tmp_path / "r.txt")]) == 1
    assert ".html" in capsys.readouterr().err
    assert main(["report", str(grace), str(grace), "-o", str(tmp_path / "r.html")]) == 1
    assert "six cube faces" in capsys.readouterr().err
    assert not (tmp_path / "r.html").exists()


@pytest.mark.skipif(not CHROMIUM.is_file(), reason="Debian chromium not installed "
                    "(apt-get install -y chromium)")
@pytest.mark.browser
def test_report_loads_in_chromium(page, tmp_path):
    pytest.importorskip("playwright.sync_api", reason="playwright not installed")
    from playwright.sync_api import sync_playwright

    path, _ = page
    os.environ.setdefault("PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD", "1")
    with sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=str(CHROMIUM),
            args=["--no-sandbox", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--disable-gpu"])
        try:
            tab = browser.new_page(viewport={"width": 1200, "height": 900})
            problems, requests = [], []
            tab.on("console", lambda m: problems.append(m.text) if m.type in
                   ("error", "warning") else None)
            tab.on("pageerror", lambda e: problems.append(str(e)))
            tab.on("request", lambda r: requests.append(r.url))
            tab.goto(path.as_uri())
            tab.wait_for_load_state("load")
            imgs = tab.evaluate("""Promise.all(Array.from(document.images).map(
                i => i.decode().then(() => [i.naturalWidth, i.naturalHeight, i.alt],
                                     () => [0, 0, i.alt])))""")
            heads = tab.evaluate("Array.from(document.querySelectorAll('h2'))"
                                 ".map(h => h.textContent)")
            tab.screenshot(path=str(tmp_path / "report.png"), full_page=True)
        finally:
            browser.close()
    assert problems == []
    assert [u for u in requests if not u.startswith(("file:", "data:"))] == []
    assert len(imgs) == 4 and all(w > 0 and h > 0 for w, h, _ in imgs), imgs
    assert any("Non-negativity" in h for h in heads)
    assert any("Fig. 2" in h for h in heads)
    with Image.open(tmp_path / "report.png") as shot:
        assert shot.size[0] == 1200 and shot.size[1] > 1500
