"""three.js's own probe-grid bake (``LightProbeGridWebGL.bake``, r187) of shprobe's reference
scenes in headless Chromium, read back into a :class:`~shprobe.grids.grid.ProbeGrid`; used by
tests/grids/test_grid_export_three_bake.py and bench/bench_grid_three.py, each opening the page
``tests/consumers/grid.html`` in its own headless Chromium.

What three.js's bake sees: for each probe a cube map (8² per face, its default) of the scene —
the environment as ``scene.background`` (the probe image resampled into three.js's
equirectangular mapping, float RGBA) and the meshes, grey Lambertian of ``albedo``, lit by a
``LightProbe`` holding the environment's l ≤ 2 SH (three.js's image-based diffuse light: no
shadows, so a surface inside a closed room is lit as if the room were not there) — projected
to L2 SH on the GPU. No visibility handling: the grid is sampled trilinearly, as shprobe's
plain interpolation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from shprobe.grids.grid import ProbeGrid

CONSUMERS = Path(__file__).resolve().parents[1] / "tests" / "consumers"
RESOLUTION = (7, 4, 7)
ALBEDO = 0.5
LUMA = np.array([0.2126, 0.7152, 0.0722])


def three_equirect(env) -> tuple[int, int, list[float]]:
    """The environment resampled (bilinear) at the texel directions of three.js's
    ``equirectUv``: u = atan2(z, x)/2π + ½, v = asin(y)/π + ½, data row 0 at v = 0."""
    w, h = 256, 128
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    phi = (u - 0.5) * 2 * np.pi
    lat = (v - 0.5) * np.pi
    cl = np.cos(lat)[:, None]
    d = np.stack([cl * np.cos(phi)[None, :], np.broadcast_to(np.sin(lat)[:, None], (h, w)),
                  cl * np.sin(phi)[None, :]], axis=-1)
    rgb = np.asarray(env.sample(d), dtype=np.float32)
    rgba = np.concatenate([rgb, np.ones((h, w, 1), np.float32)], axis=-1)
    return w, h, rgba.ravel().tolist()


def bake_job(mesh, bounds, env, sh, resolution=RESOLUTION, albedo=ALBEDO, runs=2) -> dict:
    w, h, data = three_equirect(env)
    return {"vertices": np.asarray(mesh.vertices, np.float64).ravel().tolist(),
            "faces": np.asarray(mesh.faces, np.int64).ravel().tolist(),
            "bounds": np.asarray(bounds, np.float64).ravel().tolist(),
            "resolution": list(resolution), "albedo": albedo, "runs": runs,
            "env": data, "envWidth": w, "envHeight": h,
            "sh": np.asarray(sh, np.float64).reshape(9, 3).ravel().tolist()}


def run_bakes(jobs: dict[str, dict], page) -> dict[str, dict]:
    """Each job baked by three.js on ``page`` (a Playwright page showing
    tests/consumers/grid.html): {name: {seconds, coefficients, info}}."""
    page.wait_for_function("window.gridsReady === true", timeout=60_000)
    return {name: page.evaluate("(j) => window.grids.bakeThree(j)", job)
            for name, job in jobs.items()}


def grid_from_three(result: dict, job: dict) -> ProbeGrid:
    """three.js's atlas (texture order, X fastest) as a ProbeGrid (NX, NY, NZ, 9, 3)."""
    nx, ny, nz = job["resolution"]
    c = np.reshape(result["coefficients"], (nz, ny, nx, 9, 3)).transpose(2, 1, 0, 3, 4)
    return ProbeGrid(np.ascontiguousarray(c, dtype=np.float32),
                     np.reshape(job["bounds"], (2, 3)), meta={"baked_by": "three.js"})
