"""Lightmap bake speed and memory: the packaged game scene (courtyard, 2,762 triangles) under
grace.hdr, H6, 2 bounces, 64 rays per texel, at --size 128 and 256: texels per second, rays
per second, the bake's own stages, and the peak memory allocated (tracemalloc: NumPy's arrays
included) beside the estimate the bake refuses on. Best of ``--repeat`` by CPU seconds.

    SHPROBE_TEST_DATA=../shared PYTHONPATH=src python bench/bench_lightmap.py
"""

from __future__ import annotations

import argparse
import json
import os
import time
import tracemalloc
from pathlib import Path

from _machine import machine
from shprobe.lighting.source import resolve_lighting
from shprobe.lightmaps import LightmapSettings, bake_lightmap, load_scene
from shprobe.lightmaps.scenes import game_scene_path
from shprobe.limits import format_bytes

DATA = Path(os.environ.get("SHPROBE_TEST_DATA", Path(__file__).resolve().parents[2] / "shared"))


class Stages:
    """A progress reporter that keeps each stage's wall seconds."""

    def __init__(self) -> None:
        self.times: dict[str, float] = {}
        self._name, self._t = "", 0.0

    def begin(self, description, total=None):
        self._name, self._t = description, time.perf_counter()

    def update(self, done):
        pass

    def end(self):
        self.times[self._name] = round(time.perf_counter() - self._t, 2)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--sizes", default="128,256")
    ap.add_argument("--samples", type=int, default=64)
    a = ap.parse_args()
    print(machine())
    light = resolve_lighting(str(DATA / "probes" / "grace.hdr"), lmax=2)
    scene = load_scene(game_scene_path())
    bake_lightmap(scene, light, LightmapSettings(size=96, samples=4))  # compile the kernels
    out = {}
    for size in (int(s) for s in a.sizes.split(",")):
        settings = LightmapSettings(basis="h6", size=size, samples=a.samples, bounces=2)
        best = None
        for _ in range(a.repeat):
            st = Stages()
            w, c = time.perf_counter(), time.process_time()
            lm = bake_lightmap(scene, light, settings, progress=st)
            r = (time.perf_counter() - w, time.process_time() - c, st.times, lm)
            best = r if best is None or r[1] < best[1] else best
        w, c, stages, lm = best
        d = lm.as_dict()
        tracemalloc.start()  # a second bake for the memory: tracemalloc slows the first
        bake_lightmap(scene, light, settings)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        out[f"courtyard {size}², H6, 2 bounces, {a.samples} rays/texel"] = {
            "texels": d["texels_baked"], "wall s": round(w, 2), "CPU s": round(c, 2),
            "texels/s": round(d["texels_baked"] / w), "rays/s": round(d["rays"] / w),
            "texels/CPU s": round(d["texels_baked"] / c), "stages": stages,
            "peak allocated (tracemalloc)": format_bytes(peak),
            "estimate": format_bytes(d["estimate_bytes"])}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
