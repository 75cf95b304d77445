"""PRT benchmark (issue 6): shadowed bake throughput against raw Embree any-hit rays on the same
mesh and rays, the bunny + ground bake, and run-time relighting of 100,000 vertices.

Run: PYTHONPATH=src python bench/bench_prt.py [--mesh PATH] [--samples 1024] [--lmax 4]
Prints a markdown table. Peers in the same run: embreex `EmbreeScene.run(query='OCCLUDED')`
called directly on the bake's own rays, and trimesh's `ray_pyembree.intersects_any`.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from shprobe.prt import bake, load_scene, relight, sample_directions
from shprobe.prt.bake import OFFSET_FRACTION, RayCaster

HERE = Path(__file__).resolve().parent


def best(fn, repeat=3):
    """Best wall time of ``repeat`` calls (seconds) and the last result."""
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def bake_rays(scene, samples, seed):
    """The exact rays the shadowed bake traces (origins, directions), float32."""
    d = sample_directions(samples, seed).astype(np.float32)
    eps = OFFSET_FRACTION * float(np.linalg.norm(np.ptp(scene.vertices, axis=0)))
    p = (scene.vertices + eps * scene.normals).astype(np.float32)
    cos = scene.normals.astype(np.float32) @ d.T
    vi, dj = np.nonzero(cos > 0)
    return p[vi], d[dj]


def main() -> None:
    ap = argparse.ArgumentParser()
    default_mesh = os.environ.get("SHPROBE_TEST_DATA", str(HERE.parent.parent / "shared"))
    ap.add_argument("--mesh", default=str(Path(default_mesh) / "meshes" / "bunny.obj"))
    ap.add_argument("--samples", type=int, default=1024)
    ap.add_argument("--lmax", type=int, default=4)
    ap.add_argument("--vertices", type=int, default=100_000)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()

    scene = load_scene(args.mesh, ground=True)
    o, d = bake_rays(scene, args.samples, 0)
    n_rays = len(o)
    caster = RayCaster(scene)
    half = n_rays // 2
    parts = [(o[:half], d[:half]), (o[half:], d[half:])]
    from concurrent.futures import ThreadPoolExecutor

    ex = ThreadPoolExecutor(2)
    runs = {
        "shprobe shadowed bake, 1 thread": lambda: bake(
            scene, mode="shadowed", lmax=args.lmax, samples=args.samples, seed=0, threads=1),
        "embreex run(OCCLUDED) on the same rays, 1 thread": lambda: caster.occluded(o, d),
        "shprobe shadowed bake, 2 threads": lambda: bake(
            scene, mode="shadowed", lmax=args.lmax, samples=args.samples, seed=0, threads=2),
        "embreex run(OCCLUDED) on the same rays, 2 threads":
            lambda: list(ex.map(lambda p: caster.occluded(*p), parts)),
    }
    # interleaved rounds, best of each: the machine is shared, so load hits all alike
    times = {k: float("inf") for k in runs}
    for _ in range(args.rounds):
        for k, fn in runs.items():
            times[k] = min(times[k], best(fn, 1)[0])
    ex.shutdown()
    hit = caster.occluded(o, d)
    rows = [(k, t, n_rays / t) for k, t in times.items()]

    import trimesh
    from trimesh.ray.ray_pyembree import RayMeshIntersector

    tm = trimesh.Trimesh(scene.vertices, scene.faces, process=False)
    rmi = RayMeshIntersector(tm)
    t_tm, _ = best(lambda: rmi.intersects_any(o, d), 1)
    rows.append(("trimesh ray_pyembree.intersects_any, same rays", t_tm, n_rays / t_tm))

    t_ir, _ = best(lambda: bake(scene, mode="interreflected", lmax=args.lmax,
                                samples=args.samples, bounces=2, seed=0, threads=2), 1)
    rows.append(("shprobe interreflected bake, 2 bounces, 2 threads", t_ir, n_rays / t_ir))
    t_un, _ = best(lambda: bake(scene, mode="unshadowed", lmax=args.lmax), 3)
    rows.append(("shprobe unshadowed bake (analytic)", t_un, float("nan")))

    print(f"# PRT bench — {platform.node()} {platform.machine()}, {os.cpu_count()} cores\n")
    print(f"Scene: {Path(args.mesh).name} + ground plane, {scene.n_vertices} vertices, "
          f"{len(scene.faces)} triangles; {args.samples} directions/vertex, lmax={args.lmax}, "
          f"{n_rays} rays traced (upper hemispheres), {hit.mean():.1%} blocked.\n")
    print("| what | time (s) | rays/s (M) |")
    print("| --- | ---: | ---: |")
    for name, t, r in rows:
        print(f"| {name} | {t:.3f} | {r / 1e6:.2f} |")
    ratio1 = rows[0][2] / rows[1][2]
    ratio2 = rows[2][2] / rows[3][2]
    print(f"\nBake / raw Embree throughput: {ratio1:.0%} (1 thread), {ratio2:.0%} (2 threads).\n")

    # run time: relight V vertices at lmax including the Wigner rotation of the lighting
    rng = np.random.default_rng(0)
    k = (args.lmax + 1) ** 2
    T = rng.normal(size=(args.vertices, k)).astype(np.float32)
    Tc = rng.normal(size=(args.vertices, k, 3)).astype(np.float32)
    L = rng.normal(size=(k, 3))
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    relight(T, L, rotation=R)  # warm caches
    Lf = L.astype(np.float32)
    rr = [
        ("shprobe relight, grey transfer (V, K), with rotation",
         best(lambda: relight(T, L, rotation=R), 30)[0]),
        ("shprobe relight, grey transfer, no rotation", best(lambda: relight(T, L), 30)[0]),
        ("shprobe relight, coloured transfer (V, K, 3), with rotation",
         best(lambda: relight(Tc, L, rotation=R), 30)[0]),
        ("numpy T @ L alone (float32)", best(lambda: T @ Lf, 30)[0]),
    ]
    print(f"Relight: {args.vertices} vertices, lmax={args.lmax}, best of 30.\n")
    print("| what | time (ms) |")
    print("| --- | ---: |")
    for name, t in rr:
        print(f"| {name} | {t * 1e3:.2f} |")


if __name__ == "__main__":
    main()
