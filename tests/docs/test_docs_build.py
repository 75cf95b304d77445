"""The manual builds as CI builds it (``mkdocs build --strict``, the README's command: any
warning fails) and is self-contained: nothing in its pages loads from another host, and opened
from ``file://`` in a real browser every request stays on the disk and search finds a page."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.browser import CHROMIUM_ARGS, require_chromium

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.slow

#: a page's own resources: <script src>, <link href>, <img src>, CSS url(...), JS imports
RESOURCE = re.compile(r"""(?:<script[^>]*\ssrc|<link[^>]*\shref|<img[^>]*\ssrc|<iframe[^>]*\ssrc)
                          \s*=\s*["'](https?:)?//""", re.X | re.I)
CSS_URL = re.compile(r"""url\(\s*["']?(https?:)?//""", re.I)
CDN = re.compile(r"cdnjs|jsdelivr|unpkg|googleapis|gstatic|highlightjs\.org|bootstrapcdn", re.I)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    pytest.importorskip("mkdocs", reason="mkdocs is in .[dev]/.[test] (pip install -e '.[test]')")
    pytest.importorskip("mkdocstrings", reason="mkdocstrings is in .[dev]/.[test]")
    out = tmp_path_factory.mktemp("site")
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir",
                        str(out)], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-4000:]
    assert "WARNING" not in r.stderr, r.stderr[-4000:]
    return out


def test_no_page_loads_from_another_host(site):
    pages = sorted(site.rglob("*.html"))
    assert len(pages) > 20
    for p in pages:
        text = p.read_text(encoding="utf-8")
        m = RESOURCE.search(text)
        assert m is None, f"{p.relative_to(site)} loads {text[m.start():m.end() + 60]!r}"
        m = CDN.search(text)
        assert m is None, f"{p.relative_to(site)} names a CDN: {text[m.start() - 60:m.end()]!r}"
    for p in [*site.rglob("*.css"), *site.rglob("*.js")]:
        text = p.read_text(encoding="utf-8", errors="replace")
        assert CSS_URL.search(text) is None or p.suffix != ".css", p
        m = CDN.search(text)
        assert m is None, f"{p.relative_to(site)} names a CDN: {text[m.start() - 60:m.end()]!r}"


def test_code_is_highlighted_at_build_time(site):
    text = (site / "install.html").read_text(encoding="utf-8")
    assert 'class="highlight"' in text  # Pygments' markup: no script needed to colour it
    assert (site / "css" / "pygments.css").is_file()
    assert "pygments.css" in text


def test_no_raw_sphinx_roles_in_the_reference(site):
    roles = re.compile(r":(?:func|class|meth|mod|data|attr|exc|obj):")
    for p in sorted((site / "api").glob("*.html")):
        hits = roles.findall(p.read_text(encoding="utf-8"))
        assert not hits, f"{p.name}: {len(hits)} raw roles"


def test_reference_has_numpy_sections(site):
    text = (site / "api" / "lighting.html").read_text(encoding="utf-8")
    block = text[text.index('id="shprobe.lighting.project"'):]
    block = block[:block.index('class="doc doc-heading"', 100)]
    # mkdocstrings renders numpydoc's Parameters / Returns as tables, not run-together prose
    assert "Parameters:" in block and "Returns:" in block


@pytest.mark.browser
def test_opened_from_file_stays_local_and_search_works(site):
    exe = require_chromium()
    from playwright.sync_api import sync_playwright

    requests: list[str] = []
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=exe, headless=True, args=list(CHROMIUM_ARGS))
        try:
            page = browser.new_page()
            errors: list[str] = []
            page.on("request", lambda r: requests.append(r.url))
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto((site / "api" / "index.html").as_uri())
            page.wait_for_selector("#mkdocs-search-query[data-search-ready]", state="attached",
                                   timeout=30_000)
            page.click("a[data-bs-target='#mkdocs_search_modal']")
            page.fill("#mkdocs-search-query", "irradiance")
            page.keyboard.press("End")  # a keyup, as a reader types
            page.wait_for_selector("#mkdocs-search-results article a", timeout=30_000)
            hits = page.eval_on_selector_all("#mkdocs-search-results article a",
                                             "as => as.map(a => a.href)")
            # a result opens the page it names, from the disk
            page.goto(hits[0])
            assert page.title()
            assert not errors, errors
        finally:
            browser.close()
    assert hits and all(h.startswith("file://") for h in hits), hits[:5]
    foreign = [u for u in requests if not u.startswith(("file://", "data:", "about:"))]
    assert not foreign, foreign
    assert any(u.endswith("search/search_index.js") for u in requests)


def test_ci_builds_the_manual_with_the_readmes_command():
    """.ci/run's docs line is the command the README and install.md give, with no --quiet that
    would hide a warning."""
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    line = next(ln for ln in ci.splitlines() if "mkdocs build" in ln and not ln.startswith("#"))
    assert "--quiet" not in line and "-q" not in line.split()
    cmd = line.strip()
    assert cmd in (ROOT / "README.md").read_text(encoding="utf-8")
    assert cmd in (ROOT / "docs" / "install.md").read_text(encoding="utf-8")
