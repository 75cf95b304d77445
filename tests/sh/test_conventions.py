"""Convention converters against pyshtools (when installed; it is in the `bench` extra), the
4π definition by quadrature, and the published CS-phase l ≤ 2 table
(google/spherical-harmonics HardcodedSH, DirectXMath XMSHEval)."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe import ShprobeError
from shprobe.sh import sh_basis
from shprobe.sh.conventions import (
    from_4pi,
    from_condon_shortley,
    from_shtools,
    to_4pi,
    to_condon_shortley,
    to_shtools,
)
from tests.conftest import random_dirs


def pyshtools():
    return pytest.importorskip("pyshtools", reason="pyshtools not installed (dev extra)")


def cs_table(d):
    """Condon–Shortley real SH to l = 2 as printed by google/spherical-harmonics."""
    x, y, z = d.T
    return np.stack([np.full_like(x, 0.282095), -0.488603 * y, 0.488603 * z, -0.488603 * x,
                     1.092548 * x * y, -1.092548 * y * z, 0.315392 * (3 * z * z - 1),
                     -1.092548 * x * z, 0.546274 * (x * x - y * y)], -1)


def angles(d):
    theta = np.degrees(np.arctan2(np.hypot(d[:, 0], d[:, 1]), d[:, 2]))
    phi = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    return theta, phi


def test_condon_shortley_matches_published_table():
    d = random_dirs(30, seed=1)
    c = np.random.default_rng(2).normal(size=(9, 3))
    f = sh_basis(d, 2) @ c
    g = cs_table(d) @ to_condon_shortley(c)
    np.testing.assert_allclose(f, g, atol=1e-5)
    np.testing.assert_array_equal(from_condon_shortley(to_condon_shortley(c)), c)
    assert to_condon_shortley(c.astype(np.float32)).dtype == np.float32
    assert to_condon_shortley(np.ones((2, 5, 16, 3))).shape == (2, 5, 16, 3)


@pytest.mark.parametrize("csphase", [1, -1])
def test_pyshtools_4pi_functions_are_sqrt4pi_times_ours(csphase):
    pysh = pyshtools()
    lmax = 12
    d = random_dirs(20, seed=3)
    ours = sh_basis(d, lmax)
    sign = to_condon_shortley(np.ones((lmax + 1) ** 2)) if csphase == -1 else 1.0
    for i, (t, p) in enumerate(zip(*angles(d), strict=True)):
        ylm = pysh.expand.spharm(lmax, t, p, normalization="4pi", kind="real",
                                 csphase=csphase)
        flat = from_shtools(ylm, normalization="ortho")  # just re-indexes (ortho, csphase=1)
        np.testing.assert_allclose(flat, np.sqrt(4 * np.pi) * sign * ours[i], atol=1e-12)


@pytest.mark.parametrize("norm,csphase", [("4pi", 1), ("4pi", -1), ("ortho", 1), ("ortho", -1)])
def test_to_shtools_expands_to_the_same_function(norm, csphase):
    pysh = pyshtools()
    lmax = 10
    c = np.random.default_rng(4).normal(size=((lmax + 1) ** 2, 2))
    cilm = to_shtools(c, normalization=norm, csphase=csphase)
    assert cilm.shape == (2, 2, lmax + 1, lmax + 1)
    d = random_dirs(25, seed=5)
    t, p = angles(d)
    want = sh_basis(d, lmax) @ c
    for ch in range(2):
        coeffs = pysh.SHCoeffs.from_array(cilm[ch], normalization=norm, csphase=csphase)
        got = coeffs.expand(lat=90 - t, lon=p)
        np.testing.assert_allclose(got, want[:, ch], atol=1e-11)
    np.testing.assert_allclose(from_shtools(cilm, norm, csphase), c, atol=1e-15)
    np.testing.assert_allclose(from_shtools(to_shtools(c[:, 0], norm, csphase), norm, csphase),
                               c[:, 0], atol=1e-15)


@pytest.mark.parametrize("csphase", [1, -1])
def test_4pi_definition_by_quadrature(csphase):
    # the function with 4π coefficient e_k is Y^4π_k: (1/4π)∫ Y_j Y_k = δ_jk, and
    # Y^4π_k = s_k √(4π) y_k with s_k = +1 (csphase 1) or (−1)^|m| (csphase −1)
    lmax = 6
    K = (lmax + 1) ** 2
    z, w = np.polynomial.legendre.leggauss(lmax + 2)
    phi = np.arange(2 * lmax + 2) * np.pi / (lmax + 1)
    s = np.sqrt(1 - z * z)
    u = np.stack(np.broadcast_arrays(s[:, None] * np.cos(phi), s[:, None] * np.sin(phi),
                                     z[:, None]), -1).reshape(-1, 3)
    wt = np.repeat(w * np.pi / (lmax + 1), 2 * lmax + 2)
    Y4 = sh_basis(u, lmax) @ from_4pi(np.eye(K), csphase=csphase)  # column k = Y^4π_k(u)
    np.testing.assert_allclose((Y4 * wt[:, None]).T @ Y4 / (4 * np.pi), np.eye(K), atol=1e-13)
    sign = to_condon_shortley(np.ones(K)) if csphase == -1 else np.ones(K)
    np.testing.assert_allclose(Y4, np.sqrt(4 * np.pi) * sign * sh_basis(u, lmax), atol=1e-13)


@pytest.mark.parametrize("csphase", [1, -1])
def test_flat_4pi_round_trip_and_relation(csphase):
    c = np.random.default_rng(6).normal(size=(25, 3))
    a = to_4pi(c, csphase=csphase)
    np.testing.assert_allclose(from_4pi(a, csphase=csphase), c, atol=1e-15)
    cilm = to_shtools(c[:, 0], "4pi", csphase)
    np.testing.assert_allclose(from_shtools(cilm, "ortho", 1), a[:, 0], atol=1e-15)


def test_bad_inputs():
    with pytest.raises(ShprobeError):
        to_4pi(np.ones(10))
    with pytest.raises(ShprobeError):
        to_4pi(np.ones(9), csphase=0)
    with pytest.raises(ShprobeError):
        to_shtools(np.ones(9), normalization="schmidt")
    with pytest.raises(ShprobeError):
        from_shtools(np.ones((3, 3, 3)))
