"""Issue 17: is `shprobe error`'s max the worst case, and what does finding it cost?

    PYTHONPATH=src python bench/bench_error_max.py [--part accuracy|runtime|all]
        [--grid 512] [--repeat 5] [--before f742d8c^1] [--previous f742d8c]

accuracy: per probe, the refined max (default settings) against the sample max over lat-long
grids of N = 32 … 512 rows (2N×N pixel-centre normals, brute-force E by
:func:`reference_irradiance` at every one: ~1.7e10 pair operations per probe at 512), and
against the max over 301×301 brute-force patches (spacing 1e-4 rad) around the refined normal
and around the 512-grid's worst normal. The 512 grid is also evaluated by the report's own
exact E (row prefix sums) to show the two sums agree there (max |difference|).

runtime: the library call ``error_report(env)`` and the command ``shprobe error PROBE -F json``
of three source trees, interleaved at the process level (each library sample: a fresh process,
one warm-up call, then timed calls): ``before`` = the tree before issue 17 (grid-only max,
"today's"), ``previous`` = the first refined version (issue 17, last session), ``after`` = this
tree. The trees are exported by ``git archive`` into a temporary folder.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _machine import machine

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
DATA = os.environ.get("SHPROBE_TEST_DATA", os.path.join(ROOT, "..", "shared"))
PROBES = ("grace", "ennis")

_ONE = """
import json, sys, time
from shprobe.probes.env import load_env
from shprobe.lighting.reference import error_report
env = load_env(sys.argv[1])
error_report(env)
ts = []
for _ in range(int(sys.argv[2])):
    t = time.perf_counter(); error_report(env); ts.append(time.perf_counter() - t)
print(json.dumps(ts))
"""


def accuracy(grid: int) -> None:
    from shprobe.lighting.irradiance import irradiance
    from shprobe.lighting.projection import project, total_intensity
    from shprobe.lighting.reference import (
        _Exact,
        _normal_grid,
        error_report,
        reference_irradiance,
    )
    from shprobe.lighting.sphere_search import tangent_patch
    from shprobe.probes.env import load_env

    def frac(coeffs, lm, n, ref, tot):
        return (np.abs(irradiance(coeffs[: (lm + 1) ** 2], n) - ref) / tot).max(-1)

    def patch(centre):  # 301×301 normals, spacing 1e-4 rad
        return tangent_patch(centre, 0.015, 301)

    sizes = (32, 64, 128, 256, grid)
    for name in PROBES:
        env = load_env(os.path.join(DATA, "probes", f"{name}.hdr"))
        coeffs = project(env, 4)
        tot = total_intensity(env)
        rep = error_report(env)
        t0 = time.perf_counter()
        gmax: dict[int, dict[int, float]] = {}
        at: dict[int, np.ndarray] = {}
        for n in sizes:
            nrm, _ = _normal_grid(n)
            ref = reference_irradiance(env, nrm)
            gmax[n] = {}
            for r in rep.rows:
                f = frac(coeffs, r.lmax, nrm, ref, tot)
                gmax[n][r.lmax] = float(f.max())
                if n == grid:
                    at[r.lmax] = nrm[int(np.argmax(f))]
            if n == grid:
                diff = float(np.abs(_Exact(env)(nrm) - ref).max() / tot.max())
        tg = time.perf_counter() - t0
        print(f"\n### {name}  (brute-force grids 32..{grid}: {tg:.0f} s; report's exact E vs "
              f"brute force on the {grid} grid: max |diff| {diff:.1e} of ∫L)\n")
        print(f"| lmax | grid 32 | 64 | 128 | 256 | {grid} | refined (tol) | refined − {grid} |"
              " patch | refined − patch | at normal |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for r in rep.rows:
            g = [100 * gmax[n][r.lmax] for n in sizes]
            pm = max(float(frac(coeffs, r.lmax, p, reference_irradiance(env, p), tot).max())
                     for p in (patch(r.max_normal), patch(at[r.lmax])))
            nn = ", ".join(f"{x:+.4f}" for x in r.max_normal)
            print(f"| {r.lmax} | " + " | ".join(f"{x:.4f} %" for x in g)
                  + f" | {100 * r.max_frac:.4f} % (±{100 * r.max_tol:.4f}) | "
                    f"{100 * (r.max_frac - gmax[grid][r.lmax]):+.4f} pp | {100 * pm:.4f} % | "
                    f"{100 * (r.max_frac - pm):+.4f} pp | ({nn}) |", flush=True)


def _export(commit: str, into: str) -> str:
    os.makedirs(into, exist_ok=True)
    arc = subprocess.run(["git", "-C", ROOT, "archive", commit, "src"], check=True,
                         capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", into], input=arc, check=True)
    return os.path.join(into, "src")


def runtime(repeat: int, trees: dict[str, str]) -> None:
    py = sys.executable
    lib: dict[tuple[str, str], list[float]] = {}
    cmd: dict[tuple[str, str], list[float]] = {}

    def env_for(src):
        return {**os.environ, "PYTHONPATH": src}

    for src in trees.values():  # compile and cache every tree's kernels first
        for name in PROBES:
            probe = os.path.join(DATA, "probes", f"{name}.hdr")
            subprocess.run([py, "-c", _ONE, probe, "1"], env=env_for(src), check=True,
                           capture_output=True)
    for _ in range(repeat):
        for name in PROBES:
            probe = os.path.join(DATA, "probes", f"{name}.hdr")
            for label, src in trees.items():
                out = subprocess.run([py, "-c", _ONE, probe, "2"], env=env_for(src),
                                     check=True, capture_output=True, text=True).stdout
                lib.setdefault((name, label), []).extend(json.loads(out))
                t0 = time.perf_counter()
                subprocess.run([py, "-m", "shprobe", "error", probe, "-F", "json"],
                               env=env_for(src), check=True, capture_output=True)
                cmd.setdefault((name, label), []).append(time.perf_counter() - t0)
    print("\n| probe | tree | error_report(env) best / median s | × before (median) | "
          "shprobe error -F json best / median s | × before (median) |")
    print("|---|---|---|---|---|---|")
    for name in PROBES:
        b_lib = statistics.median(lib[(name, "before")])
        b_cmd = statistics.median(cmd[(name, "before")])
        for label in trees:
            a, c = lib[(name, label)], cmd[(name, label)]
            print(f"| {name} | {label} | {min(a):.3f} / {statistics.median(a):.3f} | "
                  f"{statistics.median(a) / b_lib:.2f} | {min(c):.2f} / "
                  f"{statistics.median(c):.2f} | {statistics.median(c) / b_cmd:.2f} |")
    print(f"\n({2 * repeat} library calls and {repeat} commands per probe and tree)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--part", choices=("accuracy", "runtime", "all"), default="all")
    ap.add_argument("--grid", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--before", default="f742d8c^1",
                    help="commit of the grid-only report (before issue 17)")
    ap.add_argument("--previous", default="f742d8c",
                    help="commit of the first refined report (empty: skip)")
    a = ap.parse_args()
    print(machine())
    if a.part in ("accuracy", "all"):
        accuracy(a.grid)
    if a.part in ("runtime", "all"):
        with tempfile.TemporaryDirectory(prefix="shprobe-bench-") as tmp:
            trees = {"before": _export(a.before, os.path.join(tmp, "before"))}
            if a.previous:
                trees["previous"] = _export(a.previous, os.path.join(tmp, "previous"))
            trees["after"] = os.path.join(ROOT, "src")
            print(f"\ntrees: before = {a.before}, previous = {a.previous or '-'}, after = "
                  "this checkout")
            runtime(a.repeat, trees)
    load = os.getloadavg()
    print(f"\nend: load average {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} (1 / 5 / 15 min)")


if __name__ == "__main__":
    main()
