"""Benchmark: the array-API (torch) path against its peers, one thread, same run.

Run: ``python bench/bench_tensor.py`` (``PYTHONPATH=src`` when shprobe is not installed;
needs the ``torch`` and ``bench`` extras: sphericart-torch, e3nn). Prints markdown tables:

- ``sh_basis`` forward + backward (``y.sum().backward()``) on 10⁶ float32 directions at
  lmax 3 and 8: shprobe on torch tensors, sphericart-torch's ``SphericalHarmonics``, and a
  plain torch polynomial (lmax 3, the 16 closed forms written out);
- batched rotation of 10⁴ RGB lmax-2 coefficient sets by 10⁴ rotation matrices, forward and
  forward + backward: shprobe ``rotate`` on tensors against e3nn (``matrix_to_angles`` +
  ``wigner_D`` per band + a batched product), float32;
- the NumPy (numba) ``sh_basis`` at 10⁶ directions, lmax 3 and 8, for the record.

Timings are the best of several repeats of process CPU time (everything on one thread:
``torch.set_num_threads(1)``); the machine is shared, so CPU time is what is compared.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_v] = "1"

import time  # noqa: E402

import numpy as np  # noqa: E402
import torch  # noqa: E402

from _machine import machine  # noqa: E402

torch.set_num_threads(1)


def best(f, repeat=5):
    f()
    t_best = np.inf
    for _ in range(repeat):
        t = time.process_time()
        f()
        t_best = min(t_best, time.process_time() - t)
    return t_best


def unit_dirs(n, seed=0):
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def torch_poly3(d):
    """The 16 real SH of lmax 3 as closed-form polynomials (R&H signs)."""
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    xx, yy, zz = x * x, y * y, z * z
    return torch.stack([
        torch.full_like(x, 0.28209479177387814), 0.4886025119029199 * y,
        0.4886025119029199 * z, 0.4886025119029199 * x,
        1.0925484305920792 * x * y, 1.0925484305920792 * y * z,
        0.31539156525252005 * (3 * zz - 1), 1.0925484305920792 * x * z,
        0.5462742152960396 * (xx - yy),
        0.5900435899266435 * y * (3 * xx - yy), 2.890611442640554 * x * y * z,
        0.4570457994644658 * y * (5 * zz - 1), 0.3731763325901154 * z * (5 * zz - 3),
        0.4570457994644658 * x * (5 * zz - 1), 1.445305721320277 * z * (xx - yy),
        0.5900435899266435 * x * (xx - 3 * yy)], dim=-1)


def fwd_bwd(f, d):
    def run():
        x = d.detach().clone().requires_grad_(True)
        f(x).sum().backward()
    return run


def bench_basis():
    from shprobe.sh import sh_basis

    d = torch.tensor(unit_dirs(10**6), dtype=torch.float32)
    rows = []
    try:
        import sphericart.torch as sct
    except ImportError:
        sct = None
    for lmax in (3, 8):
        t_ours = best(fwd_bwd(lambda x, lmax=lmax: sh_basis(x, lmax), d))
        row = [f"{lmax}", f"{t_ours * 1e3:.0f}"]
        if sct is not None:
            calc = sct.SphericalHarmonics(lmax)
            t_sc = best(fwd_bwd(calc, d))
            row.append(f"{t_sc * 1e3:.0f}")
        else:
            row.append("not installed")
        row.append(f"{best(fwd_bwd(torch_poly3, d)) * 1e3:.0f}" if lmax == 3 else "—")
        t_fw = best(lambda lmax=lmax: sh_basis(d, lmax))
        row.append(f"{t_fw * 1e3:.0f}")
        rows.append(row)
    print("\n### sh_basis, torch CPU float32, 10⁶ directions, forward + backward (ms)\n")
    print("| lmax | shprobe (torch) | sphericart-torch | plain torch polynomial "
          "| shprobe forward only |")
    print("| --- | --- | --- | --- | --- |")
    for r in rows:
        print("| " + " | ".join(r) + " |")


def e3nn_rotate(c, R):
    from e3nn import o3

    a, b, g = o3.matrix_to_angles(R)
    parts = [c[:, :1]]
    for l in (1, 2):
        D = o3.wigner_D(l, a, b, g)  # e3nn's basis: y_l(Qv); rotate in its own basis
        parts.append(D @ c[:, l * l:(l + 1) ** 2])
    return torch.cat(parts, dim=1)


def bench_rotation():
    from shprobe.sh.rotation import from_quaternion, rotate

    n = 10**4
    R = torch.tensor(from_quaternion(np.random.default_rng(1).normal(size=(n, 4))),
                     dtype=torch.float32)
    c = torch.tensor(np.random.default_rng(2).normal(size=(n, 9, 3)), dtype=torch.float32)
    ours = best(lambda: rotate(c, R), repeat=9)

    def ours_fb():
        cc, rr = c.clone().requires_grad_(True), R.clone().requires_grad_(True)
        rotate(cc, rr).sum().backward()

    t_ours_fb = best(ours_fb, repeat=9)
    row = ["shprobe `rotate` (torch)", f"{ours * 1e3:.2f}", f"{t_ours_fb * 1e3:.2f}"]
    rows = [row]
    try:
        import e3nn  # noqa: F401

        t_e = best(lambda: e3nn_rotate(c, R), repeat=9)

        def e_fb():
            cc, rr = c.clone().requires_grad_(True), R.clone().requires_grad_(True)
            e3nn_rotate(cc, rr).sum().backward()

        rows.append(["e3nn `matrix_to_angles` + `wigner_D`", f"{t_e * 1e3:.2f}",
                     f"{best(e_fb, repeat=9) * 1e3:.2f}"])
    except ImportError:
        rows.append(["e3nn", "not installed", "—"])
    print("\n### rotate 10⁴ RGB lmax-2 sets by 10⁴ matrices, torch CPU float32 (ms)\n")
    print("| | forward | forward + backward |")
    print("| --- | --- | --- |")
    for r in rows:
        print("| " + " | ".join(r) + " |")


def bench_numpy():
    from shprobe.sh import sh_basis

    print("\n### NumPy path (numba), 10⁶ directions, allocating call (ms)\n")
    print("| lmax | float64 | float32 |")
    print("| --- | --- | --- |")
    d = unit_dirs(10**6)
    d32 = d.astype(np.float32)
    for lmax in (3, 8):
        t64 = best(lambda lmax=lmax: sh_basis(d, lmax))
        t32 = best(lambda lmax=lmax: sh_basis(d32, lmax))
        print(f"| {lmax} | {t64 * 1e3:.1f} | {t32 * 1e3:.1f} |")


if __name__ == "__main__":
    print(machine())
    print(f"torch {torch.__version__}, one thread; no GPU on this machine")
    bench_basis()
    bench_rotation()
    bench_numpy()
