"""Benchmark: SH basis and rotation against their peers (issue: foundation).

Run: ``python bench/bench_sh.py`` (``PYTHONPATH=src`` when shprobe is not installed;
``--cores``: ``sh_basis`` against sphericart on all the cores, both libraries threaded, wall
time, lmax 2, 6, 10, 20, 10⁶ directions, float64 and float32, ``out=`` and allocating;
``--grid``: the lmax 2–32 grid against sphericart only; ``--sweep``: ``out=`` ratios at
lmax 9–30 (the kernel's switch points); ``--alloc-pairs [--pairs N]``: the allocating calls
paired (31 pairs), with an interval; ``--lmax 9-32`` or ``--lmax 10,16``: the degrees of
``--sweep`` and ``--alloc-pairs``). Prints markdown tables; one thread everywhere. Peers:
sphericart (preallocated output, through its ``_compute_numpy`` so no allocation is timed),
scipy.special.sph_harm_y, pyshtools SHRotateRealCoef, ducc0.sht.rotate_alm, e3nn.o3.wigner_D
(when torch/e3nn are installed).
Timings are the best of several repeats of process CPU time (the machine is shared).
"""

from __future__ import annotations

import os
import sys

_CORES = len(os.sched_getaffinity(0))
for _v in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    # --cores: every library on all the cores this process may use (sphericart's OpenMP
    # threads, shprobe's one thread per core); otherwise one thread everywhere
    os.environ[_v] = str(_CORES) if "--cores" in sys.argv else "1"
if "--cores" not in sys.argv:  # shprobe's threads follow the cores the process may use
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})

import subprocess  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from _machine import machine  # noqa: E402


def best(f, number=1, repeat=7):
    """Best CPU seconds per call over ``repeat`` runs of ``number`` calls.

    Process CPU time (everything runs on one thread), so that other work on the shared
    machine pre-empting us is not counted; on an idle machine it equals wall time.
    """
    f()
    t_best = np.inf
    for _ in range(repeat):
        t = time.process_time()
        for _ in range(number):
            f()
        t_best = min(t_best, (time.process_time() - t) / number)
    return t_best


def unit_dirs(n, seed=0):
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def bench_basis(rows):
    import sphericart

    from shprobe.sh import sh_basis, sh_basis_numpy, sh_basis_scipy

    n, lmax = 10**6, 6
    d = unit_dirs(n)
    out = np.empty((n, (lmax + 1) ** 2))
    t_ours = best(lambda: sh_basis(d, lmax, out=out))
    t_alloc = best(lambda: sh_basis(d, lmax), repeat=3)
    calc = sphericart.SphericalHarmonics(lmax)
    o2 = np.empty_like(out)
    t_sc = best(lambda: calc._compute_numpy(d, o2, None, None))
    t_ours2 = best(lambda: sh_basis(d, lmax, out=out))  # again, to see the load drift
    t_ours = min(t_ours, t_ours2)
    assert np.allclose(np.abs(out), np.abs(o2), atol=1e-12)  # same functions up to sign
    t_np = best(lambda: sh_basis_numpy(d, lmax), repeat=3)
    t_scipy = best(lambda: sh_basis_scipy(d, lmax), repeat=1)
    f32 = d.astype(np.float32)
    out32 = np.empty(out.shape, np.float32)
    t_32 = best(lambda: sh_basis(f32, lmax, out=out32))
    ns = 1e9 / n
    rows.append(("shprobe `sh_basis`, preallocated `out=`", t_ours * ns, 1.0))
    rows.append(("shprobe `sh_basis`, allocating", t_alloc * ns, t_alloc / t_ours))
    rows.append(("shprobe `sh_basis`, float32, preallocated", t_32 * ns, t_32 / t_ours))
    rows.append(("sphericart 2.x `SphericalHarmonics`, preallocated", t_sc * ns, t_sc / t_ours))
    rows.append(("shprobe `sh_basis_numpy` (reference)", t_np * ns, t_np / t_ours))
    rows.append(("scipy `sph_harm_y` + complex→real", t_scipy * ns, t_scipy / t_ours))


def _timed(f):
    """(process CPU seconds, of them system seconds, minor page faults) of one call."""
    import resource

    r0 = resource.getrusage(resource.RUSAGE_SELF)
    t = time.process_time()
    f()
    t = time.process_time() - t
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    return t, r1.ru_stime - r0.ru_stime, r1.ru_minflt - r0.ru_minflt


def f32_error(fn, d32, lmax):
    """Largest |y₃₂ − y₆₄| over the band's scale √((2l+1)/4π), in float32 epsilons, against
    shprobe's float64 values on the same (rounded) directions; nan counts as infinite."""
    from shprobe.sh import sh_basis

    y64 = sh_basis(d32.astype(np.float64), lmax)
    l = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
    err = np.abs(fn(d32).astype(np.float64) - y64) / np.sqrt((2 * l + 1) / (4 * np.pi))
    err = np.where(np.isfinite(err), err, np.inf)
    return err.max() / np.finfo(np.float32).eps


def grid_inputs(lmaxes, budget):
    """(lmax, directions n, dtype, directions (n, 3) of it, a sphericart calculator) of the
    grid: 10⁶ directions, fewer where the float64 output would pass ``budget`` bytes."""
    import sphericart

    for lmax in lmaxes:
        n = min(10**6, budget // (8 * (lmax + 1) ** 2))
        d64 = unit_dirs(n)
        for dt in (np.float64, np.float32):
            yield lmax, n, dt, d64.astype(dt), sphericart.SphericalHarmonics(lmax)


def bench_basis_grid(rows, lmaxes=(2, 6, 10, 16, 20, 32), repeat=9, budget=1 << 30):
    """shprobe and sphericart, output preallocated and allocated by the call, float64 and
    float32, in the same run, 10⁶ directions, fewer where the output would pass ``budget``
    bytes (the box is shared); best and median per call.

    The two preallocated calls are interleaved, in alternating order. The two allocating
    calls are interleaved among themselves in alternating order (o s | s o | o s …), so that
    each follows the freeing of the other's gigabyte as often as its own: how fast a fresh
    array's pages come back depends on what was freed just before (the kernel hands back
    the huge pages just freed at once; pages free for longer may have been returned to the
    hypervisor, or need compacting) — an order in which one call always ran right after an
    allocating call and the other only half the time favoured the first."""
    from shprobe.sh import sh_basis

    for lmax, n, dt, d, calc in grid_inputs(lmaxes, budget):
        out = np.empty((n, (lmax + 1) ** 2), dt)
        out.fill(0)  # pages touched once, as a reused buffer is
        groups = (
            {"ours_out": lambda d=d, out=out, lmax=lmax: sh_basis(d, lmax, out=out),
             "sc_out": lambda d=d, out=out, calc=calc: calc._compute_numpy(d, out, None,
                                                                          None)},
            {"ours_alloc": lambda d=d, lmax=lmax: sh_basis(d, lmax),
             "sc_alloc": lambda d=d, calc=calc: calc.compute(d)},
        )
        t, sys_t, flt = {}, {}, {}
        for calls in groups:
            for f in calls.values():
                f()
            order = list(calls)
            for k in calls:
                t[k], sys_t[k], flt[k] = [], [], []
            for r in range(repeat):
                for k in order if r % 2 == 0 else order[::-1]:
                    cpu, sy, fl = _timed(calls[k])
                    t[k].append(cpu * 1e9 / n)
                    sys_t[k].append(sy * 1e3)
                    flt[k].append(fl)
        del out
        e_ours = e_sc = float("nan")
        if dt == np.float32:
            few = d[:2000]
            e_ours = f32_error(lambda x, lmax=lmax: sh_basis(x, lmax), few, lmax)
            e_sc = f32_error(calc.compute, few, lmax)
        rows.append((lmax, np.dtype(dt).name, n,
                     {k: (min(v), float(np.median(v))) for k, v in t.items()},
                     {k: (float(np.median(sys_t[k])), float(np.median(flt[k])))
                      for k in ("ours_alloc", "sc_alloc")}, e_ours, e_sc))


def bench_basis_cores(lmaxes=(2, 6, 10, 20), repeat=11, n=10**6):
    """``sh_basis`` and sphericart on all the cores (both threaded), in one run: 10⁶ random
    unit directions, float64 and float32, into a preallocated ``out`` (touched before, as a
    reused buffer is) and allocating. Wall time (several threads: process CPU time would sum
    them), the calls of a pair interleaved in alternating order; per call the best and the
    median of ``repeat``. Prints a markdown table; × = shprobe / sphericart (best, and median
    in brackets)."""
    import sphericart

    from shprobe.sh import sh_basis

    def wall(f):
        t = time.perf_counter()
        f()
        return time.perf_counter() - t

    print(f"### sh_basis against sphericart, {_CORES} cores each, 10⁶ directions\n")
    print("ms per call, best / median of "
          f"{repeat} interleaved repeats (wall time); × = shprobe / sphericart, best "
          "(median).\n")
    print("| lmax | dtype | shprobe out= | sphericart out | × | shprobe alloc "
          "| sphericart alloc | × |")
    print("| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for lmax in lmaxes:
        d64 = unit_dirs(n)
        calc = sphericart.SphericalHarmonics(lmax)
        for dt in (np.float64, np.float32):
            d = d64.astype(dt)
            few = d[:10000]  # same functions up to sign (sphericart's in float64: its float32
            # loses digits at high degree)
            assert np.abs(np.abs(sh_basis(few, lmax)) - np.abs(
                calc.compute(few.astype(np.float64)))).max() < (
                1e-10 if dt == np.float64 else 1e-4)
            out = np.zeros((n, (lmax + 1) ** 2), dt)
            groups = (
                {"ours_out": lambda d=d, out=out, lmax=lmax: sh_basis(d, lmax, out=out),
                 "sc_out": lambda d=d, out=out, calc=calc: calc._compute_numpy(d, out, None,
                                                                              None)},
                {"ours_alloc": lambda d=d, lmax=lmax: sh_basis(d, lmax),
                 "sc_alloc": lambda d=d, calc=calc: calc.compute(d)},
            )
            t = {}
            for calls in groups:
                for f in calls.values():
                    f()
                order = list(calls)
                for k in calls:
                    t[k] = []
                for r in range(repeat):
                    for k in order if r % 2 == 0 else order[::-1]:
                        t[k].append(wall(calls[k]) * 1e3)
            del out
            b = {k: min(v) for k, v in t.items()}
            m = {k: float(np.median(v)) for k, v in t.items()}
            print(f"| {lmax} | {np.dtype(dt).name} "
                  f"| {b['ours_out']:.1f} / {m['ours_out']:.1f} "
                  f"| {b['sc_out']:.1f} / {m['sc_out']:.1f} "
                  f"| {b['ours_out'] / b['sc_out']:.2f} ({m['ours_out'] / m['sc_out']:.2f}) "
                  f"| {b['ours_alloc']:.1f} / {m['ours_alloc']:.1f} "
                  f"| {b['sc_alloc']:.1f} / {m['sc_alloc']:.1f} "
                  f"| {b['ours_alloc'] / b['sc_alloc']:.2f} "
                  f"({m['ours_alloc'] / m['sc_alloc']:.2f}) |", flush=True)


def bench_alloc_pairs(lmaxes=(2, 6, 10, 16, 20, 32), pairs=31, budget=1 << 30):
    """Issue 16's allocating-path question, paired: shprobe's and sphericart's allocating calls
    run back to back ``pairs`` times in alternating order (as in :func:`bench_basis_grid`);
    per lmax and dtype the median of the per-pair ratios shprobe / sphericart, a bootstrap 95 %
    interval of that median, and in how many pairs shprobe was the cheaper. A ratio whose
    interval holds 1 is a tie within what this machine can resolve."""
    from shprobe.sh import sh_basis

    rng = np.random.default_rng(0)
    print("| lmax | dtype | directions | pairs | median ratio | 95 % interval | shprobe cheaper "
          "| shprobe ns (median) | sphericart ns (median) |")
    print("| ---: | --- | ---: | ---: | ---: | --- | ---: | ---: | ---: |")
    for lmax, n, dt, d, calc in grid_inputs(lmaxes, budget):
        calls = {"ours": lambda d=d, lmax=lmax: sh_basis(d, lmax),
                 "sc": lambda d=d, calc=calc: calc.compute(d)}
        for f in calls.values():
            f()
        t = {k: [] for k in calls}
        for r in range(pairs):
            for k in ("ours", "sc") if r % 2 == 0 else ("sc", "ours"):
                t[k].append(_timed(calls[k])[0] * 1e9 / n)
        ratio = np.array(t["ours"]) / np.array(t["sc"])
        boot = np.median(rng.choice(ratio, (2000, ratio.size)), axis=1)
        lo, hi = np.percentile(boot, [2.5, 97.5])
        print(f"| {lmax} | {np.dtype(dt).name} | {n:,} | {pairs} | {np.median(ratio):.3f} "
              f"| {lo:.3f} – {hi:.3f} | {int((ratio <= 1).sum())} of {pairs} "
              f"| {np.median(t['ours']):.1f} | {np.median(t['sc']):.1f} |", flush=True)


def bench_basis_sweep(lmaxes=(9, 12, 14, 18, 22, 23, 24, 26, 28, 30), repeat=7):
    """shprobe `out=` / sphericart `out`, best times, at every lmax of ``lmaxes`` (the kernel's
    switch points 22–24 included): a 256 MiB output (streamed by shprobe) and a ~1 MiB one
    (in cache), float64 and float32, the two calls interleaved in alternating order."""
    import sphericart

    from shprobe.sh import sh_basis

    table = {}
    for size, dt in ((256 << 20, np.float64), (256 << 20, np.float32), (1 << 20, np.float64),
                     (1 << 20, np.float32)):
        for lmax in lmaxes:
            K = (lmax + 1) ** 2
            n = max(8, size // (np.dtype(dt).itemsize * K)) // 4 * 4
            d = unit_dirs(n).astype(dt)
            out = np.zeros((n, K), dt)
            calc = sphericart.SphericalHarmonics(lmax)
            calls = {"ours": lambda d=d, out=out, lmax=lmax: sh_basis(d, lmax, out=out),
                     "sc": lambda d=d, out=out, calc=calc: calc._compute_numpy(d, out, None,
                                                                              None)}
            reps = max(1, int(5e6 / (n * K)))
            t = {k: [] for k in calls}
            for f in calls.values():
                f()
            for r in range(repeat):
                for k in calls if r % 2 == 0 else list(calls)[::-1]:
                    t0 = time.process_time()
                    for _ in range(reps):
                        calls[k]()
                    t[k].append(time.process_time() - t0)
            table[(size, np.dtype(dt).name, lmax)] = min(t["ours"]) / min(t["sc"])
    print("### sh_basis `out=` / sphericart, every lmax (ratio of best process CPU times, "
          f"{repeat} interleaved repeats)\n")
    print("| output | dtype | " + " | ".join(str(l) for l in lmaxes) + " |")
    print("| --- | --- | " + " | ".join("---:" for _ in lmaxes) + " |")
    for size, dt in ((256 << 20, "float64"), (256 << 20, "float32"), (1 << 20, "float64"),
                     (1 << 20, "float32")):
        print(f"| {size >> 20} MiB | {dt} | "
              + " | ".join(f"{table[(size, dt, l)]:.2f}" for l in lmaxes) + " |")
    print("\nload average at the end: "
          + " / ".join(f"{x:.2f}" for x in os.getloadavg()) + "\n")


def bench_rotation(rows, batch_rows):
    from scipy.spatial.transform import Rotation

    from shprobe.sh.conventions import to_shtools
    from shprobe.sh.rotation import rotate

    lmax = 8
    K = (lmax + 1) ** 2
    rng = np.random.default_rng(1)
    c = rng.normal(size=(K, 3))
    rot = Rotation.random(random_state=2)
    R = rot.as_matrix()
    gamma, beta, alpha = rot.as_euler("ZYZ")
    rotate(c, R)
    t = best(lambda: rotate(c, R), number=2000)
    rows.append(("shprobe `rotate` (build D + apply), RGB", t * 1e6, "1 call, 3 channels"))
    c1 = c[:, :1].copy()
    t1 = best(lambda: rotate(c1, R), number=2000)
    rows.append(("shprobe `rotate`, one channel", t1 * 1e6, ""))

    try:
        import pyshtools

        cilm = to_shtools(c)  # (3, 2, 9, 9)
        ang = np.array([alpha, beta, gamma])
        dj = pyshtools.rotate.djpi2(lmax)
        tp = best(lambda: pyshtools.rotate.SHRotateRealCoef(cilm[0], ang, dj), number=500)
        rows.append(("pyshtools `SHRotateRealCoef`, one channel", tp * 1e6,
                     f"RGB = 3 calls ≈ {3 * tp * 1e6:.1f} µs"))
    except ImportError:
        rows.append(("pyshtools", float("nan"), "not installed"))

    try:
        import ducc0

        nalm = (lmax + 1) * (lmax + 2) // 2
        alm = (rng.normal(size=(3, nalm)) + 1j * rng.normal(size=(3, nalm)))
        alm[:, : lmax + 1] = alm[:, : lmax + 1].real
        td = best(lambda: ducc0.sht.rotate_alm(alm, lmax, alpha, beta, gamma, 1), number=500)
        rows.append(("ducc0 `sht.rotate_alm`, RGB (3 complex a_lm sets)", td * 1e6,
                     "complex a_lm; real↔complex conversion not timed"))
        td1 = best(lambda: ducc0.sht.rotate_alm(alm[0], lmax, alpha, beta, gamma, 1),
                   number=500)
        rows.append(("ducc0 `sht.rotate_alm`, one set", td1 * 1e6, ""))
    except ImportError:
        rows.append(("ducc0", float("nan"), "not installed"))

    try:
        import torch
        from e3nn import o3

        torch.set_num_threads(1)
        a, b, g = (torch.tensor(v, dtype=torch.float64) for v in (alpha, beta, gamma))
        x = [torch.tensor(c[l * l:(l + 1) ** 2], dtype=torch.float64) for l in range(lmax + 1)]

        def e3():
            return [o3.wigner_D(l, a, b, g) @ x[l] for l in range(lmax + 1)]

        te = best(e3, number=5, repeat=3)
        rows.append(("e3nn `o3.wigner_D` for l ≤ 8 + apply, RGB", te * 1e6,
                     f"torch {torch.__version__}"))
    except ImportError:
        rows.append(("e3nn `o3.wigner_D`", float("nan"), "torch/e3nn not installed"))

    # batch of 10,000 rotations at lmax = 2
    n = 10_000
    Rs = Rotation.random(n, random_state=3).as_matrix()
    c2 = rng.normal(size=(9, 3))
    tb = best(lambda: rotate(c2, Rs), repeat=7)
    batch_rows.append(("shprobe `rotate(coeffs (9, 3), R (10000, 3, 3))`", tb / n * 1e6))
    cb = rng.normal(size=(n, 9, 3))
    tb2 = best(lambda: rotate(cb, Rs), repeat=7)
    batch_rows.append(("shprobe `rotate(coeffs (10000, 9, 3), R (10000, 3, 3))`", tb2 / n * 1e6))
    try:
        import ducc0

        eul = Rotation.from_matrix(Rs[:1000]).as_euler("ZYZ")
        alm2 = rng.normal(size=(3, 6)) + 0j

        def ducc_loop():
            for gg, bb, aa in eul:
                ducc0.sht.rotate_alm(alm2, 2, aa, bb, gg, 1)

        tdl = best(ducc_loop, repeat=3)
        batch_rows.append(("ducc0 `rotate_alm` in a Python loop, RGB", tdl / 1000 * 1e6))
    except ImportError:
        pass


def bench_import(rows):
    exe = sys.executable
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([os.path.join(os.path.dirname(__file__), "..", "src"),
                                         env.get("PYTHONPATH", "")])

    def run(code):
        t = time.perf_counter()
        subprocess.run([exe, "-c", code], check=True, env=env)
        return time.perf_counter() - t

    base = min(run("pass") for _ in range(5))
    imp = min(run("import shprobe") for _ in range(5))
    first = min(run("import numpy as np, shprobe; shprobe.sh_basis(np.array([0., 0, 1]), 6)")
                for _ in range(3))
    rot = min(run("import numpy as np, shprobe; shprobe.rotate(np.ones((9, 3)), np.eye(3))")
              for _ in range(3))
    rows.append(("`import shprobe`", (imp - base) * 1e3))
    rows.append(("`import shprobe` + first `sh_basis` (numba cache warm)", (first - base) * 1e3))
    rows.append(("`import shprobe` + first `rotate` (numba cache warm)", (rot - base) * 1e3))


def _lmax_arg(default):
    """The degrees of ``--lmax A-B`` (inclusive) or ``--lmax A,B,…``; ``default`` without it."""
    if "--lmax" not in sys.argv:
        return default
    arg = sys.argv[sys.argv.index("--lmax") + 1]
    if "-" in arg:
        lo, hi = (int(x) for x in arg.split("-"))
        return tuple(range(lo, hi + 1))
    return tuple(int(x) for x in arg.split(","))


def main():
    print(f"Machine: {machine()}\n")
    if "--cores" in sys.argv:
        bench_basis_cores(_lmax_arg((2, 6, 10, 20)))
        print("\nload average at the end: " + " / ".join(f"{x:.2f}" for x in os.getloadavg()))
        return
    if "--alloc-pairs" in sys.argv:
        print("load average at the start: " + " / ".join(f"{x:.2f}" for x in os.getloadavg())
              + "\n")
        pairs = int(sys.argv[sys.argv.index("--pairs") + 1]) if "--pairs" in sys.argv else 31
        bench_alloc_pairs(_lmax_arg((2, 6, 10, 16, 20, 32)), pairs=pairs)
        print("\nload average at the end: " + " / ".join(f"{x:.2f}" for x in os.getloadavg()))
        return
    if "--sweep" in sys.argv:
        print("load average at the start: " + " / ".join(f"{x:.2f}" for x in os.getloadavg())
              + "\n")
        bench_basis_sweep(_lmax_arg((9, 12, 14, 18, 22, 23, 24, 26, 28, 30)))
        return
    grid = []
    print("load average at the start: " + " / ".join(f"{x:.2f}" for x in os.getloadavg())
          + "\n")
    bench_basis_grid(grid)
    print("### sh_basis against sphericart: random unit directions, one thread\n")
    print("ns per direction, best / median of 9 interleaved repeats (process CPU time, "
          "page-fault time included); `out`: output preallocated (and touched before), "
          "`alloc`: the call allocates; × = ratio of best times (median ratio in brackets). "
          "alloc sys: median system time per allocating call (ms, page faults: zeroing the "
          "fresh pages) and minor faults, shprobe / sphericart. f32 error: largest "
          "|y₃₂ − y₆₄| over the band scale √((2l+1)/4π) in float32 epsilons (inf: nan/inf "
          "in the output).\n")
    print("| lmax | dtype | directions | shprobe out | sphericart out | × | shprobe alloc "
          "| sphericart alloc | × | alloc sys ms (faults) | f32 error shprobe / sphericart |")
    print("| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | --- |")
    for lmax, dt, n, t, fa, e1, e2 in grid:
        err = "" if dt == "float64" else f"{e1:.0f} / {e2:.3g}"
        print(f"| {lmax} | {dt} | {n:,} | {t['ours_out'][0]:.1f} / {t['ours_out'][1]:.1f} "
              f"| {t['sc_out'][0]:.1f} / {t['sc_out'][1]:.1f} "
              f"| {t['ours_out'][0] / t['sc_out'][0]:.2f} "
              f"({t['ours_out'][1] / t['sc_out'][1]:.2f}) "
              f"| {t['ours_alloc'][0]:.1f} / {t['ours_alloc'][1]:.1f} "
              f"| {t['sc_alloc'][0]:.1f} / {t['sc_alloc'][1]:.1f} "
              f"| {t['ours_alloc'][0] / t['sc_alloc'][0]:.2f} "
              f"({t['ours_alloc'][1] / t['sc_alloc'][1]:.2f}) "
              f"| {fa['ours_alloc'][0]:.0f} ({fa['ours_alloc'][1]:.0f}) / "
              f"{fa['sc_alloc'][0]:.0f} ({fa['sc_alloc'][1]:.0f}) | {err} |")
    print("\nload average at the end of the table: "
          + " / ".join(f"{x:.2f}" for x in os.getloadavg()) + "\n")
    if "--grid" in sys.argv:
        return
    rows = []
    bench_basis(rows)
    print("### sh_basis: 10⁶ random unit directions, lmax = 6, float64, one thread\n")
    print("| implementation | ns / direction | × shprobe |")
    print("| --- | ---: | ---: |")
    for name, ns, rel in rows:
        print(f"| {name} | {ns:.1f} | {rel:.2f} |")
    rrows, brows = [], []
    bench_rotation(rrows, brows)
    print("\n### Rotation of one coefficient set, lmax = 8 (build D + apply), one thread\n")
    print("| implementation | µs / call | note |")
    print("| --- | ---: | --- |")
    for name, us, note in rrows:
        print(f"| {name} | {us:.1f} | {note} |")
    print("\n### Batch: 10,000 rotations at lmax = 2, RGB\n")
    print("| implementation | µs / rotation |")
    print("| --- | ---: |")
    for name, us in brows:
        print(f"| {name} | {us:.3f} |")
    irows = []
    bench_import(irows)
    print("\n### Start-up\n")
    print("| what | ms (over a bare `python -c pass`) |")
    print("| --- | ---: |")
    for name, ms in irows:
        print(f"| {name} | {ms:.0f} |")


if __name__ == "__main__":
    main()
