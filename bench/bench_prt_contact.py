"""Issue 17: interreflected PRT at the object–ground contact, uniform ground vs adaptive
refinement (shprobe.prt.refine), against an independent per-point gather (tests/prt_gather.py:
its own Embree ray loop, cosine-weighted stratified sampling, exact hit points, no transfer
vectors) under band-limited lighting (lmax 2, so PRT at lmax 2 is exact up to noise).

    PYTHONPATH=src python bench/bench_prt_contact.py [--mesh bunny.obj] [--samples 1024]
        [--tol 0.25] [--ref 256] [--n 40]

Vertices: the original scene's (the refinement keeps them, with their indices): "contact" =
within 8 % of the object's size of its lowest 3 %, "far" = beyond 30 % (random subsets of --n).
Errors: |B_PRT − B_ref| / B_ref of the exit radiance with 1 and 2 bounces (cumulative: direct +
bounces), at vertices whose B_ref exceeds 2 % of the far vertices' median (ground under the
belly, B ≈ 0.1 % of that, is left out: its relative error is meaningless). The reference is
gathered twice with different seeds; their difference is its own noise, and the errors use
their mean. The bake's noise at the same vertices: two bakes with seeds 0 and 1.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
from tests.prt_gather import Gather  # noqa: E402

from _machine import machine  # noqa: E402
from shprobe.prt import bake, relight  # noqa: E402
from shprobe.prt.refine import bake_refined  # noqa: E402

DATA = os.environ.get("SHPROBE_TEST_DATA", os.path.join(HERE, "..", "..", "shared"))
L = np.zeros(9)
L[0], L[1], L[3], L[6] = 3.0, 1.0, 0.5, 0.3  # positive sky, brighter above (radiance, lmax 2)


def cumulative(t, idx):
    lc = np.repeat(L[:, None], 3, 1)
    return [relight(t, lc, mode="shadowed")[idx, 0], relight(t, lc, bounces=1)[idx, 0],
            relight(t, lc, bounces=2)[idx, 0]]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--mesh", default=os.path.join(DATA, "meshes", "bunny.obj"))
    ap.add_argument("--samples", type=int, default=1024)
    ap.add_argument("--tol", type=float, default=0.25)
    ap.add_argument("--ref", type=int, default=512)
    ap.add_argument("--n", type=int, default=40)
    a = ap.parse_args()
    import trimesh
    from scipy.spatial import cKDTree

    print(machine())
    m = trimesh.load(a.mesh, process=False)
    kw = dict(mode="interreflected", lmax=2, samples=a.samples, bounces=2, albedo=0.8)
    t0 = time.perf_counter()
    tu = bake(m, ground=True, refine=False, **kw)
    t_u = time.perf_counter() - t0
    t0 = time.perf_counter()
    tr = bake_refined(m, tol=a.tol, refine_mesh=True, **kw)
    t_r = time.perf_counter() - t0
    tr1 = bake_refined(m, tol=a.tol, refine_mesh=True, **{**kw, "seed": 1})
    rounds = tr.metadata["refine"]["rounds"]
    print(f"\nuniform 64x64 ground: {tu.n_vertices} vertices, bake {t_u:.1f} s")
    print(f"refined (tol {a.tol}, ground + mesh): {tr.n_vertices} vertices, bake {t_r:.1f} s "
          f"total over {len(rounds)} bakes: " + ", ".join(
              f"{r['vertices']} v {r['seconds']:.1f} s" for r in rounds)
          + f" (driving bakes at {max(64, a.samples // 4)} directions, the last at {a.samples})")
    v, n, f, alb = tu.vertices, tu.normals, tu.faces, tu.albedo
    nm = len(m.vertices)
    isg = np.arange(len(v)) >= nm
    ymin = v[:, 1].min()
    low = v[(~isg) & (v[:, 1] < ymin + 0.03 * np.ptp(v[~isg, 1]))]
    d = cKDTree(low).query(v)[0]
    size = np.ptp(v[~isg], axis=0).max()
    rng = np.random.default_rng(0)
    sets = {"contact": np.flatnonzero(d < 0.08 * size), "far": np.flatnonzero(d > 0.3 * size)}
    sets = {k: np.sort(rng.choice(s, min(a.n, len(s)), replace=False)) for k, s in sets.items()}
    R = a.ref
    print(f"\nreference: B1 ({R}, {R}) rays per level, B2 ({R // 2}, {R // 4}, {R // 4}); "
          f"bake {a.samples} directions\n")
    print("| vertices | model | n | ref noise (median) | bake noise (median) | uniform: max / "
          "median error | refined: max / median error |")
    print("|---|---|---|---|---|---|---|")
    res = {}
    floor = None  # 2 % of the far vertices' median radiance: relative errors of the dark
    for name, idx in sorted(sets.items(), key=lambda x: x[0] != "far"):  # (far first)
        refs = []
        for seed in (1, 2):
            g = Gather(v, f, n, alb, L, seed=seed)
            r0 = g.radiance(v[idx], n[idx], alb[idx, 0], 0, (4096,))
            r1 = g.radiance(v[idx], n[idx], alb[idx, 0], 1, (R, R))
            r2 = g.radiance(v[idx], n[idx], alb[idx, 0], 2, (R // 2, R // 4, R // 4))
            refs.append((r0 + r1, r0 + r1 + r2))
        bu, br, br1 = (cumulative(t, idx) for t in (tu, tr, tr1))
        for k in (1, 2):
            ref = 0.5 * (refs[0][k - 1] + refs[1][k - 1])
            if floor is None or name == "far":
                floor = 0.02 * np.median(ref)
            ok = ref > floor  # (crevice under the belly, B ≈ 0) would be meaningless
            rn = np.abs(refs[0][k - 1] - refs[1][k - 1])[ok] / ref[ok] / 2
            bn = np.abs(br[k] - br1[k])[ok] / ref[ok] / np.sqrt(2)
            eu = np.abs(bu[k] - ref)[ok] / ref[ok]
            er = np.abs(br[k] - ref)[ok] / ref[ok]
            res[name, k] = (eu, er)
            print(f"| {name} | {k} bounce{'s' if k > 1 else ''} | {ok.sum()} | "
                  f"{100 * np.median(rn):.2f} % | {100 * np.median(bn):.2f} % | "
                  f"{100 * eu.max():.2f} % / {100 * np.median(eu):.2f} % | "
                  f"{100 * er.max():.2f} % / {100 * np.median(er):.2f} % |")
    print()
    for k in (1, 2):
        fu, fr = np.median(res["far", k][0]), np.median(res["far", k][1])
        print(f"- {k} bounce(s): worst contact / median far: uniform "
              f"{res['contact', k][0].max() / fu:.1f}x, refined "
              f"{res['contact', k][1].max() / fr:.1f}x (target <= 3x)")
    print("\n" + machine().split(", load")[1].join(["end: load", ""]))


if __name__ == "__main__":
    main()
