"""PRT speed of the three things users wait for: the shadowed bake (unrefined, and the default
with a ground: the quick refinement), the interreflected bake with a ground (the quick
refinement, the default) and relighting 100,000 vertices. Wall and process CPU seconds.

Run one measurement per process, alternating two checkouts to compare them in one run, e.g.
    for w in relight shadowed interreflected; do
      PYTHONPATH=../old/src python bench/bench_prt_speed.py $w
      PYTHONPATH=src python bench/bench_prt_speed.py $w
    done
On a loaded machine compare the CPU seconds: wall time there measures the load.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # the relight is one small sgemm

import argparse
import json
import time
from pathlib import Path

import numpy as np

from shprobe.prt import bake, relight

DATA = Path(os.environ.get("SHPROBE_TEST_DATA", Path(__file__).resolve().parents[2] / "shared"))


def timed(fn):
    w, c = time.perf_counter(), time.process_time()
    fn()
    return round(time.perf_counter() - w, 3), round(time.process_time() - c, 3)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("what", choices=["relight", "shadowed", "interreflected"])
    ap.add_argument("--mesh", default=str(DATA / "meshes" / "bunny.obj"))
    a = ap.parse_args()
    res = {}
    if a.what == "shadowed":
        res["shadowed bake, unrefined, lmax 4 (wall s, CPU s)"] = timed(lambda: bake(
            a.mesh, ground=True, mode="shadowed", lmax=4, samples=1024, threads=2,
            refine=False))
        res["shadowed bake, default (quick refinement), lmax 2"] = timed(lambda: bake(
            a.mesh, ground=True, mode="shadowed", lmax=2, samples=1024, threads=2))
    elif a.what == "interreflected":
        # the quick refinement: the default now, refine="quick" (--quick-contact) before
        res["interreflected bake, quick refinement, lmax 2 (wall s, CPU s)"] = timed(
            lambda: bake(a.mesh, ground=True, mode="interreflected", lmax=2, samples=1024,
                         bounces=2, threads=2, refine="quick"))
    else:
        rng = np.random.default_rng(0)
        t = rng.standard_normal((100_000, 25)).astype(np.float32)
        light = rng.standard_normal((25, 3))
        relight(t, light)
        best = min(timed(lambda: relight(t, light)) for _ in range(50))
        res["relight, 100k vertices, lmax 4 (wall ms, CPU ms)"] = tuple(1000 * x for x in best)
    print(json.dumps(res), flush=True)


if __name__ == "__main__":
    main()
