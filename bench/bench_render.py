"""Rendering speed (issue: see it and ship it).

Run: ``PYTHONPATH=src python bench/bench_render.py`` — prints markdown tables.

1. 1024×1024 render of the bunny (../shared/meshes/bunny.obj), per-pixel and per-vertex
   shading: the whole ``shprobe.scene.render.render`` call (rays, Embree, normals, shading), and
   its parts.
2. Shading 10⁶ vertex normals with 9 RGB coefficients: shprobe's numba kernel (R&H eq. 11–13)
   against peers measured in the same run: the eq. 13 polynomial vectorised in numpy, the SH
   basis (shprobe.sh_basis) times the 9×3 irradiance coefficients, and sphericart's basis
   (its real SH differ from R&H's by sign/normalisation convention only; timing only).

Median of repeated runs after one warm-up (numba compile excluded), one thread.
"""

from __future__ import annotations

import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from shprobe.lighting.irradiance import shade_irradiance  # noqa: E402
from shprobe.scene import Camera, load_mesh, render, trace  # noqa: E402
from shprobe.sh import sh_basis  # noqa: E402
from shprobe.sh.zonal import clamped_cosine_factors, convolve  # noqa: E402


def timeit(fn, repeat=5):
    fn()
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts), min(ts)


def poly_numpy(L, n):
    """R&H eq. 13 vectorised in numpy."""
    c1, c2, c3, c4, c5 = 0.429043, 0.511664, 0.743125, 0.886227, 0.247708
    x, y, z = n[:, 0:1], n[:, 1:2], n[:, 2:3]
    return (c1 * L[8] * (x * x - y * y) + c3 * L[6] * z * z + c4 * L[0] - c5 * L[6]
            + 2 * c1 * (L[4] * x * y + L[7] * x * z + L[5] * y * z)
            + 2 * c2 * (L[3] * x + L[1] * y + L[2] * z))


def main() -> None:
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    rng = np.random.default_rng(0)
    L = rng.normal(size=(9, 3))
    L[0] += 3
    shared = Path(os.environ.get("SHPROBE_TEST_DATA", REPO.parent / "shared"))
    bunny = shared / "meshes" / "bunny.obj"
    print(f"machine: {platform.machine()} {platform.system()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}, numpy {np.__version__}\n")

    if bunny.is_file():
        mesh = load_mesh(bunny)
        cam = Camera(1024, 1024, azimuth=30, elevation=15)
        rows = []
        for mode in ("pixel", "vertex"):
            med, best = timeit(lambda mode=mode: render(mesh, L, cam, mode=mode))
            rows.append((f"render bunny 1024² {mode}", med, best))
        med, best = timeit(lambda: trace(mesh, cam))
        rows.append(("  of which: rays + Embree + normals", med, best))
        hits = trace(mesh, cam)
        nh = hits.normal[hits.face >= 0]
        med, best = timeit(lambda: shade_irradiance(L, nh))
        rows.append((f"  of which: shading {len(nh)} pixels", med, best))
        print("| 1024×1024 bunny (" + f"{len(mesh.faces)} triangles) | median s | best s |")
        print("| --- | --- | --- |")
        for name, med, best in rows:
            print(f"| {name} | {med:.3f} | {best:.3f} |")
        print()
    else:
        print(f"(bunny not found at {bunny}; skipped)\n")

    n = rng.normal(size=(1_000_000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n32 = n.astype(np.float32)
    E_lm = convolve(L, clamped_cosine_factors(2))
    peers = [
        ("shprobe shade_irradiance (numba, eq. 11-13), float32 in",
         lambda: shade_irradiance(L, n32)),
        ("shprobe shade_irradiance (numba), float64 in", lambda: shade_irradiance(L, n)),
        ("numpy eq. 13 vectorised", lambda: poly_numpy(L, n)),
        ("shprobe sh_basis + (9x3) matmul", lambda: sh_basis(n, 2) @ E_lm),
    ]
    try:
        import sphericart

        calc = sphericart.SphericalHarmonics(2)
        peers.append(("sphericart basis + (9x3) matmul", lambda: calc.compute(n) @ E_lm))
    except ImportError:
        pass
    print("| shading 10⁶ vertex normals, 9 RGB coefficients | median ms | best ms |")
    print("| --- | --- | --- |")
    for name, fn in peers:
        med, best = timeit(fn, repeat=7)
        print(f"| {name} | {1e3 * med:.1f} | {1e3 * best:.1f} |")


if __name__ == "__main__":
    main()
