"""Every numba kernel of the SH maths and the lighting layer against the one definition of its
formula, the array-API reference (``shprobe.sh._xp``, ``shprobe.sh._xp_rotation``,
``shprobe.lighting._xp``) run on NumPy, on random inputs, to ~1e-12 (float64). The list of
kernels and the test of each is in docs/architecture.md ("Kernels and their references")."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from shprobe.lighting import _xp as lx
from shprobe.sh import _xp, _xp_rotation
from tests.conftest import random_dirs

XP = _xp.numpy_namespace()


def ref_basis(d, lmax):
    return np.asarray(_xp.sh_basis(XP, np.asarray(d, dtype=np.float64), lmax))


def band_scale(lmax):
    l = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
    return np.sqrt((2 * l + 1) / (4 * np.pi))


@pytest.mark.parametrize("lmax", range(9))
def test_unrolled_kernels_equal_the_reference(lmax):
    from shprobe.sh._kernels_unrolled import KERNELS, STREAM_KERNELS

    d = random_dirs(1003, seed=lmax)
    want = ref_basis(d, lmax)
    for dtype, tol in ((np.float64, 1e-13), (np.float32, 4e-6)):
        dd = np.ascontiguousarray(d.astype(dtype))
        out = np.full((len(d), (lmax + 1) ** 2), np.nan, dtype)
        KERNELS[lmax](dd, out)
        assert (np.abs(out - want) / band_scale(lmax)).max() <= tol
        out[:] = np.nan
        a0 = ((-out.ctypes.data) % 64) // out.itemsize
        STREAM_KERNELS[lmax](dd, out, a0)
        assert (np.abs(out - want) / band_scale(lmax)).max() <= tol


@pytest.mark.parametrize("lmax", [9, 20, 47])
def test_table_kernel_equals_the_reference(lmax):
    from shprobe.sh._kernels import sh_rows
    from shprobe.sh.basis import _kernel_tables

    d = random_dirs(1001, seed=lmax)
    l = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
    # float32: against the reference at the same rounded directions, within 2 (l + 1) float32
    # epsilons of the band's scale (the kernel computes in float32 there)
    for dtype, tol in ((np.float64, 1e-12), (np.float32, 2 * (l + 1) * np.finfo(np.float32).eps)):
        dd = np.ascontiguousarray(d.astype(dtype))
        out = np.full((len(d), (lmax + 1) ** 2), np.nan, dtype)
        sh_rows(dd, lmax, *_kernel_tables(lmax, dtype), out, -1, True)
        assert np.all(np.abs(out - ref_basis(dd, lmax)) / band_scale(lmax) <= tol)


def test_sh_basis_equals_sh_basis_numpy_the_reference():
    from shprobe.sh import sh_basis, sh_basis_numpy

    d = random_dirs(5000, seed=3).reshape(50, 100, 3)
    for lmax in (0, 2, 8, 9, 30):
        assert np.abs(sh_basis(d, lmax) - sh_basis_numpy(d, lmax)).max() <= 1e-12


def test_projection_kernel_equals_the_reference():
    # lighting._kernels.project_rgb_kernel (its own inline basis, sh_into) against
    # Σ v w y of the reference basis
    from shprobe.lighting.projection import project_samples

    rng = np.random.default_rng(4)
    d = random_dirs(20000, seed=4)
    for lmax, nch in ((2, 3), (9, 3), (16, 5)):
        v = rng.normal(size=(len(d), nch))
        w = rng.uniform(0.5, 1.5, len(d)) * 4 * np.pi / len(d)
        got = project_samples(d, v, w, lmax)
        want = np.asarray(lx.project_samples(XP, d, v, w, lmax))
        assert np.abs(got - want).max() <= 1e-12 * np.abs(want).max()


def test_quadratic_kernel_equals_the_reference():
    # lighting._kernels.quad_eval (the renderer's shading at lmax ≤ 2) against R&H eq. 13
    from shprobe.lighting.irradiance import shade_irradiance

    rng = np.random.default_rng(5)
    c = rng.normal(size=(9, 3))
    n = rng.normal(size=(4000, 3)) * rng.uniform(0.1, 10, (4000, 1))  # not unit: normalised
    got = shade_irradiance(c, n, dtype=np.float64)
    want = np.asarray(lx.irradiance_quadratic(XP, c, _xp.unit_vectors(XP, n)))
    assert np.abs(got - want).max() <= 1e-12 * np.abs(want).max()


def test_latlong_error_kernel_equals_the_reference():
    # lighting._kernels.latlong_error (inline basis + the exact lat-long irradiance) against
    # |E_SH − E_ref| of the reference irradiance and the brute-force sum of NumPy
    from shprobe.lighting.projection import project
    from shprobe.lighting.reference import _Exact
    from shprobe.probes.env import Env

    rng = np.random.default_rng(6)
    env = Env(rng.uniform(0, 2, (12, 24, 3)).astype(np.float32), "latlong")
    d, L, dw = env.samples()
    exact = _Exact(env)
    n = random_dirs(300, seed=6)
    brute = np.maximum(n @ d.T, 0) @ (L.astype(np.float64) * dw[:, None])
    assert np.abs(exact(n) - brute).max() <= 1e-12 * brute.max()
    c = project(env, 4)
    tot = dw @ L.astype(np.float64)
    err, chan = exact.error_fn(c, tot)(n)
    e_sh = np.asarray(lx.irradiance(XP, c, n))
    want = np.abs(e_sh - brute) / tot
    np.testing.assert_allclose(err, want.max(axis=1), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(chan, want.argmax(axis=1))


def test_brute_force_kernel_equals_the_sum():
    # lighting._kernels.brute_kernel / brute_serial: Σ L max(0, n·ω) dω, the definition
    from shprobe.lighting.reference import reference_irradiance
    from shprobe.probes.env import Env

    rng = np.random.default_rng(7)
    env = Env(rng.uniform(0, 2, (6, 8, 8, 3)).astype(np.float32), "cube")
    d, L, dw = env.samples()
    n = random_dirs(200, seed=7)
    want = np.maximum(n @ d.T, 0) @ (L.astype(np.float64) * dw[:, None])
    assert np.abs(reference_irradiance(env, n) - want).max() <= 1e-12 * want.max()


@pytest.mark.parametrize("lmax", [1, 2, 3, 8, 16, 64])
def test_rotation_kernels_equal_the_reference(lmax):
    # sh._kernels_rotation: wigner_full, rotate_batch (lmax ≥ 3) and rotate_low_batch
    # (lmax ≤ 2) against the reference Wigner blocks and rotation (sh._xp_rotation: the
    # same algorithm, J = d(π/2) between z-rotations, in whole-array steps)
    from shprobe.sh.rotation import rotate, wigner_d

    R = Rotation.random(4, random_state=lmax).as_matrix()
    R[0] = np.eye(3)  # gimbal lock included
    R[1] = Rotation.from_euler("ZYZ", [0.3, np.pi, -1.1]).as_matrix()
    if lmax <= 16:
        got = wigner_d(R, lmax)
        want = np.asarray(_xp_rotation.wigner_d(XP, R, lmax))
        assert np.abs(got - want).max() <= 1e-12
    c = np.random.default_rng(lmax).normal(size=(4, (lmax + 1) ** 2, 3))
    got = rotate(c, R)
    want = np.asarray(_xp_rotation.rotate(XP, c, R))
    assert np.abs(got - want).max() <= 1e-12 * np.abs(c).max()


def test_d_tables_kernel_equals_the_reference():
    # sh._kernels_rotation.d_tables (the J = d(π/2) quadrant tables of the NumPy path)
    # against the reference recurrence, and J orthogonal to l = 256
    from shprobe.sh._kernels_rotation import d_tables, pq_offset

    lmax = 256
    P, Q = d_tables(0.0, 1.0, lmax)
    J = _xp_rotation.d_half_pi(lmax)
    for l in (1, 2, 5, 33, 128, 256):
        o, w = pq_offset(l), l + 1
        p = P[o:o + w * w].reshape(w, w)
        q = Q[o:o + w * w].reshape(w, w)
        assert np.abs(J[l][l:, l:] - p).max() <= 1e-12
        assert np.abs(J[l][:l, :l] - q[1:, 1:][::-1, ::-1]).max() <= 1e-12
        assert np.abs(J[l] @ J[l].T - np.eye(2 * l + 1)).max() <= 1e-12
