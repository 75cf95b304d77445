"""Wigner rotation (LH §2.2) against independent checks: group laws, orthogonality, the l = 1
block as the 3×3 matrix itself, zonal lobes, and quadrature projection of f∘R⁻¹."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from shprobe import ShprobeError
from shprobe.sh import sh_basis
from shprobe.sh.rotation import as_matrix, from_euler_zyz, from_quaternion, rotate, wigner_d
from tests.conftest import random_dirs

# ZYZ angle triples at and near gimbal lock, plus generic ones
EULER_CASES = [
    (0.3, 0.0, 0.5), (0.3, 1e-12, 0.5), (0.3, 1e-7, -2.0), (1.0, np.pi, 2.0),
    (1.0, np.pi - 1e-12, 2.0), (-2.5, np.pi / 2, 0.1), (0.7, 2.2, -1.3),
]


def random_rotations(n, seed=0):
    return Rotation.random(n, random_state=seed).as_matrix()


def sphere_quadrature(n):
    """Gauss–Legendre in z × uniform φ: exact for polynomials of degree < 2n in z, < 2n in φ."""
    z, w = np.polynomial.legendre.leggauss(n)
    phi = (np.arange(2 * n) + 0.5) * np.pi / n
    s = np.sqrt(1 - z * z)
    u = np.stack(np.broadcast_arrays(s[:, None] * np.cos(phi), s[:, None] * np.sin(phi),
                                     z[:, None]), axis=-1).reshape(-1, 3)
    wt = np.repeat(w * np.pi / n, 2 * n)
    return u, wt


def test_identity():
    D = wigner_d(np.eye(3), 10)
    np.testing.assert_allclose(D, np.eye(121), atol=1e-15)
    c = np.random.default_rng(0).normal(size=(121, 3))
    np.testing.assert_allclose(rotate(c, np.eye(3)), c, atol=1e-14)


def test_l1_block_is_the_matrix():
    # y_1m ∝ (y, z, x): coefficients of a·u turn like a → R a in that order
    R = random_rotations(5, seed=1)
    perm = [1, 2, 0]
    D1 = wigner_d(R, 1)[:, 1:, 1:]
    np.testing.assert_allclose(D1, R[:, perm][:, :, perm], atol=1e-14)


def test_inverse_and_transpose():
    R = random_rotations(4, seed=2)
    D = wigner_d(R, 8)
    Dt = wigner_d(np.swapaxes(R, -1, -2), 8)
    np.testing.assert_allclose(Dt, np.swapaxes(D, -1, -2), atol=1e-13)
    c = np.random.default_rng(3).normal(size=(4, 81, 3))
    back = rotate(rotate(c, R), np.swapaxes(R, -1, -2))
    np.testing.assert_allclose(back, c, atol=1e-13)


def test_composition():
    R1, R2 = random_rotations(2, seed=4)
    lmax = 12
    np.testing.assert_allclose(wigner_d(R1 @ R2, lmax), wigner_d(R1, lmax) @ wigner_d(R2, lmax),
                               atol=1e-13)


@pytest.mark.parametrize("angles", EULER_CASES)
def test_composition_gimbal_lock(angles):
    R = from_euler_zyz(*angles)
    R2 = random_rotations(1, seed=5)[0]
    lmax = 10
    np.testing.assert_allclose(wigner_d(R @ R2, lmax), wigner_d(R, lmax) @ wigner_d(R2, lmax),
                               atol=1e-13)


def test_orthogonality_l32():
    Rs = np.concatenate([random_rotations(4, seed=6),
                         from_euler_zyz(*np.array(EULER_CASES).T)])
    lmax = 32
    D = wigner_d(Rs, lmax)
    worst = 0.0
    for l in range(lmax + 1):
        B = D[:, l * l:(l + 1) ** 2, l * l:(l + 1) ** 2]
        worst = max(worst, np.abs(B @ np.swapaxes(B, -1, -2) - np.eye(2 * l + 1)).max())
    assert worst <= 1e-12
    # and nothing outside the blocks
    mask = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
    assert np.all(D[:, mask[:, None] != mask[None, :]] == 0.0)


def test_high_degree_round_trip():
    # l up to 200: band norms kept, R then Rᵀ returns the input, composition holds
    lmax = 200
    rng = np.random.default_rng(7)
    c = rng.normal(size=((lmax + 1) ** 2, 2))
    R1, R2 = random_rotations(2, seed=8)
    r = rotate(c, R1)
    deg = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
    n0 = np.bincount(deg, weights=(c ** 2).sum(1))
    n1 = np.bincount(deg, weights=(r ** 2).sum(1))
    np.testing.assert_allclose(n1, n0, rtol=1e-12)
    np.testing.assert_allclose(rotate(r, R1.T), c, atol=1e-11)
    np.testing.assert_allclose(rotate(rotate(c, R2), R1), rotate(c, R1 @ R2), atol=1e-11)


def test_rotated_zonal_lobe_points_along_rotated_axis():
    lmax = 9
    g = np.random.default_rng(9).normal(size=lmax + 1)  # arbitrary zonal profile per band
    deg = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
    axes = random_dirs(3, seed=10)
    Rs = random_rotations(3, seed=11)
    lobe = g[deg] * sh_basis(axes, lmax)  # b_lm = g_l y_lm(axis), LH Prop. 3.2
    turned = rotate(lobe[..., None], Rs)[..., 0]
    want = g[deg] * sh_basis(np.einsum("nij,nj->ni", Rs, axes), lmax)
    np.testing.assert_allclose(turned, want, atol=1e-13)


def _f(u):
    """A smooth, not band-limited test function with no symmetry."""
    a = np.array([0.3, -0.8, 0.5])
    return np.stack([np.exp(1.5 * u @ a) * (1 + u[:, 0] * u[:, 1]),
                     np.cos(2 * u[:, 2] + u[:, 0]) + u[:, 1] ** 3], axis=-1)


def _project(values, u, wt, lmax):
    return np.einsum("qk,qc,q->kc", sh_basis(u, lmax), values, wt)


def _check_projection(R, got, lmax):
    u, wt = sphere_quadrature(48)
    R = np.asarray(R)
    want = _project(_f(u @ R), u, wt, lmax)  # f(R⁻¹u), R⁻¹u = Rᵀu ↔ row vector u R
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_rotate_equals_projection_of_rotated_function():
    lmax = 8
    u, wt = sphere_quadrature(48)
    c = _project(_f(u), u, wt, lmax)
    R = random_rotations(1, seed=12)[0]
    _check_projection(R, rotate(c, R), lmax)


@pytest.mark.parametrize("angles", EULER_CASES)
def test_projection_euler_input(angles):
    lmax = 8
    u, wt = sphere_quadrature(48)
    c = _project(_f(u), u, wt, lmax)
    R = from_euler_zyz(*angles)
    ref = Rotation.from_euler("ZYZ", [angles[2], angles[1], angles[0]]).as_matrix()
    np.testing.assert_allclose(R, ref, atol=1e-15)
    _check_projection(ref, rotate(c, R), lmax)


def test_projection_quaternion_and_scipy_inputs():
    lmax = 6
    u, wt = sphere_quadrature(48)
    c = _project(_f(u), u, wt, lmax)
    rot = Rotation.random(random_state=13)
    xyzw = rot.as_quat()
    wxyz = np.r_[xyzw[3], xyzw[:3]]
    np.testing.assert_allclose(from_quaternion(wxyz), rot.as_matrix(), atol=1e-15)
    np.testing.assert_allclose(from_quaternion(-3 * wxyz), rot.as_matrix(), atol=1e-15)
    _check_projection(rot.as_matrix(), rotate(c, wxyz), lmax)
    _check_projection(rot.as_matrix(), rotate(c, rot), lmax)
    np.testing.assert_allclose(as_matrix(rot), rot.as_matrix())


def test_projection_random_batch():
    lmax = 5
    u, wt = sphere_quadrature(40)
    c = _project(_f(u), u, wt, lmax)
    Rs = random_rotations(6, seed=14).reshape(2, 3, 3, 3)
    got = rotate(c, Rs)
    assert got.shape == (2, 3, 36, 2)
    for i in range(2):
        for j in range(3):
            _check_projection(Rs[i, j], got[i, j], lmax)
    D = wigner_d(Rs, lmax)
    assert D.shape == (2, 3, 36, 36)
    np.testing.assert_allclose(D @ c, got, atol=1e-13)


def test_shapes_dtypes_broadcasting():
    rng = np.random.default_rng(15)
    Rs = random_rotations(4, seed=16)
    c = rng.normal(size=(4, 16, 3))
    out = rotate(c, Rs)
    for i in range(4):
        np.testing.assert_allclose(out[i], wigner_d(Rs[i], 3) @ c[i], atol=1e-14)
    # one coefficient set, many rotations; many sets, one rotation; broadcasting both
    assert rotate(c[0], Rs.reshape(2, 2, 3, 3)).shape == (2, 2, 16, 3)
    np.testing.assert_allclose(rotate(c, Rs[0]), wigner_d(Rs[0], 3) @ c, atol=1e-14)
    b = rotate(rng.normal(size=(5, 16, 3)), Rs[:2].reshape(2, 1, 3, 3))
    assert b.shape == (2, 5, 16, 3)
    # (K,) single channel, float32 kept
    v = rng.normal(size=16)
    np.testing.assert_allclose(rotate(v, Rs[0]), wigner_d(Rs[0], 3) @ v, atol=1e-14)
    assert rotate(v, Rs).shape == (4, 16)
    f32 = rotate(c.astype(np.float32), Rs)
    assert f32.dtype == np.float32
    np.testing.assert_allclose(f32, out, atol=1e-5)


@pytest.mark.parametrize("bad", [
    np.diag([1.0, 1.0, -1.0]),  # reflection
    2 * np.eye(3),
    np.full((3, 3), np.nan),
    np.zeros((3, 4)),
    np.zeros((2, 3)),
])
def test_bad_rotation(bad):
    with pytest.raises(ShprobeError):
        rotate(np.zeros((9, 3)), bad)
    with pytest.raises(ShprobeError):
        wigner_d(bad, 2)
    with pytest.raises(ShprobeError):
        as_matrix(bad)


def test_bad_coefficients_and_quaternion():
    with pytest.raises(ShprobeError):
        rotate(np.zeros((10, 3)), np.eye(3))  # 10 is not (lmax+1)²
    with pytest.raises(ShprobeError):
        rotate(np.zeros((3, 9, 1)), random_rotations(2, seed=19))  # batches 3 vs 2
    with pytest.raises(ShprobeError):
        from_quaternion([0, 0, 0, 0])
    with pytest.raises(ShprobeError):
        wigner_d(np.eye(3), -1)
    with pytest.raises(ShprobeError, match="GiB"):  # refused before allocating 32 GiB
        wigner_d(np.eye(3), 256)
    with pytest.raises(ShprobeError, match="from_euler_zyz"):
        wigner_d([0.1, 0.2, 0.3], 2)


@pytest.mark.parametrize("lmax", [0, 1, 2])
def test_closed_form_low_degree_matches_recurrence(lmax):
    # rotate() takes a closed form for lmax ≤ 2; wigner_d() always runs the recurrence
    Rs = np.concatenate([random_rotations(20, seed=17), from_euler_zyz(*np.array(EULER_CASES).T)])
    c = np.random.default_rng(18).normal(size=((lmax + 1) ** 2, 3))
    np.testing.assert_allclose(rotate(c, Rs), wigner_d(Rs, lmax) @ c, atol=1e-14)
    for R in Rs[:3]:
        np.testing.assert_allclose(rotate(c, R), wigner_d(R, lmax) @ c, atol=1e-14)


@pytest.mark.parametrize("beta", [1e-9, 0.3, 1.2, 2.9, np.pi])
def test_lh_recurrence_at_any_beta_matches_the_pi_half_construction(beta):
    # The LH recurrence run directly at β (accurate for small l) equals the d(π/2)-based
    # D(Ry(β)) that wigner_d builds; its opposite-sign quadrants are zero.
    from shprobe.sh._kernels_rotation import d_tables

    lmax = 10
    P, Q = d_tables(np.cos(beta), np.sin(beta), lmax)
    D = wigner_d(from_euler_zyz(0.0, beta, 0.0), lmax)
    o = 0
    for l in range(lmax + 1):
        w = l + 1
        p = P[o:o + w * w].reshape(w, w)
        q = Q[o:o + w * w].reshape(w, w)
        o += w * w
        B = D[l * l:(l + 1) ** 2, l * l:(l + 1) ** 2]
        np.testing.assert_allclose(B[l:, l:], p, atol=1e-12)  # m, n ≥ 0
        np.testing.assert_allclose(B[:l, :l][::-1, ::-1], q[1:, 1:], atol=1e-12)  # m, n < 0
        np.testing.assert_allclose(B[l:, :l], 0.0, atol=1e-12)
        np.testing.assert_allclose(B[:l, l:], 0.0, atol=1e-12)


def test_degree_limit():
    with pytest.raises(ShprobeError):
        wigner_d(np.eye(3), 257)
    with pytest.raises(ShprobeError):
        rotate(np.zeros((258 ** 2, 1)), np.eye(3))


def test_z_mirror_signs_are_the_basis_under_z_to_minus_z():
    """y_lm(x, y, −z) = s_lm y_lm(x, y, z) with s = z_mirror_signs, at every degree."""
    from shprobe.sh.basis import sh_basis
    from shprobe.sh.rotation import z_mirror_signs

    d = np.random.default_rng(3).normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    flipped = d * [1.0, 1.0, -1.0]
    for lmax in (0, 2, 7):
        assert np.allclose(sh_basis(flipped, lmax), sh_basis(d, lmax) * z_mirror_signs(lmax),
                           atol=1e-12)
