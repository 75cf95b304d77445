"""shprobe's lightmap bake against Blender Cycles' bake of the same scene into the same atlas:
the time each needs to reach the same RMS error against its own converged bake.

The game scene (``courtyard.glb``) under a constant white sky (radiance 1) with one diffuse
bounce, plain lightmap (irradiance at the surface normal, no normal map), both on 2 threads:

1. shprobe bakes it (``bake_lightmap``, basis plain) at a reference sample count and at a
   ladder of counts, each timed; the reference is written as a .glb, so its TEXCOORD_1 is
   the atlas both bakes fill.
2. Cycles (``bpy`` on PyPI, run by ``lightmap_cycles_worker.py`` under ``--bpy-python``: it
   pins numpy < 2, so it lives in its own virtual environment) imports that .glb, turns every
   material into a Diffuse BSDF of its base colour and bakes the DIFFUSE pass (direct +
   indirect, no colour = E / π) at its own ladder, each bake timed (BVH and set-up included,
   as in shprobe's bake).
3. Errors: relative RMS over the chart interiors (texels both tools baked whose four
   neighbours both baked too: Blender's bake leaves a chart's border texels empty at margin
   0, and samples a texel where its rasteriser puts it), each ladder step against the same
   tool's reference, corrected for the reference's own noise (independent Monte-Carlo noise:
   RMS² = measured² · R / (R + s)); the two references against each other give the
   difference of the two estimators (bias, not noise). Time to reach a target RMS is
   interpolated on log–log axes (noise ∝ 1/√samples).

    SHPROBE_TEST_DATA=../shared PYTHONPATH=src python bench/bench_lightmap_cycles.py \\
        --bpy-python /tmp/bpyenv/bin/python
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from _machine import machine
from shprobe.lightmaps import LightmapSettings, bake_lightmap, load_scene
from shprobe.lightmaps.scenes import game_scene_path

WORKER = Path(__file__).resolve().with_name("lightmap_cycles_worker.py")


def _sky(radiance: float = 1.0) -> np.ndarray:
    c = np.zeros((9, 3))
    c[0] = radiance * 2.0 * math.sqrt(math.pi)  # L00 · Y00 = radiance
    return c


def _rel_rms(x: np.ndarray, ref: np.ndarray) -> float:
    return float(np.sqrt(np.mean((x - ref) ** 2)) / np.sqrt(np.mean(ref ** 2)))


def _time_to(target: float, pts: list[tuple[float, float]]) -> float | None:
    """Seconds at which the (seconds, rms) ladder reaches ``target`` (log–log interpolation;
    extrapolated one step at most, by the 1/√time law)."""
    pts = sorted(pts)
    for (t0, e0), (t1, e1) in itertools.pairwise(pts):
        if e0 >= target >= e1 and e0 > e1:
            f = math.log(e0 / target) / math.log(e0 / e1)
            return math.exp(math.log(t0) + f * math.log(t1 / t0))
    t, e = pts[-1]
    if e > target:
        return t * (e / target) ** 2 if e < 2 * target else None
    t, e = pts[0]
    return t * (e / target) ** 2


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bpy-python", required=True, help="a Python with bpy 4.5 installed")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--bounces", type=int, default=1)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ref", type=int, default=1024, help="reference samples (both tools)")
    ap.add_argument("--ours", default="16,32,64,128,256")
    ap.add_argument("--cycles", default="4,16,64,256")
    ap.add_argument("--targets", default="0.05,0.02,0.01")
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args()
    os.environ.setdefault("NUMBA_NUM_THREADS", str(a.threads))
    print(machine())
    scene = load_scene(game_scene_path())
    sky = _sky()
    ours_ladder = [int(s) for s in a.ours.split(",")]
    cyc_ladder = [int(s) for s in a.cycles.split(",")]
    res: dict = {"size": a.size, "bounces": a.bounces, "threads": a.threads, "ref": a.ref}

    def bake(samples: int):
        t = time.perf_counter()
        lm = bake_lightmap(scene, sky, LightmapSettings(basis="plain", size=a.size,
                                                        samples=samples, bounces=a.bounces))
        return lm, time.perf_counter() - t

    bake(16)  # numba's compilation and the caches, outside the timings
    ref, t_ref = bake(a.ref)
    print(f"shprobe reference: {a.ref} samples, {int(ref.valid.sum())} texels, {t_ref:.1f} s")
    runs = [(s, *bake(s)) for s in ours_ladder]
    with tempfile.TemporaryDirectory() as d:
        glb = Path(d) / "courtyard_plain.glb"
        ref.save(glb)
        job = {"glb": str(glb), "width": ref.width, "height": ref.height,
               "samples": [*cyc_ladder, a.ref], "bounces": a.bounces, "threads": a.threads,
               "out": d}
        (Path(d) / "job.json").write_text(json.dumps(job))
        subprocess.run([a.bpy_python, str(WORKER), str(Path(d) / "job.json")], check=True)
        secs = json.loads((Path(d) / "cycles.json").read_text())
        c_full = np.load(Path(d) / f"cycles_{a.ref}.npy")
        both = ref.valid & (c_full.sum(axis=2) > 0)
        valid = both.copy()
        valid[1:] &= both[:-1]
        valid[:-1] &= both[1:]
        valid[:, 1:] &= both[:, :-1]
        valid[:, :-1] &= both[:, 1:]
        print(f"chart interiors compared: {int(valid.sum())} of {int(ref.valid.sum())} texels")
        e_ref = ref.coefficients("plain")[..., 0, :][valid]
        ours = []
        for s, lm, t in runs:
            meas = _rel_rms(lm.coefficients("plain")[..., 0, :][valid], e_ref)
            ours.append((t, meas * math.sqrt(a.ref / (a.ref + s)), s))
            print(f"shprobe {s:5d} samples: {t:7.2f} s, rel. RMS {ours[-1][1]:.4f}")
        c_ref = c_full[valid] * math.pi  # E / π → E
        cyc = []
        for s in cyc_ladder:
            c = np.load(Path(d) / f"cycles_{s}.npy")[valid] * math.pi
            meas = _rel_rms(c, c_ref)
            cyc.append((secs[str(s)], meas * math.sqrt(a.ref / (a.ref + s)), s))
            print(f"Cycles  {s:5d} samples: {cyc[-1][0]:7.2f} s, rel. RMS {cyc[-1][1]:.4f}")
    bias = _rel_rms(c_ref, e_ref)
    ratio = float(np.median(c_ref.mean(axis=1) / np.maximum(e_ref.mean(axis=1), 1e-9)))
    print(f"references: Cycles {secs[str(a.ref)]:.1f} s; shprobe vs Cycles rel. RMS "
          f"{bias:.4f}, median ratio Cycles/shprobe {ratio:.3f}")
    res.update(texels=int(valid.sum()), ours=ours, cycles=cyc,
               ref_seconds={"shprobe": t_ref, "cycles": secs[str(a.ref)]},
               references_rel_rms=bias, references_median_ratio=ratio, machine=machine())
    res["time_to"] = {}
    for tgt in (float(x) for x in a.targets.split(",")):
        to = _time_to(tgt, [(t, e) for t, e, _ in ours])
        tc = _time_to(tgt, [(t, e) for t, e, _ in cyc])
        res["time_to"][str(tgt)] = {"shprobe": to, "cycles": tc}
        fmt = lambda v: "—" if v is None else f"{v:.2f} s"  # noqa: E731
        print(f"time to rel. RMS {tgt:.3f}: shprobe {fmt(to)}, Cycles {fmt(tc)}")
    if a.json:
        a.json.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
