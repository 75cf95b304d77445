"""Zonal functions (LH §3, R&H eq. 5–9) against the papers' numbers, scipy quadrature and
direct quadrature on the sphere."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate
from scipy.special import eval_legendre

from shprobe import ShprobeError
from shprobe.sh import sh_basis
from shprobe.sh.zonal import (
    circular_window,
    clamped_cosine_factors,
    clamped_cosine_H,
    convolve,
    legendre_moments,
    window_moments,
    zonal_coeffs,
    zonal_from_moments,
)
from tests.conftest import random_dirs


def frame(n):
    """Orthonormal (t, b, n) with n the given unit axis."""
    a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    t = np.cross(a, n)
    t /= np.linalg.norm(t)
    return t, np.cross(n, t), n


def cap_quadrature(n, z0, nz=60, nphi=120):
    """Nodes/weights on {u : u·n > z0}: Gauss–Legendre in u·n on [z0, 1] × uniform φ."""
    x, w = np.polynomial.legendre.leggauss(nz)
    z = 0.5 * (1 - z0) * x + 0.5 * (1 + z0)
    w = 0.5 * (1 - z0) * w
    phi = (np.arange(nphi) + 0.5) * 2 * np.pi / nphi
    s = np.sqrt(1 - z * z)
    t, b, nn = frame(n)
    u = (s[:, None, None] * np.cos(phi)[None, :, None] * t
         + s[:, None, None] * np.sin(phi)[None, :, None] * b + z[:, None, None] * nn)
    return u.reshape(-1, 3), np.repeat(w * 2 * np.pi / nphi, nphi)


def test_rh_eq9_numbers():
    want = [3.141593, 2.094395, 0.785398, 0, -0.130900, 0, 0.049087]
    np.testing.assert_allclose(clamped_cosine_factors(6), want, atol=5e-7)


def test_a_hat_closed_form_equals_pi_H_recurrence():
    np.testing.assert_allclose(clamped_cosine_factors(60), np.pi * clamped_cosine_H(60),
                               rtol=1e-13, atol=1e-16)


def test_H_against_scipy_quad():
    for l in range(12):
        ref = 2 * integrate.quad(lambda z, l=l: z * eval_legendre(l, z), 0, 1, epsabs=1e-14)[0]
        assert abs(clamped_cosine_H(11)[l] - ref) < 1e-12


def test_legendre_moments_against_scipy_quad():
    def h(z):
        return np.exp(1.3 * z) * (1 + z * z)

    got = legendre_moments(h, 20)
    for l in range(21):
        ref = 2 * np.pi * integrate.quad(lambda z, l=l: h(z) * eval_legendre(l, z), -1, 1,
                                         epsabs=1e-14, limit=200)[0]
        assert abs(got[l] - ref) < 1e-11
    # the clamped cosine with the interval at its kink gives Â_l exactly
    np.testing.assert_allclose(legendre_moments(lambda z: z, 12, interval=(0.0, 1.0)),
                               clamped_cosine_factors(12), atol=1e-14)


def test_zonal_coeffs_equal_sphere_quadrature():
    lmax = 10
    axes = random_dirs(2, seed=3)

    def h(z):
        return np.exp(2.0 * z) + np.sin(3 * z)

    got = zonal_coeffs(h, axes, lmax)
    assert got.shape == (2, (lmax + 1) ** 2)
    z, w = np.polynomial.legendre.leggauss(50)
    phi = (np.arange(100) + 0.5) * np.pi / 50
    s = np.sqrt(1 - z * z)
    u = np.stack(np.broadcast_arrays(s[:, None] * np.cos(phi), s[:, None] * np.sin(phi),
                                     z[:, None]), -1).reshape(-1, 3)
    wt = np.repeat(w * np.pi / 50, 100)
    Y = sh_basis(u, lmax)
    for i in range(2):
        want = (wt * h(u @ axes[i])) @ Y
        np.testing.assert_allclose(got[i], want, atol=1e-12)


@pytest.mark.parametrize("aperture", [0.05, 0.4, 1.2, np.pi / 2, 2.5, np.pi])
def test_circular_window_equals_cap_quadrature(aperture):
    lmax = 12
    n = random_dirs(1, seed=5)[0]
    got = circular_window(n, aperture, lmax)
    z0 = np.cos(aperture)
    u, wt = cap_quadrature(n, z0)
    want = 2 / (1 - z0) * (wt @ sh_basis(u, lmax))
    np.testing.assert_allclose(got, want, atol=1e-11)
    # LH normalisation: total power ∫ L = a_00 √(4π) = 4π
    assert abs(got[0] * np.sqrt(4 * np.pi) - 4 * np.pi) < 1e-12
    # power scales; a constant radiance gives radiance × cap integral, colours add an axis
    np.testing.assert_allclose(circular_window(n, aperture, lmax, power=2.0),
                               got * 2.0 / (4 * np.pi), atol=1e-14)
    rgb = circular_window(n, aperture, lmax, radiance=[1.0, 0.5, 2.0])
    assert rgb.shape == ((lmax + 1) ** 2, 3)
    np.testing.assert_allclose(rgb[:, 1], 0.5 * (wt @ sh_basis(u, lmax)), atol=1e-11)


def test_window_recurrence_against_scipy_quad_high_degree():
    zeta = 0.3
    z0 = np.cos(zeta)
    got = window_moments(zeta, 60)
    for l in (0, 1, 2, 7, 30, 60):
        ref = 4 * np.pi / (1 - z0) * integrate.quad(lambda z, l=l: eval_legendre(l, z), z0, 1,
                                                   epsabs=1e-15, limit=200)[0]
        assert abs(got[l] - ref) < 1e-10


def test_zonal_from_moments_batched_and_normalised():
    mom = np.arange(1.0, 5.0)
    axes = 3.0 * random_dirs(6, seed=7).reshape(2, 3, 3)
    b = zonal_from_moments(mom, axes)
    assert b.shape == (2, 3, 16)
    deg = np.repeat(np.arange(4), 2 * np.arange(4) + 1)
    np.testing.assert_allclose(b, mom[deg] * sh_basis(axes / 3.0, 3), atol=1e-15)


def test_convolve_gives_the_hemispherical_integral():
    """For lighting band-limited to l ≤ 4, E(n) = Σ Â_l L_lm y_lm(n) (Funk–Hecke) equals
    ∫ L(ω) max(n·ω, 0) dω by quadrature over the hemisphere about n."""
    lmax = 4
    L = np.random.default_rng(71).normal(size=((lmax + 1) ** 2, 2))
    E = convolve(L, clamped_cosine_factors(lmax))
    for n in random_dirs(5, seed=72):
        u, w = cap_quadrature(n, 0.0, nz=40, nphi=80)
        want = (sh_basis(u, lmax) @ L * ((u @ n) * w)[:, None]).sum(0)
        np.testing.assert_allclose(sh_basis(n, lmax) @ E, want, rtol=1e-12, atol=1e-12)


def test_float32_axis_gives_float32():
    ax = np.array([0.3, -0.5, 0.8], np.float32)
    for c in (circular_window(ax, 0.4, 6), circular_window(ax, 0.4, 6, radiance=[1, 2, 3]),
              zonal_coeffs(lambda z: z * z, ax, 6)):
        assert c.dtype == np.float32
    np.testing.assert_allclose(circular_window(ax, 0.4, 6),
                               circular_window(ax.astype(np.float64), 0.4, 6), rtol=1e-6,
                               atol=1e-7)


def test_bad_inputs():
    with pytest.raises(ShprobeError):
        circular_window([0, 0, 1], 0.0, 4)
    with pytest.raises(ShprobeError):
        circular_window([0, 0, 0], 0.5, 4)
    with pytest.raises(ShprobeError):
        legendre_moments(lambda z: z, 4, interval=(0.5, 0.2))
    with pytest.raises(ShprobeError):
        legendre_moments(lambda z: np.ones(3), 4)
    with pytest.raises(ShprobeError):
        zonal_from_moments(np.ones((2, 2)), [0, 0, 1])


def test_window_recurrence_equals_prop32_quadrature():
    # LH eq. 11 recurrence vs Gauss–Legendre of the cap indicator on [cos ζ, 1] (Prop. 3.2)
    n = random_dirs(3, seed=8)
    for zeta in (0.2, 1.0, 2.0):
        want = zonal_coeffs(lambda z: np.ones_like(z), n, 20, interval=(np.cos(zeta), 1.0))
        np.testing.assert_allclose(circular_window(n, zeta, 20, radiance=1.0), want,
                                   atol=1e-12)
