"""Benchmark: SH basis and rotation against their peers (issue: foundation).

Run: ``python bench/bench_sh.py`` (``PYTHONPATH=src`` when shprobe is not installed). Prints
markdown tables; one thread everywhere. Peers: sphericart (preallocated output, through its
``_compute_numpy`` so no allocation is timed), scipy.special.sph_harm_y, pyshtools
SHRotateRealCoef, ducc0.sht.rotate_alm, e3nn.o3.wigner_D (when torch/e3nn are installed).
Timings are the best of several repeats of process CPU time (the machine is shared).
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_v] = "1"

import subprocess  # noqa: E402
import sys  # noqa: E402
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


def main():
    print(f"Machine: {machine()}\n")
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
