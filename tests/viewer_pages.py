"""Helpers of the viewer's page tests (tests/test_viewer_degrees.py, _labels, _hbasis,
_camera): a served session (:class:`tests.test_viewer.Served`), the page opened in headless
Chromium at a window size (:func:`tests.browser.chromium_page`), screenshots kept where
``$SHPROBE_VIEWER_SHOTS`` says, and a small PRT bake made in the test."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from .browser import chromium_page
from .test_viewer import VENDOR, Served

__all__ = ["bake_ball", "opened", "serving", "set_state", "settle", "shot"]


@contextlib.contextmanager
def serving(session: Any) -> Iterator[Served]:
    """``session`` served on a free local port for the length of the block."""
    s = Served(session)
    try:
        yield s
    finally:
        s.close()


@contextlib.contextmanager
def opened(served: Served, width: int = 1280, height: int = 800) -> Iterator[Any]:
    """The viewer's page in headless Chromium at ``width`` × ``height``, loaded (ready or
    failed); console errors in ``page.shprobe_console``."""
    if not VENDOR.is_file():
        import pytest

        pytest.skip("three.js not vendored (run tools/vendor_js.sh)")
    with chromium_page() as page:
        page.set_viewport_size({"width": width, "height": height})
        page.goto(served.url)
        page.wait_for_function("() => window.__shprobe && (window.__shprobe.ready || "
                               "window.__shprobe.lastError)", timeout=90000)
        yield page


def settle(page: Any) -> None:
    page.evaluate("() => window.__shprobe.settled()")


def set_state(page: Any, state: dict[str, Any]) -> None:
    page.evaluate("(s) => window.__shprobe.setState(s)", state)
    settle(page)


def shot(page: Any, name: str) -> Path:
    """A screenshot of the whole page (looked at when the tests change the page)."""
    d = Path(os.environ.get("SHPROBE_VIEWER_SHOTS", "/tmp"))
    d.mkdir(parents=True, exist_ok=True)
    p = d / f"viewer_{name}.png"
    page.screenshot(path=str(p))
    return p


def bake_ball(tmp_path: Path, lmax: int = 6, mode: str = "shadowed", bounces: int = 0
              ) -> Path:
    """A small fast PRT bake: an icosphere on a ground plane (a few seconds)."""
    from shprobe.prt import bake, load_scene
    from shprobe.scene.render import sphere_mesh

    mp = tmp_path / "ball.obj"
    sphere_mesh(2).export(mp)
    kw = {"bounces": bounces} if mode == "interreflected" else {}
    t = bake(load_scene([str(mp)], ground=True, ground_resolution=8), mode=mode, lmax=lmax,
             samples=64, **kw)
    out = tmp_path / f"ball_{mode}_l{lmax}.npz"
    t.save(out)
    return out
