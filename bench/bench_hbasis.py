"""Benchmark: H6 evaluation and SH → H6 conversion vs SH9 evaluation, 10⁶ normals.

Run: PYTHONPATH=src python bench/bench_hbasis.py [--n 1000000] [--repeat 5]
Prints a markdown table (best of ``repeat`` wall-clock times, one thread as numpy runs it).
Peers measured in the same run: shprobe.sh.sh_basis(lmax=2) (the issue's yardstick) and, if
installed, sphericart's real SH up to l = 2.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from shprobe.hbasis import h_basis, sh_to_h
from shprobe.hbasis.study import run_study
from shprobe.sh import sh_basis


def best(fn, repeat: int) -> float:
    fn()  # warm-up (numba compile, caches)
    t = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        t.append(time.perf_counter() - t0)
    return min(t)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--study", type=int, default=10000, help="signals for the study timing")
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    d64 = rng.normal(size=(a.n, 3))
    d64 /= np.linalg.norm(d64, axis=1, keepdims=True)
    d32 = d64.astype(np.float32)
    s64 = rng.normal(size=(a.n, 9, 3))
    s32 = s64.astype(np.float32)
    rows = [
        ("SH9 eval: shprobe.sh.sh_basis(lmax=2), float64 (peer)", lambda: sh_basis(d64, 2)),
        ("SH9 eval: shprobe.sh.sh_basis(lmax=2), float32 (peer)", lambda: sh_basis(d32, 2)),
        ("H6 eval: h_basis(n=6), float64", lambda: h_basis(d64, 6)),
        ("H6 eval: h_basis(n=6), float32", lambda: h_basis(d32, 6)),
        ("H4 eval: h_basis(n=4), float64", lambda: h_basis(d64, 4)),
        ("SH→H6: sh_to_h, (N, 9, 3) float64", lambda: sh_to_h(s64)),
        ("SH→H6: sh_to_h, (N, 9, 3) float32", lambda: sh_to_h(s32)),
    ]
    try:
        import sphericart

        calc = sphericart.SphericalHarmonics(2)
        rows.insert(2, ("SH9 eval: sphericart l≤2, float64 (peer)", lambda: calc.compute(d64)))
    except ImportError:
        pass
    print(f"N = {a.n} normals / SH sets, best of {a.repeat}; {platform.machine()}, "
          f"Python {platform.python_version()}, numpy {np.__version__}\n")
    print("| operation | time (ms) | M items/s |")
    print("| --- | ---: | ---: |")
    for name, fn in rows:
        t = best(fn, a.repeat)
        print(f"| {name} | {1e3 * t:.1f} | {a.n / t / 1e6:.1f} |")
    t0 = time.perf_counter()
    run_study(a.study, seed=0)
    print(f"\nFig. 3 study, {a.study} signals (cold, includes matrix set-up): "
          f"{time.perf_counter() - t0:.2f} s")


if __name__ == "__main__":
    main()
