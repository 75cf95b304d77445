"""The public SH functions on JAX arrays: the NumPy path's values, ``jax.grad`` against central
finite differences, and ``jax.jit`` of every function (traced once, same values)."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.lighting.irradiance import irradiance, irradiance_matrix, irradiance_quadratic
from shprobe.lighting.projection import project_samples
from shprobe.lighting.windows import window_factors
from shprobe.sh import sh_basis
from shprobe.sh.rotation import from_euler_zyz, from_quaternion, rotate, wigner_d
from shprobe.sh.zonal import clamped_cosine_factors, convolve
from tests.tensors.tensor_support import coeffs, need, quats, unit

jax = need("jax")
need("array_api_compat")
jax.config.update("jax_enable_x64", True)
jnp = jax.numpy

C = coeffs(3)
C2 = coeffs(2)
N = unit(8) * 1.3
Q = quats(4)
R = from_quaternion(Q)
D, V, W = unit(30, 5), np.random.default_rng(6).normal(size=(30, 3)), np.full(30, 0.1)

#: name → (function of JAX arrays, its NumPy arguments, the NumPy result)
CASES = {
    "sh_basis": (lambda d: sh_basis(d, 4), (N / 1.3,), sh_basis(N / 1.3, 4)),
    "from_quaternion": (from_quaternion, (Q,), R),
    "from_euler_zyz": (from_euler_zyz, (np.array([0.3, 1.0]), np.array([1.1, 0.2]),
                                        np.array([-0.4, 2.0])),
                       from_euler_zyz([0.3, 1.0], [1.1, 0.2], [-0.4, 2.0])),
    "wigner_d": (lambda r: wigner_d(r, 3), (R,), wigner_d(R, 3)),
    "rotate": (rotate, (coeffs(3, batch=(4,)), R), rotate(coeffs(3, batch=(4,)), R)),
    "rotate_q": (rotate, (coeffs(2, batch=(4,)), Q), rotate(coeffs(2, batch=(4,)), Q)),
    "irradiance": (irradiance, (C, N), irradiance(C, N)),
    "irradiance_matrix": (irradiance_matrix, (C2,), irradiance_matrix(C2)),
    "irradiance_quadratic": (irradiance_quadratic, (C2, N), irradiance_quadratic(C2, N)),
    "project_samples": (lambda d, v, w: project_samples(d, v, w, lmax=3), (D, V, W),
                        project_samples(D, V, W, lmax=3)),
    "convolve": (convolve, (C, clamped_cosine_factors(3)), convolve(C, clamped_cosine_factors(3))),
    "window_hann": (lambda s: window_factors("hann", 6, s), (np.float64(0.6),),
                    window_factors("hann", 6, 0.6)),
    "window_lanczos": (lambda s: window_factors("lanczos", 6, s), (np.float64(0.6),),
                       window_factors("lanczos", 6, 0.6)),
    "window_gaussian": (lambda s: window_factors("gaussian", 6, s), (np.float64(0.05),),
                        window_factors("gaussian", 6, 0.05)),
    "window_laplacian": (lambda s: window_factors("laplacian", 6, s), (np.float64(0.05),),
                         window_factors("laplacian", 6, 0.05)),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_values_and_jit(name):
    f, args, want = CASES[name]
    jargs = [jnp.asarray(a) for a in args]
    got = f(*jargs)
    assert isinstance(got, jax.Array) and got.dtype == jnp.float64
    np.testing.assert_allclose(np.asarray(got), want, rtol=1e-12, atol=1e-12)
    jitted = jax.jit(f)
    np.testing.assert_allclose(np.asarray(jitted(*jargs)), want, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name", sorted(CASES))
def test_grad_against_finite_differences(name):
    """jax.grad of a random linear read-out of the output, against central differences along
    a random direction of each argument."""
    f, args, want = CASES[name]
    if name in ("rotate", "wigner_d"):  # keep the matrix a rotation: differentiate the angle
        f = (lambda c, t: rotate(c, from_euler_zyz(t, 0.4, -0.7))) if name == "rotate" else (
            lambda t: wigner_d(from_euler_zyz(t, 0.4, -0.7), 3))
        args = (args[0], np.float64(0.3)) if name == "rotate" else (np.float64(0.3),)
        want = np.asarray(f(*[jnp.asarray(a) for a in args]))
    rng = np.random.default_rng(7)
    proj = jnp.asarray(rng.normal(size=np.shape(want)))
    for i in range(len(args)):
        def g(a, i=i):
            full = [jnp.asarray(x) for x in args]
            full[i] = a
            return jnp.sum(f(*full) * proj)

        x0 = jnp.asarray(args[i])
        grad = jax.grad(g)(x0)
        step = jnp.asarray(rng.normal(size=np.shape(args[i])))
        h = 1e-6
        fd = (g(x0 + h * step) - g(x0 - h * step)) / (2 * h)
        np.testing.assert_allclose(float(jnp.sum(grad * step)), float(fd), rtol=1e-6,
                                   atol=1e-7)
