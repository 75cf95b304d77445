"""The three.js grid export read by three.js r187 itself: the file written by
``export_grid(..., "three")`` loaded by tests/consumers/shprobe_grid_loader.mjs (the loader the
docs print) into ``LightProbeGridWebGL`` in headless Chromium (WebGL2 on SwiftShader), a white
``MeshLambertMaterial`` drawn at known points with known normals into a float render target (no
tone mapping, linear output), the pixels read back.

three.js's shader: E(n) by R&H eq. 13 on the trilinearly filtered atlas (sample point moved
half a cell along the normal, clamped to the outer probe centres), times ``BRDF_Lambert`` =
RECIPROCAL_PI × colour: a white surface shows E/π. So every pixel must equal
``ProbeGrid.irradiance(points, normals, leak_control=False) / π`` — float32 texels and
6-digit shader constants: within 1e-5 of the peak. One deliberately corrupted export (a sign
flipped in every probe) must disagree.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from shprobe.grids.exports import export_grid
from shprobe.grids.grid import ProbeGrid
from tests.conftest import REPO
from tests.support.npm_packages import ensure_npm_packages

CONSUMERS = REPO / "tests" / "consumers"
TOL = 1e-5


def require_three() -> None:
    if not (CONSUMERS / "node_modules" / "three").is_dir() and not ensure_npm_packages():
        pytest.skip("npm package three not installed (cd tests/consumers && npm ci)")


def random_grid(seed: int = 1) -> ProbeGrid:
    """A 5×3×4 grid over uneven bounds, every probe its own lighting (mostly positive)."""
    rng = np.random.default_rng(seed)
    c = rng.normal(size=(5, 3, 4, 9, 3)) * 0.3
    c[..., 0, :] += 2.0
    return ProbeGrid(c.astype(np.float32), np.array([[-2.0, 0.5, -1.0], [3.0, 2.0, 4.0]]))


def samples(grid: ProbeGrid, n: int = 512, seed: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Points and unit normals whose sample point p + n·spacing/2 lies inside the volume
    (three.js lights a fragment from the grid only there), reaching its faces so the clamp to
    the outer probe centres is exercised."""
    rng = np.random.default_rng(seed)
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    lo, hi = grid.bounds
    sp = grid.spacing
    q = lo + 0.02 * sp + rng.random((n, 3)) * (hi - lo - 0.04 * sp)
    return q - nrm * sp * 0.5, nrm


@pytest.mark.browser
@pytest.mark.node
def test_three_renders_the_exported_grid(tmp_path):
    from tests.support.browser import ORIGIN, chromium_page

    require_three()
    grid = random_grid()
    path = export_grid(grid, "three", tmp_path / "grid.three.json", source="random")
    doc = json.loads(path.read_text())
    bad = json.loads(path.read_text())
    c = np.reshape(bad["coefficients"], (-1, 9, 3))
    c[:, 2, 0] *= -1.0  # L10 red: the z gradient
    bad["coefficients"] = c.ravel().tolist()
    p, n = samples(grid)
    with chromium_page(serve={"/": CONSUMERS}) as page:
        page.goto(ORIGIN + "/grid.html")
        page.wait_for_function("window.gridsReady === true", timeout=60_000)
        runs = [page.evaluate("([d, p, n]) => window.grids.renderSamples(d, p, n)",
                              [d, p.ravel().tolist(), n.ravel().tolist()]) for d in (doc, bad)]
        console = list(page.shprobe_console)
    assert not [m for m in console if m.startswith(("error", "pageerror"))], console
    assert runs[0]["info"]["version"] == "187"
    ref = grid.irradiance(p, n, leak_control=False) / np.pi
    assert ref.min() > 0.05  # lit everywhere: a pixel the grid did not light would show 0
    got = np.reshape(runs[0]["rgb"], (-1, 3))
    rel = np.abs(got - ref).max() / np.abs(ref).max()
    print(f"three.js LightProbeGridWebGL vs ProbeGrid.irradiance/pi: max rel diff {rel:.3g}")
    assert rel <= TOL
    flipped = np.reshape(runs[1]["rgb"], (-1, 3))
    assert np.abs(flipped - ref).max() / np.abs(ref).max() > 1e-2, "sign flip went unnoticed"


def test_docs_print_the_loader_the_test_runs():
    loader = (CONSUMERS / "shprobe_grid_loader.mjs").read_text()
    assert loader in (REPO / "docs" / "grid-exports.md").read_text()
