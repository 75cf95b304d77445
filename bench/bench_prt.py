"""PRT benchmark: shadowed bake throughput against raw Embree any-hit rays on the same
mesh and rays, the bunny + ground bake, and run-time relighting of 100,000 vertices.

Run: PYTHONPATH=src python bench/bench_prt.py [--mesh PATH] [--samples 1024] [--lmax 4]
Prints a markdown table. Peers in the same run: embreex `EmbreeScene.run(query='OCCLUDED')`
called directly on the bake's own rays, and trimesh's `ray_pyembree.intersects_any`.
"""

from __future__ import annotations

import os

# BLAS pinned to one thread before numpy loads: the relight timings (one sgemm) are stable
# that way on a shared 2-core box; the bakes do no BLAS work of note.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import platform
import time
from pathlib import Path

import numpy as np

from shprobe.prt import Transfer, bake, load_scene, relight, sample_directions
from shprobe.prt.directions import OFFSET_FRACTION, random_rotation
from shprobe.scene import RayCaster

HERE = Path(__file__).resolve().parent


def best(fn, repeat=3):
    """Best wall time and best process CPU time (all threads) of ``repeat`` calls (seconds),
    and the last result."""
    wall, cpu, out = float("inf"), float("inf"), None
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        out = fn()
        wall = min(wall, time.perf_counter() - w)
        cpu = min(cpu, time.process_time() - c)
    return wall, cpu, out


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
    load0 = os.getloadavg()

    scene = load_scene(args.mesh, ground=True)
    o, d = bake_rays(scene, args.samples, 0)
    n_rays = len(o)
    caster = RayCaster(scene.vertices, scene.faces)
    ol = caster.local(o)  # the bake maps its ray origins into the caster's frame once, too
    half = n_rays // 2
    parts = [(ol[:half], d[:half]), (ol[half:], d[half:])]
    from concurrent.futures import ThreadPoolExecutor

    ex = ThreadPoolExecutor(2)
    runs = {
        "shprobe shadowed bake, 1 thread": lambda: bake(
            scene, mode="shadowed", lmax=args.lmax, samples=args.samples, seed=0, threads=1),
        "embreex run(OCCLUDED) on the same rays, 1 thread": lambda: caster.occluded_local(ol, d),
        "shprobe shadowed bake, 2 threads": lambda: bake(
            scene, mode="shadowed", lmax=args.lmax, samples=args.samples, seed=0, threads=2),
        "embreex run(OCCLUDED) on the same rays, 2 threads":
            lambda: list(ex.map(lambda p: caster.occluded_local(*p), parts)),
    }
    # interleaved rounds, best of each: the machine is shared, so load hits all alike
    wall = {k: float("inf") for k in runs}
    cpu = dict(wall)
    for _ in range(args.rounds):
        for k, fn in runs.items():
            w, c, _ = best(fn, 1)
            wall[k], cpu[k] = min(wall[k], w), min(cpu[k], c)
    ex.shutdown()
    hit = caster.occluded_local(ol, d)
    rows = [(k, wall[k], cpu[k], n_rays) for k in runs]

    import trimesh
    from trimesh.ray.ray_pyembree import RayMeshIntersector

    tm = trimesh.Trimesh(scene.vertices, scene.faces, process=False)
    rmi = RayMeshIntersector(tm)
    w, c, _ = best(lambda: rmi.intersects_any(o, d), 1)
    rows.append(("trimesh ray_pyembree.intersects_any, same rays", w, c, n_rays))
    w, c, _ = best(lambda: bake(args.mesh, ground=True, mode="shadowed", lmax=args.lmax,
                                samples=args.samples, seed=0, threads=2, refine=False), 3)
    rows.append(("shprobe shadowed bake from the .obj path (load + ground + bake), 2 threads",
                 w, c, n_rays))
    w, c, _ = best(lambda: bake(scene, mode="interreflected", lmax=args.lmax,
                                   samples=args.samples, bounces=2, seed=0, threads=2), 3)
    rows.append(("shprobe interreflected bake, 2 bounces (all models), 2 threads", w, c, n_rays))
    w, c, _ = best(lambda: bake(scene, mode="unshadowed", lmax=args.lmax), 3)
    rows.append(("shprobe unshadowed bake (analytic)", w, c, 0))

    print(f"# PRT bench — {platform.node()} {platform.machine()}, {os.cpu_count()} cores, "
          f"load average {load0[0]:.2f} / {load0[1]:.2f} / {load0[2]:.2f} (1/5/15 min) at "
          "start\n")
    print(f"Scene: {Path(args.mesh).name} + ground plane, {scene.n_vertices} vertices, "
          f"{len(scene.faces)} triangles; {args.samples} directions/vertex, lmax={args.lmax}, "
          f"{n_rays} rays traced (upper hemispheres), {hit.mean():.1%} blocked. "
          f"Best of {args.rounds} interleaved rounds (first four rows), else best of 3 "
          "(trimesh: 1).\n")
    print("| what | wall (s) | CPU (s) | rays/s wall (M) | rays per CPU-s (M) |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for name, w, c, n in rows:
        rw = f"{n / w / 1e6:.2f}" if n else "–"
        rc = f"{n / c / 1e6:.2f}" if n else "–"
        print(f"| {name} | {w:.3f} | {c:.3f} | {rw} | {rc} |")
    k1, e1, k2, e2 = list(runs)
    print(f"\nBake / raw Embree throughput — wall: {wall[e1] / wall[k1]:.0%} (1 thread), "
          f"{wall[e2] / wall[k2]:.0%} (2 threads); CPU time: {cpu[e1] / cpu[k1]:.0%} "
          f"(1 thread), {cpu[e2] / cpu[k2]:.0%} (2 threads).\n")

    # run time: relight V vertices at lmax including the Wigner rotation of the lighting
    rng = np.random.default_rng(0)
    k = (args.lmax + 1) ** 2
    V = args.vertices
    T = rng.normal(size=(V, k)).astype(np.float32)
    Tc = rng.normal(size=(V, k, 3)).astype(np.float32)
    L = rng.normal(size=(k, 3))
    R = random_rotation(rng)
    normals = rng.normal(size=(V, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    # a Transfer as an interreflected bake of V vertices with 2 bounces leaves it
    big = Transfer(vertices=normals, normals=normals, faces=np.zeros((0, 3), np.int64),
                   albedo=np.full((V, 3), 0.8), lmax=args.lmax,
                   traced=rng.normal(size=(3, V, k)).astype(np.float32), bounce_counts=(0, 1, 2),
                   metadata={"mode": "interreflected"})
    w_un, _, _ = best(lambda: relight(big, L, R, mode="unshadowed"), 1)  # computes, caches
    relight(T, L, rotation=R)  # warm caches
    Lf = L.astype(np.float32)
    n = 30
    rr = [
        ("shprobe relight, grey transfer (V, K), with rotation",
         best(lambda: relight(T, L, rotation=R), n)),
        ("shprobe relight, grey transfer, no rotation", best(lambda: relight(T, L), n)),
        ("shprobe relight, coloured transfer (V, K, 3), with rotation",
         best(lambda: relight(Tc, L, rotation=R), n)),
        ("shprobe relight of a Transfer, --mode shadowed picked at run time, with rotation",
         best(lambda: relight(big, L, R, mode="shadowed"), n)),
        ("shprobe relight of a Transfer, --bounces 1 picked at run time, with rotation",
         best(lambda: relight(big, L, R, bounces=1), n)),
        ("shprobe relight of a Transfer, unshadowed (analytic, cached), with rotation",
         best(lambda: relight(big, L, R, mode="unshadowed"), n)),
        ("numpy T @ L alone (float32)", best(lambda: T @ Lf, n)),
    ]
    print(f"Relight: {V} vertices, lmax={args.lmax}, best of {n}, BLAS "
          f"(OpenBLAS) threads = {os.environ['OPENBLAS_NUM_THREADS']}.\n")
    print("| what | wall (ms) | CPU (ms) |")
    print("| --- | ---: | ---: |")
    for name, (w, c, _) in rr:
        print(f"| {name} | {w * 1e3:.2f} | {c * 1e3:.2f} |")
    print(f"\nFirst unshadowed relight of that Transfer (computes the analytic transfer of {V} "
          f"normals once): {w_un * 1e3:.1f} ms.")
    load1 = os.getloadavg()
    print(f"\nLoad average at the end: {load1[0]:.2f} / {load1[1]:.2f} / {load1[2]:.2f}.")


if __name__ == "__main__":
    main()
