"""A grid bake's time estimate against its real time: the estimate the CLI announces
(`estimate_grid_bake` with the scene, its trial trace included) and the bake's wall seconds,
for small and large settings on the room, the bunny on its ground, the bunny in a box far
larger than it (probes that see sky: little bounce work whatever the settings) and the room
with black surfaces (bounces that gather nothing). A warm-up bake first, so that the figures
are the bake's own, not the compiler's. The process CPU seconds are the figure to compare on a
loaded machine (a bounce runs mostly in one thread: unloaded, its wall time is about its CPU
time); wall seconds there measure the load.

    SHPROBE_TEST_DATA=../shared PYTHONPATH=src python bench/bench_grid_estimate.py [--quick]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from _machine import machine
from shprobe.grids import GridSettings, bake_grid, estimate_grid_bake
from shprobe.grids.bake import grid_scene
from shprobe.grids.trial import ASSUMED, TRIAL_FACES, trial_fractions

DATA = Path(os.environ.get("SHPROBE_TEST_DATA", Path(__file__).resolve().parents[2] / "shared"))
FAR = [[-20, -20, -20], [20, 20, 20]]
BOX = [[-2, -2, -2], [2, 2, 2]]

CASES = [  # (label, scene, albedo, resolution, samples, bounces, gather, bounds)
    ("room, defaults", "room", (), (4, 4, 4), 4096, 2, 2, None),
    ("bunny in a 40-unit box, max bounces and gather", "BUNNY", (), (4, 4, 4), 16384, 16, 256,
     FAR),
    ("room, black, max bounces and gather", "room", (0.0,), (4, 4, 4), 4096, 16, 256, None),
    ("room, DDGI recursion", "room", (), (4, 4, 4), 8192, 8, 0, None),
    ("bunny on ground", "bunny-on-ground", (), (4, 4, 4), 8192, 3, 6, None),
    ("room", "room", (), (4, 4, 4), 16384, 3, 6, None),
    ("room", "room", (), (6, 4, 6), 8192, 4, 8, None),
    ("sphere of 81,920 faces in a box twice its size", 6, (), (4, 4, 4), 8192, 3, 6, BOX),
    ("sphere of 327,680 faces (no trial)", 7, (), (4, 4, 4), 8192, 3, 6, BOX),
]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="only the first three (fast) cases")
    a = ap.parse_args()
    print(machine())
    sky = np.zeros((9, 3))
    sky[0] = 1.0
    sc, s = grid_scene(["room"], GridSettings((2, 2, 2), samples=256))
    bake_grid(sc, sky, s)  # warm-up
    cases = CASES[:3] if a.quick else CASES
    print("| scene and settings | samples | bounces | gather | lit / onward | estimate | "
          "bake wall | bake CPU |")
    for label, scene, albedo, res, d, b, g, bounds in cases:
        path = str(DATA / "meshes" / "bunny.obj") if scene == "BUNNY" else scene
        if isinstance(scene, int):
            import trimesh

            path = trimesh.creation.icosphere(subdivisions=scene)
        settings = GridSettings(res, bounds=bounds, samples=d, bounces=b, gather=g)
        sc, settings = grid_scene([path], settings, list(albedo))
        t = time.perf_counter()
        cost = estimate_grid_bake(len(sc.faces), settings, sc)
        te = time.perf_counter() - t
        fr = (ASSUMED if len(sc.faces) > TRIAL_FACES else
              trial_fractions(sc.vertices, sc.faces, sc.albedo, settings.bounds, settings))
        t, c = time.perf_counter(), _cpu()
        bake_grid(sc, sky, settings)
        real, cpu = time.perf_counter() - t, _cpu() - c
        print(f"| {label} ({len(sc.faces)} faces, {'x'.join(map(str, res))}) | {d} | {b} | {g} "
              f"| {fr.lit:.2f} / {fr.onward:.2f} | {cost.seconds:.1f} s (in {te:.2f} s) "
              f"| {real:.1f} s | {cpu:.1f} s |", flush=True)


def _cpu() -> float:
    t = os.times()
    return t.user + t.system


if __name__ == "__main__":
    main()
