"""Headless Debian Chromium driven by Playwright's Python client, for tests that need a real
browser (WebGL2, WebGPU, ES modules). Never downloads a browser: the system /usr/bin/chromium is
used, and a test skips with a reason when Chromium or the ``playwright`` package is absent
(``.ci/run`` installs both).

    with chromium_page(serve={"/": some_dir}) as page:
        page.goto(ORIGIN + "/index.html")

``serve`` maps URL path prefixes to local folders; files are answered by request
interception under :data:`ORIGIN` (no socket, no server process).
"""

from __future__ import annotations

import contextlib
import mimetypes
import os
import shutil
from collections.abc import Iterator, Mapping
from pathlib import Path

import pytest

os.environ.setdefault("PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD", "1")

#: the origin under which ``serve``d files appear (a secure context: WebGPU needs one)
ORIGIN = "https://shprobe.test"

#: flags for running as root in a container without a GPU: WebGL2 on SwiftShader, WebGPU on
#: SwiftShader's Vulkan (may still give no adapter; callers check)
CHROMIUM_ARGS = (
    "--no-sandbox", "--disable-background-networking", "--disable-component-update",
    "--disable-sync", "--disable-dev-shm-usage",
    "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
    "--enable-unsafe-webgpu", "--enable-features=Vulkan",
)


def chromium_path() -> str | None:
    """The system Chromium executable (``$SHPROBE_CHROMIUM`` or /usr/bin/chromium)."""
    for p in (os.environ.get("SHPROBE_CHROMIUM"), "/usr/bin/chromium",
              shutil.which("chromium")):
        if p and os.access(p, os.X_OK):
            return p
    return None


def require_chromium() -> str:
    """The Chromium path, or skip the calling test with the reason."""
    exe = chromium_path()
    if exe is None:
        pytest.skip("Chromium not installed (/usr/bin/chromium; .ci/run installs Debian's)")
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        pytest.skip("playwright (Python client) not installed (pip install playwright)")
    return exe


@contextlib.contextmanager
def chromium_page(serve: Mapping[str, str | os.PathLike[str]] | None = None,
                  extra_args: tuple[str, ...] = ()) -> Iterator[object]:
    """A Playwright page in headless system Chromium; console errors are collected in
    ``page.shprobe_console``. ``serve``: URL prefix → folder, answered under :data:`ORIGIN`."""
    exe = require_chromium()
    from playwright.sync_api import sync_playwright

    roots = {k.rstrip("/") + "/": Path(v).resolve() for k, v in (serve or {}).items()}

    def handle(route):
        path = route.request.url[len(ORIGIN):].split("?", 1)[0]
        for prefix, root in sorted(roots.items(), key=lambda kv: -len(kv[0])):
            if path.startswith(prefix):
                f = (root / path[len(prefix):]).resolve()
                if f.is_file() and (f == root or root in f.parents):
                    ctype = mimetypes.guess_type(f.name)[0] or "application/octet-stream"
                    if f.suffix in (".js", ".mjs"):
                        ctype = "text/javascript"
                    return route.fulfill(status=200, body=f.read_bytes(), content_type=ctype)
        return route.fulfill(status=404, body="not found")

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=exe, headless=True,
                                     args=[*CHROMIUM_ARGS, *extra_args])
        try:
            page = browser.new_page()
            page.shprobe_console = []
            page.on("console", lambda m: page.shprobe_console.append(f"{m.type}: {m.text}"))
            page.on("pageerror", lambda e: page.shprobe_console.append(f"pageerror: {e}"))
            page.route(ORIGIN + "/**", handle)
            yield page
        finally:
            browser.close()
