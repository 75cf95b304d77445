"""The library's one bad-value policy on the NumPy path of the SH functions: NaN or infinite
coefficients or directions are one ShprobeError (as normals always were), object arrays are a
ShprobeError rather than numpy's ValueError, and huge directions are normalised without
overflow."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.lighting.irradiance import irradiance, irradiance_matrix, irradiance_quadratic
from shprobe.sh import sh_basis
from shprobe.sh.rotation import rotate
from tests.tensors.tensor_support import coeffs, unit

R = np.eye(3)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_coefficients_refused(bad):
    c = coeffs(2)
    c[4, 1] = bad
    n = unit(3)
    for f in (lambda: irradiance(c, n), lambda: irradiance(c[:, 1], n),
              lambda: irradiance_matrix(c), lambda: irradiance_quadratic(c, n),
              lambda: rotate(c, R), lambda: rotate(c[None], R[None]),
              lambda: rotate(c.astype(np.float32), R)):
        with pytest.raises(ShprobeError, match="NaN or infinity"):
            f()


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_directions_refused(bad):
    d = unit(5)
    d[2, 1] = bad
    for lmax in (2, 12):
        with pytest.raises(ShprobeError):
            sh_basis(d, lmax)
    with pytest.raises(ShprobeError):
        sh_basis(d.astype(np.float32), 3)
    with pytest.raises(ShprobeError):
        irradiance(coeffs(2), d)


def test_object_arrays_are_one_error():
    junk = np.array([[object(), 1.0, 2.0]], dtype=object)
    with pytest.raises(ShprobeError):
        sh_basis(junk, 2)
    with pytest.raises(ShprobeError):
        rotate(np.array([object()] * 9, dtype=object), R)
    with pytest.raises(ShprobeError):
        rotate(coeffs(1), np.array([[object()] * 3] * 3, dtype=object))
    # numbers held in an object array are numbers
    ok = np.array([[0.0, 0.0, 1.0]], dtype=object)
    np.testing.assert_array_equal(sh_basis(ok, 2), sh_basis(np.array([[0.0, 0.0, 1.0]]), 2))


def test_huge_directions_normalised_without_overflow():
    for v in ([1e200, 1e200, 0.0], [0.0, -3e300, 4e300], [1e30, 0.0, 0.0]):
        d = np.array([v])
        u = d / np.abs(d).max()
        u /= np.linalg.norm(u)
        for lmax in (2, 8, 20):
            got = sh_basis(d, lmax)
            assert np.all(np.isfinite(got))
            np.testing.assert_allclose(got, sh_basis(u, lmax), atol=1e-14)
    f32 = np.array([[3e20, 0.0, 4e20]], dtype=np.float32)  # squares overflow float32
    np.testing.assert_allclose(sh_basis(f32, 3), sh_basis(np.array([[0.6, 0.0, 0.8]]), 3),
                               atol=1e-6)
    # unit directions are used as given, bit for bit (the fast path)
    d = unit(100)
    out = sh_basis(d, 5)
    from shprobe.sh._kernels_unrolled import KERNELS

    ref = np.empty_like(out)
    KERNELS[5](np.ascontiguousarray(d), ref)
    np.testing.assert_array_equal(out, ref)
