"""H-basis (Habel & Wimmer 2010): basis, T_h, rivals and the Fig. 3 study, checked against
independent quadratures (Gauss–Legendre in θ rather than in z) and closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.hbasis import all_bases, get_basis, h_basis, project_h, sh_to_h, sh_to_h_matrix
from shprobe.hbasis.basis import T_H4_PAPER
from shprobe.hbasis.study import imse, random_irradiance, run_study, vmf_moments
from shprobe.sh import sh_basis
from shprobe.zonal import clamped_cosine_factors

from .conftest import random_dirs


def theta_quadrature(n_theta=60, n_phi=64, sphere=False):
    """Independent rule: Gauss–Legendre in θ ∈ [0, π/2] (or [0, π]) with sin θ, uniform φ."""
    t, w = np.polynomial.legendre.leggauss(n_theta)
    top = np.pi if sphere else np.pi / 2
    th = 0.5 * top * (t + 1)
    wt = 0.5 * top * w * np.sin(th)
    ph = 2 * np.pi * (np.arange(n_phi) + 0.25) / n_phi
    T, P = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    return d, np.repeat(wt, n_phi) * (2 * np.pi / n_phi), T.ravel(), P.ravel()


def test_h_matches_paper_formulas():
    d, _, th, ph = theta_quadrature(7, 9)
    c = np.sqrt(3 / (2 * np.pi))
    expect = np.stack([
        np.full_like(th, 1 / np.sqrt(2 * np.pi)),                       # eq. 8
        -c * np.sin(ph) * np.sin(th),                                    # eq. 9
        c * (2 * np.cos(th) - 1),                                        # eq. 10 (root on const)
        -c * np.cos(ph) * np.sin(th),                                    # eq. 11
        0.5 * np.sqrt(15 / (2 * np.pi)) * np.sin(2 * ph) * np.sin(th) ** 2,  # eq. 12
        0.5 * np.sqrt(15 / (2 * np.pi)) * np.cos(2 * ph) * np.sin(th) ** 2,  # eq. 13
    ], -1)
    np.testing.assert_allclose(h_basis(d), expect, atol=1e-14)
    np.testing.assert_allclose(h_basis(d, 4), expect[:, :4], atol=1e-14)
    assert h_basis(d.astype(np.float32)).dtype == np.float32
    # large batches go through the numba kernel: same formulas, any leading shape, float32
    big = random_dirs(2 * 4096, seed=8).reshape(2, 4096, 3)
    x, y, z = big[..., 0], big[..., 1], big[..., 2]
    ref = np.stack([np.full_like(x, 1 / np.sqrt(2 * np.pi)), -c * y, c * (2 * z - 1), -c * x,
                    np.sqrt(15 / (2 * np.pi)) * x * y,
                    0.5 * np.sqrt(15 / (2 * np.pi)) * (x * x - y * y)], -1)
    np.testing.assert_allclose(h_basis(big), ref, atol=1e-14)
    np.testing.assert_allclose(h_basis(big[..., ::-1][..., ::-1], 4), ref[..., :4], atol=1e-14)
    np.testing.assert_allclose(h_basis(big.astype(np.float32)), ref, atol=1e-6)
    with pytest.raises(ShprobeError):
        h_basis(d, 5)


def test_h_orthonormal_on_hemisphere():
    d, w, _, _ = theta_quadrature()
    b = h_basis(d)
    np.testing.assert_allclose((b * w[:, None]).T @ b, np.eye(6), atol=1e-12)


def test_t_h_against_independent_projection_and_closed_form():
    d, w, _, _ = theta_quadrature()
    t = (h_basis(d) * w[:, None]).T @ sh_basis(d, 2)
    np.testing.assert_allclose(sh_to_h_matrix(), t, atol=1e-12)
    r2 = 1 / np.sqrt(2)
    th = sh_to_h_matrix()
    # the derivation in docs/hbasis.md
    assert th[0, 0] == pytest.approx(r2) and th[0, 2] == pytest.approx(np.sqrt(6) / 4)
    assert th[1, 1] == pytest.approx(-r2) and th[1, 5] == pytest.approx(-3 * np.sqrt(10) / 16)
    assert th[2, 2] == pytest.approx(np.sqrt(2) / 4) and th[2, 6] == pytest.approx(np.sqrt(30) / 8)
    assert th[3, 3] == pytest.approx(-r2) and th[3, 7] == pytest.approx(-3 * np.sqrt(10) / 16)
    assert th[4, 4] == pytest.approx(r2) and th[5, 8] == pytest.approx(r2)
    assert np.count_nonzero(th) == 10
    np.testing.assert_array_equal(sh_to_h_matrix(2, 4), th[:4])


def test_t_h_l4_block_is_appendix_a_with_m_pm1_flipped():
    d, w, _, _ = theta_quadrature()
    t4 = (h_basis(d) * w[:, None]).T @ sh_basis(d, 4)[:, 16:25]
    np.testing.assert_allclose(sh_to_h_matrix(4)[:, 16:25], t4, atol=1e-12)
    flip = np.ones(9)
    flip[[3, 5]] = -1  # columns m = -1, +1: Condon–Shortley phase of the paper's SH
    np.testing.assert_allclose(t4, T_H4_PAPER * flip, atol=1e-12)
    np.testing.assert_allclose(sh_to_h_matrix(4)[:, :9], sh_to_h_matrix(2), atol=1e-14)


def test_span_of_h6_survives_sh_to_h_to_evaluate(rng):
    c = rng.normal(size=(6, 3))
    # SH coefficients of f = Σ c_i Hⁱ over the whole sphere, by least squares on the sphere
    sd = random_dirs(200, seed=3)
    s, *_ = np.linalg.lstsq(sh_basis(sd, 2), h_basis(sd) @ c, rcond=None)
    np.testing.assert_allclose(sh_to_h(s), c, atol=1e-12)
    # a large batch (numba path) equals T_h @ s for every item
    batch = rng.normal(size=(3, 2000, 9, 2))
    want = np.einsum("ij,...jc->...ic", sh_to_h_matrix(), batch)
    np.testing.assert_allclose(sh_to_h(batch), want, atol=1e-13)
    np.testing.assert_allclose(sh_to_h(batch, 4)[1, 7], sh_to_h_matrix(2, 4) @ batch[1, 7],
                               atol=1e-13)
    d, _, _, _ = theta_quadrature(9, 11)
    np.testing.assert_allclose(h_basis(d) @ sh_to_h(s), h_basis(d) @ c, atol=1e-12)
    # project_h of the same function by quadrature
    np.testing.assert_allclose(project_h(lambda v: h_basis(v) @ c), c, atol=1e-12)


def test_rivals_gram_and_definitions():
    d, w, _, _ = theta_quadrature(80, 128)
    for b in all_bases().values():
        B = b.evaluate(d)
        g = (B * w[:, None]).T @ B
        if b.orthonormal:
            np.testing.assert_allclose(g, np.eye(b.n_coeffs), atol=1e-10, err_msg=b.name)
        else:
            assert np.linalg.eigvalsh(g).min() > 1e-3, b.name  # a basis, not orthonormal
        assert B.shape == (len(d), b.n_coeffs)
    # Makhotkin: orthonormal for the cosine-weighted measure z dω
    for name in ("Makhotkin2", "Makhotkin3"):
        B = get_basis(name).evaluate(d)
        np.testing.assert_allclose((B * (w * d[:, 2])[:, None]).T @ B,
                                   np.eye(B.shape[1]), atol=1e-10)
    h = h_basis(d)
    hl2 = np.sqrt(3 / (2 * np.pi)) * np.stack(
        [d @ np.array([-1 / np.sqrt(6), -1 / np.sqrt(2), 1 / np.sqrt(3)]),
         d @ np.array([-1 / np.sqrt(6), 1 / np.sqrt(2), 1 / np.sqrt(3)]),
         d @ np.array([np.sqrt(2 / 3), 0, 1 / np.sqrt(3)])], -1)
    np.testing.assert_allclose(get_basis("hl2").evaluate(d), hl2, atol=1e-14)
    # paper §4: HSH (l=1, m=0) is H³, Zernike (n=2, m=0) is −H³; both start with H¹
    hsh = get_basis("HSH2").evaluate(d)
    np.testing.assert_allclose(hsh[:, 2], h[:, 2], atol=1e-12)
    np.testing.assert_allclose(hsh[:, 0], h[:, 0], atol=1e-12)
    z6 = get_basis("Zernike6").evaluate(d)
    np.testing.assert_allclose(z6[:, 4], -h[:, 2], atol=1e-12)
    # Zernike n=1: ρ cos φ with ρ = √(1 − z) is x / √(1 + z)
    np.testing.assert_allclose(z6[:, 2], np.sqrt(2 / np.pi) * d[:, 0] / np.sqrt(1 + d[:, 2]),
                               atol=1e-12)
    with pytest.raises(ShprobeError):
        get_basis("nope")


def test_project_recovers_coefficients_in_span(rng):
    for b in all_bases().values():
        c = rng.normal(size=(b.n_coeffs, 2))
        got = b.project(lambda v, b=b, c=c: b.evaluate(v) @ c)
        np.testing.assert_allclose(got, c, atol=1e-8, err_msg=b.name)


def test_lsq_linear_sh_equals_h4_and_sh_matrix_is_projection():
    e = random_irradiance(40, seed=5)
    a, b = imse(get_basis("H4"), e), imse(get_basis("SH4 (LSQ)"), e)
    np.testing.assert_allclose(a, b, rtol=1e-9)
    # Makhotkin spans HSH's space: fitted by least squares it has HSH's IMSE exactly, with its
    # own (cosine-weighted) projection more
    import dataclasses

    mk = get_basis("Makhotkin3")
    mk_lsq = dataclasses.replace(mk, name="Makhotkin3 (LSQ)", fit="hemisphere")
    np.testing.assert_allclose(imse(mk_lsq, e), imse(get_basis("HSH3"), e), rtol=1e-7)
    assert np.all(imse(mk, e) >= imse(mk_lsq, e) * (1 - 1e-9))
    # SH → H6 through the rival interface equals T_h on the l ≤ 16 signal
    np.testing.assert_allclose(get_basis("H6").sh_matrix(16), sh_to_h_matrix(16), atol=1e-12)


def test_vmf_moments_closed_form():
    k = np.array([4.0, 20.0, 64.0])
    m = vmf_moments(k, 2)
    np.testing.assert_allclose(m[:, 0], 1.0, rtol=1e-12)
    np.testing.assert_allclose(m[:, 1], 1 / np.tanh(k) - 1 / k, rtol=1e-12)  # Langevin
    # P2 moment: 1 − 3 (coth κ − 1/κ)/κ
    np.testing.assert_allclose(m[:, 2], 1 - 3 * (1 / np.tanh(k) - 1 / k) / k, rtol=1e-12)


def test_generator_is_exact_irradiance():
    """E from the generator equals the brute-force hemispherical integral of its lighting."""
    from shprobe.hbasis.study import random_lighting

    L = random_lighting(2, seed=11)[0]
    e = random_irradiance(2, seed=11)[0]
    ws, ww, _, _ = theta_quadrature(200, 400, sphere=True)
    rad = sh_basis(ws, 16) @ L  # the band-limited lighting
    n = random_dirs(5, seed=2)
    direct = np.maximum(n @ ws.T, 0) @ (rad * ww[:, None])
    np.testing.assert_allclose(sh_basis(n, 16) @ e, direct, rtol=2e-4)
    assert clamped_cosine_factors(16)[3] == 0


def test_imse_quadratic_form_matches_direct_integration():
    e = random_irradiance(3, seed=4)  # (3, K, 3)
    d, w, _, _ = theta_quadrature(80, 160)
    E = np.einsum("nk,skc->snc", sh_basis(d, 16), e)
    for name in ("H6", "HL2", "Zernike6", "HSH3", "SH9", "Makhotkin2"):
        b = get_basis(name)
        approx = np.einsum("ni,sic->snc", b.evaluate(d), b.sh_matrix(16) @ e)
        direct = np.einsum("n,snc->sc", w, (approx - E) ** 2)
        np.testing.assert_allclose(imse(b, e), direct, rtol=1e-6, err_msg=name)


def test_study_orders_bases_like_the_paper():
    r = run_study(600, seed=1)
    m = dict(zip(r.names, r.mean_imse, strict=True))
    assert m["H6"] < m["H4"] and m["H6"] < m["HL2"]
    assert m["H6"] < m["Zernike6"]  # lowest among 6-coefficient bases
    assert m["SH9"] < m["H6"] and m["HSH3"] > m["H6"]  # only quadratic SH below H6
    assert m["HL2"] == max(m.values())
    assert m["H4"] == pytest.approx(m["SH4 (LSQ)"], rel=1e-9)
    assert m["Zernike3"] < m["HL2"]
    assert "| 6 | H6 |" in r.markdown() and r.csv().startswith("basis,coefficients")
