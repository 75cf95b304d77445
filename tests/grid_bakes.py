"""Grid bakes shared by the grid tests (each baked once per test process)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from shprobe.grids import GridSettings, bake_grid
from shprobe.grids.scenes import room_on_ground
from shprobe.prt.geometry import load_scene

#: Albedo of the room and its ground in the grid tests.
ROOM_ALBEDO = 0.5
#: Bounces of the grid tests' bakes and of the path tracer that checks them.
BOUNCES = 2


@lru_cache(maxsize=4)
def room_grid(lighting_key: str):
    """The room on its ground baked 7×4×7 under a probe path or ``preset:NAME``; returns
    (RoomScene, ProbeGrid)."""
    from shprobe.lighting.source import resolve_lighting

    room = room_on_ground()
    if lighting_key.startswith("preset:"):
        light = resolve_lighting(preset=lighting_key[7:])
    else:
        light = resolve_lighting(lighting_key, lmax=2)
    grid = bake_grid(load_scene(room.mesh(), albedo=ROOM_ALBEDO), light,
                     GridSettings((7, 4, 7), bounds=room.bounds, bounces=BOUNCES))
    return room, grid


def leak_points(room, n: int = 2000, seed: int = 1):
    """Points and normals inside the cavity (its floor facing up, and the volume with random
    normals) and on the ground outside the room (facing up)."""
    rng = np.random.default_rng(seed)
    cav = room.cavity
    floor = np.column_stack([rng.uniform(cav[0, 0], cav[1, 0], n), np.full(n, cav[0, 1]),
                             rng.uniform(cav[0, 2], cav[1, 2], n)])
    volume = rng.uniform(cav[0], cav[1], (n, 3))
    normals = rng.normal(size=(n, 3))
    g = room.ground
    ground = np.column_stack([rng.uniform(-g, g, 4 * n), np.zeros(4 * n),
                              rng.uniform(-g, g, 4 * n)])
    out = np.all(np.abs(ground[:, [0, 2]]) < room.outer[1, [0, 2]], axis=1)
    ground = ground[~out][:n]
    up = np.tile([0.0, 1.0, 0.0], (n, 1))
    return (floor, up), (volume, normals), (ground, up[: len(ground)])
