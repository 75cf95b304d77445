"""Issue 17: is `shprobe error`'s max the worst case? The refined max (default settings) vs the
sample max over a 512×1024 lat-long grid of normals (brute-force E at every one: ~1.7e10 pair
operations per probe), and the runtime of the error report with and without refinement.

    PYTHONPATH=src python bench/bench_error_max.py [--grid 512] [--repeat 5]

Prints a markdown table per probe: lmax, grid max at N = 32 / 64 / 128 / 256 / 512, the refined
max with its tolerance and the normal where it occurs, and |refined − 512-grid| (must be ≤ tol,
or the refined max larger: the grid can only under-estimate a maximum).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _machine import machine
from shprobe.lighting.irradiance import irradiance
from shprobe.lighting.projection import project, total_intensity
from shprobe.lighting.reference import _normal_grid, error_report, reference_irradiance
from shprobe.probes.layouts import load_env

DATA = os.environ.get("SHPROBE_TEST_DATA", os.path.join(os.path.dirname(__file__), "..", "..",
                                                         "shared"))


def grid_max(env, coeffs, tot, n: int, lmaxes) -> dict[int, float]:
    nrm, _ = _normal_grid(n)
    ref = reference_irradiance(env, nrm)
    return {lm: float((np.abs(irradiance(coeffs[: (lm + 1) ** 2], nrm) - ref) / tot).max())
            for lm in lmaxes}


def patch_max(env, coeffs, tot, lmax, centre, half=0.015, n=301) -> float:
    """Max of the error over an n×n patch of normals within ±half rad of ``centre``."""
    c = np.asarray(centre, dtype=np.float64)
    a = np.array([1.0, 0, 0]) if abs(c[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(c, a)
    u /= np.linalg.norm(u)
    w = np.cross(c, u)
    t = np.linspace(-half, half, n)
    x, y = np.meshgrid(t, t)
    p = c + x[..., None] * u + y[..., None] * w
    p = (p / np.linalg.norm(p, axis=-1, keepdims=True)).reshape(-1, 3)
    e = np.abs(irradiance(coeffs[: (lmax + 1) ** 2], p) - reference_irradiance(env, p)) / tot
    return float(e.max())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--grid", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    print(machine())
    lmaxes = (1, 2, 3, 4)
    for name in ("grace", "ennis"):
        env = load_env(os.path.join(DATA, "probes", f"{name}.hdr"))
        coeffs = project(env, 4)
        tot = total_intensity(env)
        rep = error_report(env)
        t0 = time.perf_counter()
        grids = {n: grid_max(env, coeffs, tot, n, lmaxes) for n in (32, 64, 128, 256, a.grid)}
        tg = time.perf_counter() - t0
        print(f"\n### {name}  (grids 32..{a.grid}: {tg:.1f} s)\n")
        print("| lmax | grid 32 | 64 | 128 | 256 | " + f"{a.grid} | refined (tol) | at normal |"
              " refined − grid " + f"{a.grid} |")
        print("|---|---|---|---|---|---|---|---|---|")
        for r in rep.rows:
            g = [100 * grids[n][r.lmax] for n in (32, 64, 128, 256, a.grid)]
            d = 100 * (r.max_frac - grids[a.grid][r.lmax])
            nn = ", ".join(f"{x:+.3f}" for x in r.max_normal)
            print(f"| {r.lmax} | " + " | ".join(f"{x:.4f} %" for x in g)
                  + f" | {100 * r.max_frac:.4f} % (±{100 * r.max_tol:.4f}) | ({nn}) | "
                    f"{d:+.5f} pp |")
        # the refined max against a fine brute-force patch around its normal (and around the
        # 512-grid's worst normal): ±0.015 rad, 301×301 normals, spacing 1e-4 rad
        print()
        nrm512, _ = _normal_grid(a.grid)
        ref512 = reference_irradiance(env, nrm512)
        for r in rep.rows:
            e512 = np.abs(irradiance(coeffs[: (r.lmax + 1) ** 2], nrm512) - ref512) / tot
            at512 = nrm512[int(np.argmax(e512.max(1)))]
            best = max(patch_max(env, coeffs, tot, r.lmax, c) for c in (r.max_normal, at512))
            print(f"- lmax {r.lmax}: fine patch max {100 * best:.4f} %, refined − patch "
                  f"{100 * (r.max_frac - best):+.5f} pp (tol {100 * r.max_tol:.4f} pp)")
        # runtime of the library call, interleaved, with and without refinement
        ts: dict[str, list[float]] = {"grid only (before)": [], "refined (after)": []}
        for _ in range(a.repeat):
            for k, ref in (("grid only (before)", False), ("refined (after)", True)):
                t0 = time.perf_counter()
                error_report(env, refine=ref)
                ts[k].append(time.perf_counter() - t0)
        print()
        for k, v in ts.items():
            print(f"- error_report {k}: best {1e3 * min(v):.0f} ms, median "
                  f"{1e3 * statistics.median(v):.0f} ms")
    print("\n" + machine().split(", load")[1].join(["end: load", ""]))


if __name__ == "__main__":
    main()
