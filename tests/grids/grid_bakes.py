"""Grid bakes shared by the grid tests (each baked once per test process)."""

from __future__ import annotations

from functools import lru_cache

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
