"""Lighting design (R&H §3.3), analytic lights, windows and the min-E certificate."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.lighting.design import (
    blend,
    cone_light,
    directional_light,
    negate_band,
    negate_coeff,
    scale_band,
    scale_coeff,
    set_band,
    set_coeff,
    sky_light,
)
from shprobe.lighting.irradiance import shade_irradiance
from shprobe.lighting.windows import (
    WINDOWS,
    auto_window,
    min_irradiance,
    window_bias,
    window_factors,
)
from shprobe.sh import sh_basis
from tests.conftest import random_dirs


def project_latlong(path, lmax):
    """Brute-force projection of a lat-long probe (R&H eq. 10 as a Riemann sum), written out
    here independently of shprobe.lighting.projection: row 0 = +Y, u = 0.5 → −Z, u = 0.75 → +X."""
    import OpenImageIO as oiio

    img = oiio.ImageBuf(str(path)).get_pixels(oiio.FLOAT)[:, :, :3].astype(np.float64)
    H, W = img.shape[:2]
    th = np.pi * (np.arange(H) + 0.5) / H
    a = 2 * np.pi * ((np.arange(W) + 0.5) / W - 0.5)
    T, A = np.meshgrid(th, a, indexing="ij")
    d = np.stack([np.sin(T) * np.sin(A), np.cos(T), -np.sin(T) * np.cos(A)], -1)
    dw = (2 * np.pi / W) * (np.pi / H) * np.sin(T)
    Y = sh_basis(d.reshape(-1, 3), lmax) * dw.reshape(-1, 1)
    return Y.T @ img.reshape(-1, 3)


def fine_sphere(n=300):
    """(n·2n) directions on a θ-φ grid (poles dense, no gap wider than π/n)."""
    th = np.linspace(0, np.pi, n)
    ph = np.linspace(0, 2 * np.pi, 2 * n, endpoint=False)
    T, P = np.meshgrid(th, ph, indexing="ij")
    return np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)


def test_coefficient_and_band_edits():
    L = np.arange(27, dtype=float).reshape(9, 3)
    out = set_coeff(L, 1, 1, [7, 8, 9])
    np.testing.assert_array_equal(out[3], [7, 8, 9])
    assert L[3, 0] == 9  # input untouched
    np.testing.assert_array_equal(scale_coeff(L, 2, -1, 2)[5], 2 * L[5])
    np.testing.assert_array_equal(negate_coeff(L, 0, 0)[0], -L[0])
    np.testing.assert_array_equal(scale_band(L, 2, 0)[4:], 0)
    np.testing.assert_array_equal(negate_band(L, 1)[1:4], -L[1:4])
    np.testing.assert_array_equal(set_band(L, 1, 0.5)[1:4], 0.5)
    grown = set_coeff(L, 3, -2, 1.0)
    assert grown.shape == (16, 3) and grown[3 * 4 - 2, 1] == 1.0
    np.testing.assert_array_equal(grown[:9], L)
    with pytest.raises(ShprobeError):
        set_coeff(L, 1, 2, 1.0)
    with pytest.raises(ShprobeError):
        set_coeff(L, 1, 1, [1, 2])
    # negating band 1 mirrors the lighting through the origin: E(n) -> E(-n) for l <= 2
    n = random_dirs(50)
    np.testing.assert_allclose(shade_irradiance(negate_band(L, 1), n, np.float64),
                               shade_irradiance(L, -n, np.float64), atol=1e-10)


def _cone_quadrature(axis, zeta, lmax, nt=40, nphi=64):
    """Exact quadrature of the cone indicator's SH projection in a frame around the axis:
    Gauss–Legendre in t = cos θ on [cos ζ, 1], uniform in φ."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    e1 = np.cross(a, [1.0, 0.3, 0.2])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    x, w = np.polynomial.legendre.leggauss(nt)
    c = np.cos(zeta)
    t = c + (x + 1) * (1 - c) / 2
    wt = w * (1 - c) / 2
    ph = 2 * np.pi * np.arange(nphi) / nphi
    T, P = np.meshgrid(t, ph, indexing="ij")
    s = np.sqrt(1 - T**2)
    d = (T[..., None] * a + s[..., None] * (np.cos(P)[..., None] * e1
                                             + np.sin(P)[..., None] * e2))
    W = wt[:, None] * (2 * np.pi / nphi) * np.ones_like(P)
    return (sh_basis(d.reshape(-1, 3), lmax) * W.reshape(-1, 1)).sum(0)


@pytest.mark.parametrize("zeta", [0.1, 0.7, np.pi / 2, 2.5])
def test_cone_light_matches_quadrature(zeta):
    axis = [0.3, -0.5, 0.8]
    got = cone_light(axis, zeta, [1.0, 2.0], lmax=6)
    ref = _cone_quadrature(axis, zeta, 6)
    np.testing.assert_allclose(got[:, 0], ref, atol=1e-12)
    np.testing.assert_allclose(got[:, 1], 2 * ref, atol=1e-12)


def test_directional_light_and_small_cone_limit():
    d = np.array([1.0, 2.0, -0.5])
    L = directional_light(d, [3.0, 1.0, 0.5], lmax=3)
    np.testing.assert_allclose(L[:, 0], 3 * sh_basis(d / np.linalg.norm(d), 3))
    # a tiny cone of the same total power converges to the directional light
    zeta = 1e-3
    cone = cone_light(d, zeta, 3.0 / (2 * np.pi * (1 - np.cos(zeta))), lmax=3)
    np.testing.assert_allclose(cone[:, 0], L[:, 0], rtol=1e-5, atol=1e-7)


def test_sky_light_closed_forms():
    # uniform radiance 1: L00 = √(4π), E = π everywhere (R&H: Â_0 L00 y00)
    L = sky_light(sky=1.0, ground=1.0)
    np.testing.assert_allclose(L[0, 0], np.sqrt(4 * np.pi))
    np.testing.assert_allclose(L[1:, 0], 0, atol=1e-12)
    # sky only, up = +Y: band moments 2π(1 − 0), 2π(P0(0) − P2(0))/3 = π, 2π(P1(0) − P3(0))/5 = 0
    S = sky_light(up=[0, 1, 0], sky=1.0, ground=0.0, lmax=2)
    np.testing.assert_allclose(S[0, 0], np.sqrt(4 * np.pi) / 2)
    np.testing.assert_allclose(S[1, 0], np.pi * np.sqrt(3 / (4 * np.pi)))  # L_1,-1 (y axis)
    np.testing.assert_allclose(S[[2, 3], 0], 0, atol=1e-12)
    np.testing.assert_allclose(S[4:, 0], 0, atol=1e-12)


def test_blend_is_linear_and_pads():
    a = directional_light([0, 1, 0], 1.0, lmax=1)
    b = sky_light(lmax=2)
    out = blend([(a, 2.0), (b, 0.5)])
    assert out.shape == (9, 1)
    np.testing.assert_allclose(out[:4], 2 * a + 0.5 * b[:4])
    np.testing.assert_allclose(out[4:], 0.5 * b[4:])
    with pytest.raises(ShprobeError):
        blend([])


def test_window_factors_shapes_and_limits():
    for kind in WINDOWS:
        np.testing.assert_array_equal(window_factors(kind, 4, 0.0), np.ones(5))
        w = window_factors(kind, 4, 0.5)
        assert w[0] == 1 and np.all(np.diff(w) <= 1e-15) and np.all(w >= 0)
    hann = [1, 0.5 * (1 + np.cos(np.pi / 3)), 0.5 * (1 + np.cos(2 * np.pi / 3))]
    np.testing.assert_allclose(window_factors("hann", 2, 1.0), hann)
    np.testing.assert_allclose(window_factors("lanczos", 2, 1.0),
                               [1, np.sin(np.pi / 3) / (np.pi / 3),
                                np.sin(2 * np.pi / 3) / (2 * np.pi / 3)])
    np.testing.assert_allclose(window_factors("gaussian", 2, 0.1), np.exp([0, -0.2, -0.6]))
    np.testing.assert_allclose(window_factors("laplacian", 2, 0.1), [1, 1 / 1.4, 1 / 4.6])
    np.testing.assert_array_equal(window_factors("hann", 2, 3.0), [1, 0, 0])
    with pytest.raises(ShprobeError):
        window_factors("box", 2, 1.0)
    L = np.random.default_rng(1).normal(size=(9, 3))
    assert window_bias(L, np.ones(3)) == 0
    assert 0 < window_bias(L, window_factors("hann", 2, 1.0)) < 1


@pytest.mark.parametrize("seed", range(6))
def test_certificate_lmax2_against_brute_force(seed):
    rng = np.random.default_rng(seed)
    L = rng.normal(size=(9, 3))
    L[0] += rng.uniform(0, 3)
    cert = min_irradiance(L)
    assert cert.exact
    pts = fine_sphere(300)
    brute = shade_irradiance(L, pts, np.float64).min(0)
    # the bound is below every sampled value, and the grid gets within its resolution of it
    assert np.all(cert.lower_bound <= brute + 1e-12)
    assert np.all(brute - cert.lower_bound < 1e-3 * (1 + np.abs(L).sum(0)))
    np.testing.assert_allclose(cert.minimum, cert.lower_bound, atol=1e-9)
    at = np.array([shade_irradiance(L[:, c], cert.direction[c], np.float64) for c in range(3)])
    np.testing.assert_allclose(at, cert.minimum, atol=1e-12)


def test_certificate_hard_case():
    """Only L00 and L20 (> 0): A = diag(0, 0, c3 L20), b = 0 — the trust-region hard case;
    the minimum c4 L00 − c5 L20 lies on the whole equator z = 0."""
    L = np.zeros((9, 1))
    L[0], L[6] = 0.2, 1.0
    cert = min_irradiance(L)
    c4, c5 = np.pi / (2 * np.sqrt(np.pi)), (np.pi / 4) * np.sqrt(5 / (16 * np.pi))
    np.testing.assert_allclose(cert.minimum, c4 * 0.2 - c5, atol=1e-12)
    np.testing.assert_allclose(cert.lower_bound, c4 * 0.2 - c5, atol=1e-9)
    assert abs(cert.direction[0, 2]) < 1e-9


def test_certificate_higher_lmax_numerical():
    L = np.random.default_rng(7).normal(size=(25, 2))
    L[0] += 2
    cert = min_irradiance(L)
    assert not cert.exact
    brute = shade_irradiance(L, fine_sphere(400), np.float64).min(0)
    assert np.all(cert.minimum <= brute + 1e-12)
    assert np.all(brute - cert.minimum < 1e-3)


def test_ennis_rings_at_lmax2_and_auto_window_fixes_it(ennis_path):
    L = project_latlong(ennis_path, 2)
    before = min_irradiance(L)
    assert before.minimum.min() < 0 and not before.nonnegative
    choice = auto_window(L)
    assert choice.kind in WINDOWS and choice.strength > 0
    assert choice.after.nonnegative and np.all(choice.after.lower_bound >= 0)
    assert 0 < choice.bias < 0.5
    windowed = L * choice.factors[[0, 1, 1, 1, 2, 2, 2, 2, 2]][:, None]
    assert shade_irradiance(windowed, fine_sphere(200), np.float64).min() >= -1e-9
    # the mildest: every other kind tried costs at least as much bias
    assert all(b >= choice.bias for _, b in choice.candidates.values())
    # a slightly weaker window of the same kind is not enough
    weaker = window_factors(choice.kind, 2, choice.strength * 0.95)
    assert not min_irradiance(L * weaker[[0, 1, 1, 1, 2, 2, 2, 2, 2]][:, None]).nonnegative


def test_auto_window_leaves_positive_lighting_alone(grace_path):
    L = project_latlong(grace_path, 2)
    choice = auto_window(L)
    assert choice.kind == "none" and choice.bias == 0
    assert choice.before.minimum.min() > 0
