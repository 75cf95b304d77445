"""PRT bake memory: the estimate the bake announces (and its memory check refuses on) against
the peak resident memory the bake reaches, on the packaged bunny + ground, one subprocess per
bake (its peak RSS: ``VmHWM`` of /proc/self/status, which unlike ``ru_maxrss`` does not
inherit the peak of the process that started it).

Run: PYTHONPATH=src python bench/bench_prt_memory.py [--lmax 2 6 10 16]
     [--modes unshadowed shadowed interreflected] [--samples 1024] [--threads 2]
Prints one markdown row per bake: estimate, peak, peak/estimate, vertices (estimated and
final) and the bake's seconds; exits 1 when an estimate is off by more than ``--tol``
(default 20 %) of the peak. ``tests/prt/test_prt_memory.py`` runs the cheap cases.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

#: One bake in a fresh process: what it announced, what it reached.
CHILD = r"""
import json, resource, sys, time
from shprobe.prt import PrtSettings, bake, estimate_bake, load_scene
from shprobe.scene.mesh import bunny_path
mode, lmax, samples, threads = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
s = PrtSettings(mode=mode, lmax=lmax, samples=samples, threads=threads)
sc = load_scene([str(bunny_path())], ground=True)
# the CLI's own choice: a traced bake that adds the ground refines (QUICK)
s = s.but(refine=s.refinement(True) or False)
est = estimate_bake(sc, s)
t0 = time.perf_counter()
t = bake(sc, s)
secs = time.perf_counter() - t0
try:  # this process's own high-water mark (ru_maxrss would keep the forking parent's)
    peak = next(int(l.split()[1]) * 1024 for l in open("/proc/self/status")
                if l.startswith("VmHWM:"))
except (OSError, StopIteration):
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps({"estimate": est.nbytes, "est_seconds": est.seconds,
                  "est_vertices": est.vertices, "vertices": t.n_vertices, "peak": peak,
                  "seconds": secs}))
"""


#: A small bake of the same kind first, in its own process: shprobe's mesh cache then holds the
#: bunny and numba's on-disk cache the bake's kernels. The first read of a mesh file (trimesh's
#: parse) and a kernel's first compilation are one-off transients (together up to ~0.4 GB)
#: that a user's second bake does not repeat and that the estimate does not count.
WARM = r"""
import sys
from shprobe.prt import PrtSettings, bake, load_scene
from shprobe.scene.mesh import bunny_path
mode, lmax, threads = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
s = PrtSettings(mode=mode, lmax=lmax, samples=64, threads=threads)
bake(load_scene([str(bunny_path())], ground=True), s.but(refine=False))
"""


def measure(mode: str, lmax: int, samples: int = 1024, threads: int = 2) -> dict:
    """Run one bake in a subprocess (the mesh cache warmed first); its estimate and peak RSS
    (bytes) and more."""
    subprocess.run([sys.executable, "-c", WARM, mode, str(lmax), str(threads)],
                   capture_output=True, check=True)
    r = subprocess.run([sys.executable, "-c", CHILD, mode, str(lmax), str(samples),
                        str(threads)], capture_output=True, text=True, check=True)
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lmax", type=int, nargs="+", default=[2, 6, 10, 16])
    ap.add_argument("--modes", nargs="+", default=["unshadowed", "shadowed", "interreflected"])
    ap.add_argument("--samples", type=int, default=1024)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--tol", type=float, default=0.2)
    a = ap.parse_args()
    sys.path.insert(0, __file__.rsplit("/", 1)[0])
    from _machine import machine

    print(f"machine: {machine()}; bunny + ground, {a.samples} samples, {a.threads} threads\n")
    print("| mode | lmax | estimate | peak RSS | estimate/peak | vertices (est. / final) "
          "| bake s (est. / measured) |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    bad = 0
    for mode in a.modes:
        for lmax in a.lmax:
            t0 = time.perf_counter()
            m = measure(mode, lmax, a.samples, a.threads)
            ratio = m["estimate"] / m["peak"]
            bad += abs(ratio - 1) > a.tol
            print(f"| {mode} | {lmax} | {m['estimate'] / 1e9:.3f} GB | {m['peak'] / 1e9:.3f} GB "
                  f"| {ratio:.2f} | {m['est_vertices']:,} / {m['vertices']:,} "
                  f"| {m['est_seconds']:.0f} / {m['seconds']:.0f} |", flush=True)
            del t0
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
