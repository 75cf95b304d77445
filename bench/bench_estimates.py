"""Memory estimates against measured peaks: every bake, export and transform that checks its
memory before it starts, run in a fresh process at a modest size.

Each case runs in a child process (``python bench/bench_estimates.py --child CASE SCALE``): it
builds its inputs, resets the kernel's high-water mark of its resident memory
(``/proc/self/clear_refs``), notes its resident memory, runs the operation and reads the
high-water mark again (``VmHWM``); the peak is the difference, what the operation itself
allocated, set against the estimate the operation checks against ``--max-memory``.

Run: ``python bench/bench_estimates.py [--scale small|medium] [--tolerance 0.2]``. Prints a
markdown table and exits 1 when an estimate is more than the tolerance away from its peak.
Linux only (``/proc``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

#: Problem size of each case per scale (probes per axis, splats, ...).
SIZES = {
    "small": {"grid-bake": (16, 8, 16), "grid-bake-bounce": (10, 6, 10),
              "grid-bake-many": (24, 8, 24), "grid-export": (48, 24, 48), "splats": 150_000},
    "medium": {"grid-bake": (28, 12, 28), "grid-bake-bounce": (16, 8, 16),
               "grid-bake-many": (40, 16, 40), "grid-export": (80, 40, 80),
               "splats": 400_000},
}
CASES = ["grid-bake", "grid-bake-bounce", "grid-bake-many", "grid-export-three",
         "grid-export-unity", "grid-export-godot", "splat-write-spz", "splat-write-glb",
         "splat-read-ply", "splat-read-spz", "splat-read-glb", "splat-transform-ply",
         "splat-transform-ply-spz", "splat-transform-ply-glb", "splat-transform-glb-spz"]


def _status(key: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024
    raise RuntimeError(f"no {key} in /proc/self/status")


def _measure(op) -> tuple[int, int]:
    """(bytes the call ``op()`` allocated at its peak, resident bytes before it)."""
    import gc

    gc.collect()
    try:  # hand the memory freed while the inputs were made back to the kernel first, so
        # that the call's peak is not hidden in pages already resident
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # reset VmHWM to the current resident size
    before = _status("VmRSS")
    op()
    return _status("VmHWM") - before, before


def _grid(res):
    import numpy as np

    from shprobe.grids import ProbeGrid

    rng = np.random.default_rng(0)
    return ProbeGrid(coeffs=rng.normal(size=(*res, 9, 3)).astype(np.float32),
                     bounds=np.array([[-1.0, -1, -1], [1, 1, 1]]))


def _splats(n: int):
    import numpy as np

    from shprobe.splats import Splats

    rng = np.random.default_rng(0)
    return Splats(rng.normal(size=(n, 3)).astype(np.float32),
                  (rng.normal(size=(n, 3)) - 3).astype(np.float32),
                  rng.normal(size=(n, 4)).astype(np.float32),
                  rng.normal(size=n).astype(np.float32),
                  (rng.normal(size=(n, 16, 3)) * 0.3).astype(np.float32))


def child(case: str, scale: str, tmp: Path) -> dict:
    """Run one case in this process: its estimate and its measured peak."""
    size = SIZES[scale]
    if case.startswith("grid-bake"):
        import numpy as np

        from shprobe.grids import GridSettings, bake_grid, estimate_grid_bake
        from shprobe.grids.scenes import named_scene
        from shprobe.prt import load_scene
        from shprobe.sh.indexing import num_coeffs

        scene, bounds = named_scene("room")
        sc = load_scene(scene)
        bounce = case.endswith("bounce")  # "many": many probes, few rays (depth rays rule)
        settings = GridSettings(resolution=size[case], bounds=bounds,
                                samples=64 if case.endswith("many") else 256,
                                bounces=1 if bounce else 0, gather=0)
        light = np.zeros((num_coeffs(2), 3))
        light[0] = 1.0
        est = estimate_grid_bake(len(sc.faces), settings).nbytes
        peak, base = _measure(lambda: bake_grid(sc, light, settings))
    elif case.startswith("grid-export"):
        from shprobe.grids.exports import estimate_export, export_text

        g = _grid(size["grid-export"])
        fmt = case.rsplit("-", 1)[1]
        est = estimate_export(g, fmt)
        peak, base = _measure(lambda: export_text(g, fmt))
    elif case.startswith("splat-write"):
        import shprobe.splats as sp
        from shprobe.splats.formats import estimate_write

        s = _splats(size["splats"])
        out = tmp / f"s.{case.rsplit('-', 1)[1]}"
        est = estimate_write(s, out)
        peak, base = _measure(lambda: sp.write(out, s))
    elif case.startswith("splat-read"):
        import shprobe.splats as sp
        from shprobe.splats.formats import estimate_read

        n, kind = size["splats"], "." + case.rsplit("-", 1)[1]
        src = tmp / f"s{kind}"
        sp.write(src, _splats(n))
        est = estimate_read(n, 3, kind)
        peak, base = _measure(lambda: sp.read(src))
    elif case.startswith("splat-transform-") and case.count("-") == 3:
        import shprobe.splats as sp
        from shprobe.splats.formats import estimate_transform

        n = size["splats"]
        a, b = ("." + x for x in case.split("-")[2:])
        src, out = tmp / f"s{a}", tmp / f"t{b}"
        sp.write(src, _splats(n))
        settings = sp.TransformSettings(similarity=sp.rotation([[0, -1, 0], [1, 0, 0],
                                                                 [0, 0, 1]]))
        est = estimate_transform(n, 3, a, b)
        peak, base = _measure(lambda: sp.transform_file(src, out, settings))
    elif case == "splat-transform-ply":
        import shprobe.splats as sp
        from shprobe.splats.formats import estimate_stream
        from shprobe.splats.ply import read_layout

        src = tmp / "s.ply"
        sp.write(src, _splats(size["splats"]))
        settings = sp.TransformSettings(similarity=sp.rotation([[0, -1, 0], [1, 0, 0],
                                                                 [0, 0, 1]]))
        out = tmp / "t.ply"
        est = estimate_stream(read_layout(src))
        peak, base = _measure(lambda: sp.transform_file(src, out, settings))
    else:
        raise SystemExit(f"unknown case {case}")
    return {"case": case, "estimate": float(est), "peak": float(peak), "base": float(base)}


def run(scale: str, tolerance: float, cases: list[str]) -> int:
    from _machine import machine

    rows, bad = [], 0
    for case in cases:
        with tempfile.TemporaryDirectory() as d:
            r = subprocess.run([sys.executable, __file__, "--child", case, "--scale", scale,
                                "--tmp", d], capture_output=True, text=True, timeout=900)
        if r.returncode != 0:
            print(f"{case}: child failed:\n{r.stderr[-2000:]}", file=sys.stderr)
            bad += 1
            continue
        res = json.loads(r.stdout.strip().splitlines()[-1])
        ratio = res["estimate"] / max(res["peak"], 1.0)
        ok = abs(ratio - 1.0) <= tolerance
        bad += not ok
        rows.append(f"| {case} | {res['estimate'] / 1e6:,.0f} | {res['peak'] / 1e6:,.0f} | "
                    f"{ratio:.2f} | {'ok' if ok else 'OUT'} |")
    print(f"machine: {machine()}")
    print(f"scale {scale}: {json.dumps({k: v for k, v in SIZES[scale].items()})}\n")
    print("| case | estimate MB | measured peak MB | estimate / peak | within "
          f"{tolerance:.0%} |")
    print("| --- | ---: | ---: | ---: | --- |")
    print("\n".join(rows))
    return 1 if bad else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", choices=sorted(SIZES), default="small")
    ap.add_argument("--tolerance", type=float, default=0.2)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--child")
    ap.add_argument("--tmp")
    a = ap.parse_args()
    if a.child:
        print(json.dumps(child(a.child, a.scale, Path(a.tmp))))
        return 0
    return run(a.scale, a.tolerance, [c for c in a.cases.split(",") if c])


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "2")
    raise SystemExit(main())
