"""Benchmark: H6 evaluation and SH → H6 conversion against SH9 evaluation, 10⁶ items.

Run: ``PYTHONPATH=src python bench/bench_hbasis.py [--n 1000000] [--repeat 9]``.

The issue's target: evaluating H6 for 10⁶ normals and converting 10⁶ SH sets to H6 each at
least as fast as evaluating SH9 (``shprobe.sh.sh_basis(lmax=2)``) for the same normals. Like is
compared with like in one run: every shprobe call writes into a preallocated ``out=`` array
(so page-faulting a fresh output is not timed), one thread (the thread variables are set
before numpy/numba are imported), and each figure is the best of ``--repeat`` runs of
**process CPU time** (the machine is shared; on an idle machine this equals wall time).
Reported per item: ns, and the bytes each call must read and write (all four kernels are
memory-bound, so bytes moved decide the ranking). Peer in the same run, when installed:
sphericart's real SH up to l = 2 (preallocated, through ``_compute_numpy``). Prints markdown.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from _machine import machine  # noqa: E402


def best(fn, repeat: int) -> float:
    """Best process-CPU seconds of one call over ``repeat`` runs (after a warm-up call)."""
    fn()  # warm-up: numba compile / cache load
    t_best = np.inf
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        t_best = min(t_best, time.process_time() - t0)
    return t_best


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=9)
    ap.add_argument("--study", type=int, default=10000, help="signals for the study timing")
    a = ap.parse_args()

    from shprobe.hbasis import h_basis, sh_to_h, sh_to_h_matrix
    from shprobe.hbasis.study import run_study
    from shprobe.sh import sh_basis

    n = a.n
    rng = np.random.default_rng(0)
    d64 = rng.normal(size=(n, 3))
    d64 /= np.linalg.norm(d64, axis=1, keepdims=True)
    rows = []  # (label, seconds, bytes per item, is_target)
    for dt in (np.float64, np.float32):
        name = np.dtype(dt).name
        b = np.dtype(dt).itemsize
        d = d64.astype(dt)
        o9, o6 = np.empty((n, 9), dt), np.empty((n, 6), dt)
        s1, s3 = rng.normal(size=(n, 9, 1)).astype(dt), rng.normal(size=(n, 9, 3)).astype(dt)
        h1, h3 = np.empty((n, 6, 1), dt), np.empty((n, 6, 3), dt)
        # correctness of what is timed (one pass each)
        tol = 1e-12 if dt == np.float64 else 2e-6
        assert np.allclose(sh_to_h(s3, out=h3), np.einsum("ij,njc->nic", sh_to_h_matrix(), s3),
                           atol=tol * 10)
        x, y, z = (d64[:5000, i] for i in range(3))
        c3, c5 = np.sqrt(3 / (2 * np.pi)), np.sqrt(15 / (2 * np.pi))
        want = np.stack([np.full_like(x, 1 / np.sqrt(2 * np.pi)), -c3 * y, c3 * (2 * z - 1),
                         -c3 * x, c5 * x * y, 0.5 * c5 * (x * x - y * y)], -1)
        assert np.allclose(h_basis(d[:5000], out=o6[:5000]), want, atol=tol * 10)
        rows.append((f"SH9 eval `sh_basis(d, 2, out=)` (yardstick), {name}",
                     best(lambda d=d, o9=o9: sh_basis(d, 2, out=o9), a.repeat), 3 * b + 9 * b,
                     False))
        rows.append((f"H6 eval `h_basis(d, 6, out=)`, {name}",
                     best(lambda d=d, o6=o6: h_basis(d, 6, out=o6), a.repeat), 3 * b + 6 * b,
                     True))
        rows.append((f"SH→H6 `sh_to_h(s, out=)`, one channel (N, 9, 1), {name}",
                     best(lambda s1=s1, h1=h1: sh_to_h(s1, out=h1), a.repeat), 9 * b + 6 * b,
                     True))
        rows.append((f"SH→H6 `sh_to_h(s, out=)`, RGB (N, 9, 3), {name}",
                     best(lambda s3=s3, h3=h3: sh_to_h(s3, out=h3), a.repeat), 27 * b + 18 * b,
                     True))
        if dt == np.float64:
            rows.append(("SH→H6 `sh_to_h(s)`, RGB, allocating the output, float64",
                         best(lambda s3=s3: sh_to_h(s3), a.repeat), 45 * b, False))
            dst = np.empty_like(s3)
            rows.append(("plain copy of the RGB SH input (N, 9, 3) into a preallocated array, "
                         "float64 (floor)",
                         best(lambda s3=s3, dst=dst: np.copyto(dst, s3), a.repeat), 54 * b,
                         False))
            try:
                import sphericart

                calc = sphericart.SphericalHarmonics(2)
                osc = np.empty((n, 9))
                rows.append(("SH9 eval, sphericart l ≤ 2, preallocated (peer), float64",
                             best(lambda c=calc, d=d, o=osc: c._compute_numpy(d, o, None, None),
                                  a.repeat),
                             12 * b, False))
            except ImportError:
                rows.append(("SH9 eval, sphericart (peer): not installed", float("nan"), 0,
                             False))
    print(f"N = {n} normals / SH sets; best of {a.repeat} runs of process CPU time, one thread.")
    print(f"Machine: {machine()}\n")
    print("| operation | ms | ns / item | bytes read+written / item | × SH9 eval (same type) |")
    print("| --- | ---: | ---: | ---: | ---: |")
    ref = {}
    for label, t, nbytes, _ in rows:
        key = "float32" if "float32" in label else "float64"
        if label.startswith("SH9 eval `sh_basis"):
            ref[key] = t
        ratio = t / ref[key] if key in ref and np.isfinite(t) else float("nan")
        print(f"| {label} | {1e3 * t:.2f} | {1e9 * t / n:.2f} | {nbytes} | {ratio:.2f} |")
    t0 = time.process_time()
    run_study(a.study, seed=0)
    print(f"\nFig. 3 study, {a.study} signals (cold, includes matrix set-up), CPU time: "
          f"{time.process_time() - t0:.2f} s")


if __name__ == "__main__":
    main()
