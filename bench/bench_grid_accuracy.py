"""What the accuracy options buy: the room baked 7×4×7 under the grace preset at several
``samples`` and ``gather`` (and finer grids), against the independent path tracer of the tests
(tests/grids/grid_pathtracer.py, 160,000 paths a point): the probes' own irradiance (lowest outside
layer, 4 normals) and the interpolated irradiance on the ground near the room; and the leak
(inside / outside) with and without leak control under grace.hdr.

    SHPROBE_TEST_DATA=../shared PYTHONPATH=src python bench/bench_grid_accuracy.py
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from _machine import machine
from shprobe.grids import GridSettings, bake_grid
from shprobe.grids.scenes import room_on_ground
from shprobe.lighting.irradiance import irradiance
from shprobe.lighting.source import resolve_lighting
from shprobe.probes.presets import get_preset
from shprobe.prt.geometry import load_scene

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "grids"))
from grid_pathtracer import PathTracer, sh_sky  # noqa: E402

DATA = Path(os.environ.get("SHPROBE_TEST_DATA", ROOT.parent / "shared"))
GROUND = np.array([[3.5, 0, 0], [0, 0, -3.5], [3.2, 0, 3.2], [-4.0, 0, 1.0], [1.0, 0, 4.5],
                   [-3.2, 0, -3.2], [3.3, 0, -1.5], [-5.0, 0, -5.0]])
NEAR_WALL = np.array([[2.5, 0, -1.0], [3.0, 0, 0.0], [0.0, 0, 2.6]])
NORMALS = ([0, 1, 0], [1, 0, 0], [0, 0, -1], [0, -1, 0])


def main() -> None:
    print(machine())
    room = room_on_ground()
    mesh = room.mesh()
    scene = load_scene(mesh, albedo=0.5)
    tracer = PathTracer(mesh.vertices, mesh.faces, 0.5, sh_sky(get_preset("grace")))
    up = np.tile([0.0, 1.0, 0.0], (len(GROUND), 1))
    ref_ground = tracer.irradiance(GROUND, up, 2, paths=160000, seed=11)
    ref_wall = tracer.irradiance(NEAR_WALL, up[:3], 2, paths=160000, seed=12)
    out = {}
    refs = None
    for s, gather in ((1024, 2), (4096, 0), (4096, 2), (4096, 8), (16384, 2)):
        t = time.process_time()
        g = bake_grid(scene, get_preset("grace"), GridSettings((7, 4, 7), bounds=room.bounds,
                                                               samples=s, gather=gather))
        cpu = time.process_time() - t
        pos = g.probe_positions().reshape(-1, 3)
        c = np.asarray(g.coeffs, dtype=np.float64).reshape(-1, 9, 3)
        sel = np.flatnonzero((pos[:, 1] < 1.0) & ~room.inside(pos))
        if refs is None:
            refs = [tracer.irradiance(pos[sel], np.tile(np.asarray(n, float), (len(sel), 1)),
                                      2, paths=40000, seed=13) for n in NORMALS]
        own = []
        for n, ref in zip(NORMALS, refs, strict=True):
            e = np.stack([irradiance(c[i], np.asarray(n, float)) for i in sel])
            own.append(np.abs(e / ref - 1).mean(axis=1))
        own = np.concatenate(own)
        ground = np.abs(g.irradiance(GROUND, up) / ref_ground - 1).mean(axis=1)
        wall = g.irradiance(NEAR_WALL, up[:3]) / ref_wall - 1
        out[f"{s} rays/probe, gather {gather}"] = {
            "bake CPU s": round(cpu, 2),
            "probes' own |error| median / max": [round(float(np.median(own)), 4),
                                                round(float(own.max()), 4)],
            "ground 1.2-3.5 m from the walls |error| max": round(float(ground.max()), 4),
            "ground 0.5-1 m from the walls error": np.round(wall.mean(axis=1), 3).tolist()}
    for res in ((13, 4, 13), (13, 8, 13), (25, 8, 25)):  # the resolution: the real knob
        t = time.process_time()
        g = bake_grid(scene, get_preset("grace"), GridSettings(res, bounds=room.bounds))
        cpu = time.process_time() - t
        ground = np.abs(g.irradiance(GROUND, up) / ref_ground - 1).mean(axis=1)
        wall = g.irradiance(NEAR_WALL, up[:3]) / ref_wall - 1
        out["x".join(map(str, res)) + ", 4096 rays/probe"] = {
            "bake CPU s": round(cpu, 2),
            "ground 1.2-3.5 m from the walls |error| max": round(float(ground.max()), 4),
            "ground 0.5-1 m from the walls error": np.round(wall.mean(axis=1), 3).tolist()}
    light = resolve_lighting(str(DATA / "probes" / "grace.hdr"), lmax=2)
    g = bake_grid(scene, light, GridSettings((7, 4, 7), bounds=room.bounds))
    rng = np.random.default_rng(1)
    cav = room.cavity
    floor = np.column_stack([rng.uniform(cav[0, 0], cav[1, 0], 4000), np.full(4000, cav[0, 1]),
                             rng.uniform(cav[0, 2], cav[1, 2], 4000)])
    vol, vn = rng.uniform(cav[0], cav[1], (4000, 3)), rng.normal(size=(4000, 3))
    gp = np.column_stack([rng.uniform(-6, 6, 20000), np.zeros(20000), rng.uniform(-6, 6, 20000)])
    gp = gp[~np.all(np.abs(gp[:, [0, 2]]) < 2.0, axis=1)][:4000]
    upn = np.tile([0.0, 1.0, 0.0], (4000, 1))
    for lc in (True, False):
        o = g.irradiance(gp, upn[: len(gp)], lc).mean()
        fl = g.irradiance(floor, upn, lc).mean() / o
        out[f"grace.hdr, leak control {'on' if lc else 'off (plain trilinear)'}"] = {
            "cavity floor / ground outside": round(float(fl), 5),
            "cavity volume (random normals) / ground outside":
                round(float(g.irradiance(vol, vn, lc).mean() / o), 5)}
    for wall in (0.05, 0.02):  # thinner walls than the bias (a tenth of the 1 m cell side)
        thin = room_on_ground(wall=wall)
        g = bake_grid(load_scene(thin.mesh(), albedo=0.5), light,
                      GridSettings((7, 4, 7), bounds=thin.bounds))
        vol = rng.uniform(thin.cavity[0], thin.cavity[1], (4000, 3))
        for lc in (True, False):
            o = g.irradiance(gp, upn[: len(gp)], lc).mean()
            out[f"grace.hdr, walls {wall} m, leak control {'on' if lc else 'off'}"] = {
                "cavity volume (random normals) / ground outside":
                    round(float(g.irradiance(vol, vn, lc).mean() / o), 5)}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
