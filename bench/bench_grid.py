"""Grid bake speed: a 7×4×7 grid of the closed room on its ground (grace.hdr) and of the bunny
on a ground plane (``grids.scenes``: the scenes bench_grid_three.py gives three.js, albedo
0.5), defaults (4096 rays per probe, 2 bounces, lmax 2), and the accuracy option (--samples)
on the room, with the room's leak. Wall and process CPU seconds, the bake's own
stages, best of ``--repeat``.

    SHPROBE_TEST_DATA=../shared PYTHONPATH=src python bench/bench_grid.py
On a loaded machine compare the CPU seconds: wall time there measures the load.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from _machine import machine
from shprobe.grids import GridSettings, bake_grid
from shprobe.grids.scenes import bunny_on_ground, room_on_ground
from shprobe.lighting.source import resolve_lighting
from shprobe.prt.geometry import load_scene

DATA = Path(os.environ.get("SHPROBE_TEST_DATA", Path(__file__).resolve().parents[2] / "shared"))


class Stages:
    """A progress reporter that keeps each stage's wall seconds."""

    def __init__(self) -> None:
        self.times: dict[str, float] = {}
        self._name, self._t = None, 0.0

    def begin(self, description, total=None):
        self._name, self._t = description.split(": ", 1)[-1], time.perf_counter()

    def update(self, done):
        pass

    def end(self):
        self.times[self._name] = round(time.perf_counter() - self._t, 2)


def timed(scene, light, settings, repeat):
    best = None
    for _ in range(repeat):
        st = Stages()
        w, c = time.perf_counter(), time.process_time()
        g = bake_grid(scene, light, settings, progress=st)
        r = (round(time.perf_counter() - w, 2), round(time.process_time() - c, 2), st.times)
        best = r if best is None or r[1] < best[1] else best
    return best, g


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--samples", default="1024,4096,16384",
                    help="rays per probe tried on the room (the accuracy option)")
    a = ap.parse_args()
    print(machine())
    light = resolve_lighting(str(DATA / "probes" / "grace.hdr"), lmax=2)
    room = room_on_ground()
    room_scene = load_scene(room.mesh(), albedo=0.5)
    bunny_mesh, bunny_bounds = bunny_on_ground()  # the scene bench_grid_three.py bakes
    bunny = load_scene(bunny_mesh, albedo=0.5)
    out = {}
    for s in (int(x) for x in a.samples.split(",")):
        (w, c, stages), g = timed(room_scene, light,
                                  GridSettings((7, 4, 7), bounds=room.bounds, samples=s),
                                  a.repeat)
        out[f"room 7x4x7, {s} rays/probe"] = {
            "wall s": w, "CPU s": c, "stages": stages,
            "leak (floor / ground), leak control": f"{room.leak(g).floor_ratio:.4%}",
            "leak, plain trilinear": f"{room.leak(g, leak_control=False).floor_ratio:.4%}"}
    (w, c, stages), g = timed(bunny, light, GridSettings((7, 4, 7), bounds=bunny_bounds),
                              a.repeat)
    out[f"bunny on a ground 7x4x7 ({len(bunny.faces)} triangles), 4096 rays/probe"] = {
        "wall s": w, "CPU s": c, "stages": stages, "moved": g.meta["moved"],
        "invalid": g.meta["invalid"]}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
