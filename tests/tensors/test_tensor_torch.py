"""The public SH functions on torch tensors: the same values as the NumPy path (1e-12 in
float64, float32 rounding in float32), the same kind/dtype/device back, and exact gradients
(``torch.autograd.gradcheck`` in float64 for every function and every tensor argument)."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.lighting.irradiance import irradiance, irradiance_matrix, irradiance_quadratic
from shprobe.lighting.projection import project_samples
from shprobe.lighting.windows import window_factors
from shprobe.sh import sh_basis
from shprobe.sh.rotation import from_euler_zyz, from_quaternion, rotate, wigner_d
from shprobe.sh.zonal import clamped_cosine_factors, convolve
from tests.tensors.tensor_support import coeffs, need, quats, unit

torch = need("torch")
need("array_api_compat")


def T(a, dtype=None):
    return torch.tensor(np.asarray(a), dtype=dtype or torch.float64)


def close(t, a, tol=1e-12):
    assert isinstance(t, torch.Tensor)
    np.testing.assert_allclose(t.detach().numpy(), a, rtol=tol, atol=tol)


# ----------------------------------------------------------------------------- values


@pytest.mark.parametrize("lmax", [0, 1, 2, 3, 6, 8, 12, 20])
def test_sh_basis_equals_numpy(lmax):
    d = unit(300)
    t = sh_basis(T(d), lmax)
    assert t.dtype == torch.float64 and t.shape == (300, (lmax + 1) ** 2)
    close(t, sh_basis(d, lmax))
    # float32: float32 in, float32 out, within float32 rounding of the band scale
    t32 = sh_basis(T(d, torch.float32), lmax)
    assert t32.dtype == torch.float32
    np.testing.assert_allclose(t32.numpy(), sh_basis(d, lmax), atol=2e-6 * (lmax + 1) ** 1.5)
    # and the NumPy float32 path gives the same to float32 rounding
    np.testing.assert_allclose(t32.numpy(), sh_basis(d.astype(np.float32), lmax),
                               atol=2e-6 * (lmax + 1) ** 1.5)


def test_sh_basis_batched_and_independent():
    """Leading axes kept; checked against scipy's (independent) complex harmonics too."""
    from shprobe.sh import sh_basis_scipy

    d = unit(60).reshape(3, 4, 5, 3)
    t = sh_basis(T(d), 5)
    assert t.shape == (3, 4, 5, 36)
    close(t, sh_basis_scipy(d, 5), 1e-11)


@pytest.mark.parametrize("lmax", [1, 2, 3, 5, 10])
def test_wigner_and_rotate_equal_numpy(lmax):
    q = quats(6)
    R = from_quaternion(q)
    close(from_quaternion(T(q)), R)
    close(wigner_d(T(R), lmax), wigner_d(R, lmax))
    c = coeffs(lmax, batch=(6,))
    close(rotate(T(c), T(R)), rotate(c, R))
    close(rotate(T(c), T(q)), rotate(c, q))  # quaternions as the rotation
    close(rotate(T(c[0, :, 0]), T(R[2])), rotate(c[0, :, 0], R[2]))  # (K,) and one matrix
    # one set, many rotations (broadcast), numpy rotation with tensor coefficients
    close(rotate(T(c[0]), R), rotate(c[0], R))
    from scipy.spatial.transform import Rotation

    close(rotate(T(c[0]), Rotation.from_matrix(R)), rotate(c[0], R))
    c32 = rotate(T(c, torch.float32), T(R, torch.float32))
    assert c32.dtype == torch.float32
    np.testing.assert_allclose(c32.numpy(), rotate(c, R), atol=1e-5 * lmax)


def test_euler_equals_numpy():
    a, b, g = np.array([0.3, -1.0]), np.array([1.2, 0.1]), np.array([2.0, 0.7])
    close(from_euler_zyz(T(a), T(b), T(g)), from_euler_zyz(a, b, g))
    close(from_euler_zyz(T(a), 0.5, g), from_euler_zyz(a, 0.5, g))


def test_lighting_functions_equal_numpy():
    c = coeffs(4)
    n = unit(50, 3) * 2.5  # normals are normalised by policy
    close(irradiance(T(c), T(n)), irradiance(c, n))
    close(irradiance(T(c[:, 1]), T(n)), irradiance(c[:, 1], n))
    close(irradiance_matrix(T(c[:9])), irradiance_matrix(c[:9]))
    close(irradiance_matrix(T(coeffs(2, batch=(4,)))), irradiance_matrix(coeffs(2, batch=(4,))))
    close(irradiance_quadratic(T(c[:9]), T(n)), irradiance_quadratic(c[:9], n))
    d, v, w = unit(400, 5), np.random.default_rng(6).normal(size=(400, 3)), np.full(400, 0.01)
    close(project_samples(T(d), T(v), T(w), lmax=4), project_samples(d, v, w, lmax=4))
    close(project_samples(T(d), T(v[:, 0]), lmax=3), project_samples(d, v[:, 0], lmax=3))
    for kind in ("hann", "lanczos", "gaussian", "laplacian"):
        for s in (0.0, 0.4, 1.7):
            close(window_factors(kind, 7, T(s)), window_factors(kind, 7, s))
    close(clamped_cosine_factors(9, like=T(c)), clamped_cosine_factors(9))
    f = window_factors("gaussian", 4, 0.1)
    close(convolve(T(c), T(f)), convolve(c, f))
    close(convolve(T(c), f), convolve(c, f))


def test_float32_lighting_within_rounding():
    c, n = coeffs(3), unit(40, 8)
    got = irradiance(T(c, torch.float32), T(n, torch.float32))
    assert got.dtype == torch.float32
    np.testing.assert_allclose(got.numpy(), irradiance(c, n), rtol=1e-5, atol=1e-5)
    got = project_samples(T(n, torch.float32), T(np.ones((40, 3)), torch.float32), lmax=3)
    np.testing.assert_allclose(got.numpy(), project_samples(n, np.ones((40, 3)), lmax=3),
                               rtol=1e-5, atol=1e-5)


def test_same_kind_and_dtype_back():
    c32 = T(coeffs(2), torch.float32)
    n32 = T(unit(5), torch.float32)
    for out in (irradiance(c32, n32), irradiance_matrix(c32), irradiance_quadratic(c32, n32),
                rotate(c32, T(quats(1)[0], torch.float32)), convolve(c32, [1.0, 0.5, 0.25]),
                project_samples(n32, T(np.ones((5, 3)), torch.float32), lmax=2),
                sh_basis(n32, 2), wigner_d(T(quats(2), torch.float32), 2)):
        assert isinstance(out, torch.Tensor) and out.dtype == torch.float32
        assert out.device == c32.device


# ----------------------------------------------------------------------------- gradients


def gradcheck(f, *args, eps=1e-6):
    """torch's gradcheck in float64 (fast mode: the Jacobian checked along random
    projections, both sides); ``eps`` 1e-7 where a step must keep R a rotation to 1e-6."""
    args = tuple(a.detach().clone().requires_grad_(True) for a in args)
    assert torch.autograd.gradcheck(f, args, eps=eps, atol=1e-6, rtol=1e-5, fast_mode=True)


def test_gradcheck_sh_basis():
    for lmax in (1, 3, 8):
        gradcheck(lambda d, lmax=lmax: sh_basis(d, lmax), T(unit(4)))


def test_gradcheck_rotation():
    q = T(quats(3))
    gradcheck(from_quaternion, q)
    gradcheck(lambda a, b, g: from_euler_zyz(a, b, g), T([0.3, 1.0]), T([1.1, 0.2]),
              T([-0.4, 2.0]))
    R = from_quaternion(q).detach()
    for lmax in (2, 4):
        gradcheck(lambda c, r: rotate(c, r), T(coeffs(lmax, batch=(3,))), R, eps=1e-7)
        gradcheck(lambda c, q: rotate(c, q), T(coeffs(lmax, batch=(3,))), q)
        gradcheck(lambda r, lmax=lmax: wigner_d(r, lmax), R, eps=1e-7)
    # through the Euler angles into a rotation of coefficients
    gradcheck(lambda b: rotate(T(coeffs(3)), from_euler_zyz(0.2, b, 0.5)), T(0.8))


def test_gradcheck_lighting():
    c, n = T(coeffs(3)), T(unit(6) * 1.5)
    gradcheck(irradiance, c, n)
    gradcheck(irradiance_matrix, T(coeffs(2, batch=(2,))))
    gradcheck(irradiance_quadratic, T(coeffs(2)), n)
    d, v, w = T(unit(20)), T(np.random.default_rng(4).normal(size=(20, 3))), T(np.ones(20))
    gradcheck(lambda d, v, w: project_samples(d, v, w, lmax=3), d, v, w)
    for kind in ("hann", "lanczos", "gaussian", "laplacian"):
        gradcheck(lambda s, kind=kind: window_factors(kind, 6, s), T(0.6))
    gradcheck(lambda c, f: convolve(c, f), c, T([1.0, 0.7, 0.4, 0.2]))


def test_gradient_of_rotation_angle_is_the_generator():
    """d/dt rotate(c, Rz(t)) at t = 0 is the infinitesimal z-rotation, a closed form: f(Rz(−t)u)
    shifts φ by −t, and ∂t cos m(φ−t) = m sin mφ, ∂t sin m(φ−t) = −m cos mφ, so the derivative
    of the coefficient of order m is −m a_l,−m."""
    from shprobe.sh import sh_lm

    lmax = 4
    c = T(coeffs(lmax, 1)[:, 0])
    t = T(0.0)
    jac = torch.autograd.functional.jacobian(
        lambda t: rotate(c, from_euler_zyz(t, 0.0, 0.0)), t)
    l, m = sh_lm(np.arange(25))
    want = -m * c.numpy()[l * (l + 1) - m]
    np.testing.assert_allclose(jac.numpy(), want, atol=1e-12)


# ----------------------------------------------------------------------------- policy


def test_nan_policy_on_tensors():
    c = T(coeffs(2))
    bad = c.clone()
    bad[3, 1] = float("nan")
    n = T(unit(4))
    nan_n = n.clone()
    nan_n[0, 0] = float("nan")
    for f in (lambda: irradiance(bad, n), lambda: irradiance(c, nan_n),
              lambda: irradiance_matrix(bad), lambda: rotate(bad, T(np.eye(3))),
              lambda: sh_basis(nan_n, 2), lambda: irradiance(c, torch.zeros(2, 3)),
              lambda: rotate(c, T(np.ones((3, 3)))), lambda: from_quaternion(torch.zeros(4))):
        with pytest.raises(ShprobeError):
            f()
    huge = T([[1e200, 1e200, 0.0]])
    close(sh_basis(huge, 4), sh_basis(np.array([[1.0, 1.0, 0.0]]) / np.sqrt(2), 4))
