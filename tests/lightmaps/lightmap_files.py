"""Small lightmap .glb files for the lightmap viewer and figure tests, made without a bake:
the packaged courtyard with TEXCOORD_1 on its floor (a planar map of the 16 m square) and a
smooth, strongly directional coefficient field written by shprobe.lightmaps.format."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from shprobe.lightmaps import format as fmt
from shprobe.lightmaps.scenes import game_scene_path

__all__ = ["bilinear", "floor_lightmap"]


def _field(h: int, w: int, n: int, seed: int) -> np.ndarray:
    """(h, w, n, 3) coefficients: a positive first term, smooth directional ones."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:h, 0:w] / max(h, w)
    c = np.zeros((h, w, n, 3))
    for i in range(n):
        for ch in range(3):
            a, b, p = rng.uniform(1, 4, 3)
            c[:, :, i, ch] = np.sin(a * u * 3 + p) * np.cos(b * v * 3 + p)
    c[:, :, 0] = 4.0 + 1.5 * c[:, :, 0]  # the mean irradiance term dominates
    c[:, :, 1:] *= 1.2
    return c


def floor_lightmap(path: Path, encoding: str = "h6", size: int = 16, seed: int = 0) -> Path:
    """Write the courtyard with a ``size``² lightmap on its floor (the other meshes have no
    TEXCOORD_1, so a lightmap viewer draws the floor only) and return ``path``."""
    doc, binary = fmt.parse_glb(game_scene_path().read_bytes())
    binary = bytearray(binary)
    mesh = next(i for i, m in enumerate(doc["meshes"]) if m["name"] == "floor")
    prim = doc["meshes"][mesh]["primitives"][0]
    acc = doc["accessors"][prim["attributes"]["POSITION"]]
    view = doc["bufferViews"][acc["bufferView"]]
    p = np.frombuffer(bytes(binary), np.float32, acc["count"] * 3, view.get("byteOffset", 0))
    p = p.reshape(-1, 3)
    uv1 = np.stack([(p[:, 0] + 8) / 16, (p[:, 2] + 8) / 16], 1).astype(np.float32)
    binary.extend(b"\0" * (-len(binary) % 4))
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(binary),
                               "byteLength": uv1.nbytes, "target": 34962})
    binary.extend(uv1.tobytes())
    doc["accessors"].append({"bufferView": len(doc["bufferViews"]) - 1, "componentType": 5126,
                             "count": len(uv1), "type": "VEC2"})
    prim["attributes"]["TEXCOORD_1"] = len(doc["accessors"]) - 1
    fmt.add_lightmap(doc, binary, encoding, _field(size, size, fmt.N_COEFFS[encoding], seed),
                     [(mesh, 0)])
    fmt.write_glb(path, doc, binary, overwrite=True)
    return path


def bilinear(img: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """``img`` (H, W, ...) sampled at glTF UVs (N, 2) as a GPU does with LINEAR filtering and
    clamp-to-edge (texel centres at (i + ½)/size, row 0 at v = 0)."""
    h, w = img.shape[:2]
    x = np.clip(uv[:, 0] * w - 0.5, 0, w - 1)
    y = np.clip(uv[:, 1] * h - 0.5, 0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = x - x0, y - y0
    ex = (slice(None),) + (None,) * (img.ndim - 2)
    return ((img[y0, x0] * (1 - fx)[ex] + img[y0, x1] * fx[ex]) * (1 - fy)[ex]
            + (img[y1, x0] * (1 - fx)[ex] + img[y1, x1] * fx[ex]) * fy[ex])


@contextmanager
def lightmap_page(path: Path, height: int) -> Iterator:
    """The lightmap page of ``path`` served and opened in headless Chromium (1500 px wide),
    ready; its console and page errors collected in ``page.errors``."""
    from playwright.sync_api import sync_playwright

    from shprobe.viewer.lightmap import load_lightmap_view
    from tests.viewer.test_viewer import FLAGS, Served, _need_browser

    _need_browser()
    served = Served(None, grid=load_lightmap_view(path), page="/lightmap")
    errors: list[str] = []
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path="/usr/bin/chromium", headless=True, args=FLAGS)
        try:
            pg = b.new_page(viewport={"width": 1500, "height": height})
            pg.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            pg.on("pageerror", lambda e: errors.append(str(e)))
            pg.goto(served.url)
            pg.wait_for_function("() => window.__shprobe && (window.__shprobe.ready || "
                                 "window.__shprobe.lastError)", timeout=90000)
            pg.errors = errors
            yield pg
        finally:
            b.close()
            served.close()
