"""sh_basis against independent evaluations: quadrature orthonormality, scipy's complex SH
(Condon–Shortley phase removed, `sh_basis_scipy`) to l = 64, the addition theorem and
P_l(u·v) to l = 256."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import eval_legendre

from shprobe import ShprobeError
from shprobe.sh import sh_basis, sh_basis_numpy, sh_basis_scipy
from tests.conftest import random_dirs


def band_norm(lmax):
    l = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
    return np.sqrt((2 * l + 1) / (4 * np.pi))


def test_orthonormal_by_quadrature_l16():
    lmax = 16
    n = lmax + 2  # Gauss–Legendre exact for degree 2n−1 ≥ 2·lmax in z
    z, w = np.polynomial.legendre.leggauss(n)
    nphi = 2 * lmax + 2
    phi = np.arange(nphi) * 2 * np.pi / nphi
    s = np.sqrt(1 - z * z)
    u = np.stack(np.broadcast_arrays(s[:, None] * np.cos(phi), s[:, None] * np.sin(phi),
                                     z[:, None]), -1).reshape(-1, 3)
    wt = np.repeat(w * 2 * np.pi / nphi, nphi)
    Y = sh_basis(u, lmax)
    G = (Y * wt[:, None]).T @ Y
    np.testing.assert_allclose(G, np.eye((lmax + 1) ** 2), atol=1e-13)


def test_scipy_reference_is_the_rh_table():
    d = random_dirs(5, seed=11)
    x, y, z = d.T
    want = np.stack([np.full_like(x, 0.282095), 0.488603 * y, 0.488603 * z, 0.488603 * x,
                     1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3 * z * z - 1),
                     1.092548 * x * z, 0.546274 * (x * x - y * y)], -1)
    np.testing.assert_allclose(sh_basis_scipy(d, 2), want, atol=2e-6)


def test_against_scipy_every_l_to_64():
    lmax = 64
    d = np.concatenate([random_dirs(300, seed=3),
                        [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0.6, 0.8, 0], [0, 1e-9, 1]]])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    err = np.abs(sh_basis(d, lmax) - sh_basis_scipy(d, lmax)) / band_norm(lmax)
    assert err.max() <= 1e-12


def test_numba_kernel_matches_numpy_reference():
    # the table kernel fuses a·(z p1 − b p2) into A z p1 − AB p2 (one FMA): same recurrence,
    # last-bit differences; float32 output is computed in float32 (see the next test)
    d = random_dirs(500, seed=4)
    tol = (np.repeat(np.arange(21), 2 * np.arange(21) + 1) + 1) * band_norm(20)
    assert np.all(np.abs(sh_basis(d, 20) - sh_basis_numpy(d, 20)) <= 2 * np.finfo(float).eps * tol)
    f = d.astype(np.float32)
    assert sh_basis(f, 20).dtype == np.float32
    err = np.abs(sh_basis(f, 20) - sh_basis_numpy(f, 20).astype(np.float64))
    assert np.all(err <= np.finfo(np.float32).eps * tol)


def test_float32_against_float64_every_degree_to_64():
    """float32 directions → float32 output (float32 arithmetic, in every unrolled kernel and
    in the table kernel) against float64 evaluation of the same (rounded) directions: the
    error in degree l stays within (l + 1) float32 epsilons of the band's scale √((2l+1)/4π),
    the size of the change a one-ulp move of the direction itself makes."""
    eps = np.finfo(np.float32).eps
    d = np.concatenate([random_dirs(400, seed=12),
                        [[0, 0, 1], [0, 0, -1], [1, 0, 0], [1e-3, 0, 1], [0.6, 0.8, 0]]])
    d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    for lmax in (*range(9), 9, 10, 16, 33, 64):  # each unrolled kernel, then the table
        y32 = sh_basis(d, lmax)
        assert y32.dtype == np.float32
        y64 = sh_basis(d.astype(np.float64), lmax)
        l = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
        err = np.abs(y32 - y64) / band_norm(lmax)
        assert np.all(err <= 1.5 * (l + 1) * eps), lmax


def test_degree_256_addition_theorem_and_legendre():
    lmax = 256
    u = np.concatenate([random_dirs(40, seed=5), [[0, 0, 1], [0, 0, -1], [1, 0, 0]]])
    v = np.concatenate([random_dirs(40, seed=6), [[0, 0, 1], [0.6, 0, 0.8], [0, 1, 0]]])
    Yu, Yv = sh_basis(u, lmax), sh_basis(v, lmax)
    assert np.all(np.isfinite(Yu))
    deg = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
    l = np.arange(lmax + 1)
    sq = np.stack([np.bincount(deg, weights=row ** 2) for row in Yu])
    np.testing.assert_allclose(sq, np.broadcast_to((2 * l + 1) / (4 * np.pi), sq.shape),
                               rtol=1e-12)
    dot = np.stack([np.bincount(deg, weights=a * b) for a, b in zip(Yu, Yv, strict=True)])
    want = (2 * l + 1) / (4 * np.pi) * eval_legendre(l[None, :], np.sum(u * v, 1)[:, None])
    np.testing.assert_allclose(dot, want, atol=1e-12 * (2 * lmax + 1) / (4 * np.pi))


@pytest.mark.parametrize("lmax", [128, 256])
def test_every_value_against_scipy_at_high_degree(lmax):
    """Each y_lm, not only sums over m (a flipped sign or a cos/sin swap within a band leaves
    the addition theorem intact): against scipy's sph_harm_y, relative to the band's scale
    √((2l+1)/4π), on random and near-pole directions."""
    d = np.concatenate([random_dirs(6, seed=9),
                        [[1e-4, 2e-4, 1.0], [0.6, 0.8, 0.0], [-0.3, 0.1, -0.948683]]])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    l = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
    err = (sh_basis(d, lmax) - sh_basis_scipy(d, lmax)) / np.sqrt((2 * l + 1) / (4 * np.pi))
    assert np.abs(err).max() < 1e-10


def test_degree_1024_finite_float32():
    d = random_dirs(3, seed=7, dtype=np.float32)
    Y = sh_basis(d, 1024)
    assert Y.dtype == np.float32 and np.all(np.isfinite(Y))
    deg = np.repeat(np.arange(1025), 2 * np.arange(1025) + 1)
    sq = np.bincount(deg, weights=Y[0].astype(np.float64) ** 2)
    np.testing.assert_allclose(sq, (2 * np.arange(1025) + 1) / (4 * np.pi), rtol=1e-4)


def test_out_parameter_and_shapes():
    d = random_dirs(12, seed=8).reshape(3, 4, 3)
    out = np.full((3, 4, 25), np.nan)
    r = sh_basis(d, 4, out=out)
    assert r is out
    np.testing.assert_allclose(out, sh_basis_numpy(d, 4), atol=1e-15)
    assert sh_basis(np.zeros((0, 3)), 3).shape == (0, 16)
    assert sh_basis([0, 0, 1], 2).shape == (9,)
    with pytest.raises(ShprobeError):
        sh_basis(d, 4, out=np.empty((3, 4, 25), dtype=np.float32))
    with pytest.raises(ShprobeError):
        sh_basis(d, 4, out=np.empty((3, 4, 16)))
    with pytest.raises(ShprobeError):
        sh_basis(np.zeros((4, 2)), 2)
    with pytest.raises(ShprobeError):
        sh_basis(d, -1)


@pytest.mark.parametrize("lmax", range(0, 11))
def test_unrolled_and_loop_kernels_match_reference(lmax):
    # lmax ≤ 8 runs the generated unrolled kernels, above that the table loop
    d = np.concatenate([random_dirs(200, seed=9), [[0, 0, 1], [0, 0, -1], [0, 1, 0]]])
    for dtype in (np.float64, np.float32):
        got = sh_basis(d.astype(dtype), lmax)
        assert got.dtype == dtype
        want = sh_basis_numpy(d.astype(dtype), lmax)
        tol = 1e-14 if dtype == np.float64 else 1e-6
        np.testing.assert_allclose(got, want, rtol=0, atol=tol)


def test_generated_unrolled_module_is_current():
    import importlib.util
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    spec = importlib.util.spec_from_file_location("gen", root / "tools" / "gen_sh_unrolled.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    assert (root / "src" / "shprobe" / "sh" / "_kernels_unrolled.py").read_text() == gen.source()


def test_import_does_not_load_numba():
    # `import shprobe` must stay light: numba and the kernels load on first use only
    import subprocess
    import sys

    code = ("import sys, shprobe, shprobe.sh, shprobe.sh.rotation, shprobe.sh.zonal, "
            "shprobe.sh.conventions, shprobe.cli.main; print('numba' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "False"


def test_degree_1024_near_the_poles():
    # the (x+iy)^m factor goes to 0 while the z-polynomials grow near the poles: no overflow,
    # and the addition theorem Σ_m y_lm² = (2l+1)/4π still holds
    lmax = 1024
    eps = np.array([0.0, 1e-12, 1e-6, 1e-3])
    z = 1 - eps
    d = np.stack([np.sqrt(1 - z * z), np.zeros_like(z), z], -1)
    d = np.concatenate([d, -d])
    Y = sh_basis(d, lmax)
    assert np.all(np.isfinite(Y))
    deg = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
    want = (2 * np.arange(lmax + 1) + 1) / (4 * np.pi)
    for row in Y:
        np.testing.assert_allclose(np.bincount(deg, weights=row ** 2), want, rtol=1e-10)


def test_streamed_output_equals_plain_stores(monkeypatch):
    # outputs ≥ STREAM_MIN_BYTES are written block by block with aligned non-temporal
    # stores: same values as plain stores, whatever the output's alignment and row count —
    # by the table kernel and by the unrolled ones (lmax ≤ 8, several blocks of rows)
    import shprobe.sh.basis as basis

    d = random_dirs(1001, seed=13)
    for lmax, dtype in ((0, np.float64), (2, np.float32), (2, np.float64), (8, np.float32),
                        (9, np.float64), (12, np.float32), (21, np.float64)):
        dd = d.astype(dtype)
        plain = sh_basis(dd, lmax)
        monkeypatch.setattr(basis, "STREAM_MIN_BYTES", 0)
        monkeypatch.setattr(basis, "UNROLLED_STREAM_MIN_BYTES", 0)
        K = (lmax + 1) ** 2
        big = np.full(len(d) * K + 7, np.nan, dtype)
        for off in (0, 1, 3):
            out = big[off:off + len(d) * K].reshape(len(d), K)
            assert basis._stream_start(out) >= 0
            np.testing.assert_array_equal(sh_basis(dd, lmax, out=out), plain)
        assert np.isnan(big[len(d) * K + 3:]).all()  # nothing written past the end
        monkeypatch.undo()


def test_large_out_at_unrolled_degrees_goes_through_the_stream_kernels(monkeypatch):
    # (the values are checked above; here: that a large out= takes the streaming path)
    import shprobe.sh.basis as basis
    from shprobe.sh import _kernels_unrolled as _unrolled

    calls, real = [], _unrolled.STREAM_KERNELS

    def spy(k):
        def f(*args):
            calls.append(k)
            return real[k](*args)
        return f

    monkeypatch.setattr(_unrolled, "STREAM_KERNELS", tuple(spy(k) for k in range(9)))
    monkeypatch.setattr(basis, "STREAM_MIN_BYTES", 0)
    monkeypatch.setattr(basis, "UNROLLED_STREAM_MIN_BYTES", 0)
    d = random_dirs(100, seed=3)
    out = np.empty((100, 9))
    sh_basis(d, 2, out=out)
    sh_basis(d, 2)  # a fresh array: plain stores (see _stream_start)
    assert calls == [2]


def test_rows_through_the_buffer_equal_rows_in_place():
    # an output larger than L2 is computed block by block into a buffer and copied out (a
    # caller's out=, a fresh output with long rows); a fresh output with short rows, and a small
    # output, in place: the same values, and the recurrence's values (scipy's, independently,
    # for float64)
    from shprobe.sh import _kernels

    for lmax, dtype, n, in_place in ((12, np.float64, 1603, True), (40, np.float64, 1001, False),
                                     (20, np.float32, 1201, True), (56, np.float32, 1003, False)):
        K = (lmax + 1) ** 2
        row = K * np.dtype(dtype).itemsize
        assert n * row > _kernels.IN_PLACE_MAX_BYTES
        d = random_dirs(n, seed=17).astype(dtype)
        out = np.full((n, K), np.nan, dtype)
        big = sh_basis(d, lmax, out=out)  # through the buffer
        fresh = sh_basis(d, lmax)  # in place where 4 rows fit FRESH_FOUR_MAX_BYTES
        assert (4 * row <= _kernels.FRESH_FOUR_MAX_BYTES) == in_place
        small = np.concatenate([sh_basis(d[i:i + 8], lmax) for i in range(0, n, 8)])
        np.testing.assert_array_equal(big, small)
        np.testing.assert_array_equal(fresh, small)
        if dtype == np.float64:
            assert (np.abs(big - sh_basis_scipy(d, lmax)) / band_norm(lmax)).max() <= 1e-12
        else:  # as in the float32 test above: against float64 on the same rounded directions
            err = np.abs(big - sh_basis(d.astype(np.float64), lmax)) / band_norm(lmax)
            l = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
            assert np.all(err <= 1.5 * (l + 1) * np.finfo(np.float32).eps)
