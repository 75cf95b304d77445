"""H-basis (Habel & Wimmer 2010): basis, T_h, rivals and the Fig. 3 study, checked against
independent quadratures (Gauss–Legendre in θ rather than in z) and closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.hbasis import (
    all_bases,
    evaluate_h,
    get_basis,
    h_basis,
    project_h,
    sh_to_h,
    sh_to_h_matrix,
)
from shprobe.hbasis.basis import T_H4_PAPER
from shprobe.hbasis.normalmap import shade_h
from shprobe.hbasis.rivals import makhotkin_cosine
from shprobe.hbasis.study import (
    LMAX_SIGNAL,
    gram_report,
    imse,
    random_irradiance,
    random_signals,
    run_study,
    vmf_irradiance,
    vmf_moments,
)
from shprobe.sh import sh_basis
from shprobe.sh.zonal import clamped_cosine_factors
from tests.conftest import random_dirs


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
            assert np.abs(g - np.eye(b.n_coeffs)).max() > 0.1, b.name
        assert B.shape == (len(d), b.n_coeffs)
    # Makhotkin (shifted Jacobi P^(m,m)) is hemispherically orthonormal (H&W §2.2) ...
    for name in ("Makhotkin2", "Makhotkin3"):
        assert get_basis(name).orthonormal and get_basis(name).fit == "hemisphere"
    # ... and equals HSH function by function (independent code: scipy Jacobi vs shifted SH)
    np.testing.assert_allclose(get_basis("Makhotkin3").evaluate(d), get_basis("HSH3").evaluate(d),
                               atol=1e-12)
    # it is zero (m ≠ 0) or constant (m = 0) on the border z = 0
    ring = np.stack([np.cos(np.linspace(0, 6, 7)), np.sin(np.linspace(0, 6, 7)), np.zeros(7)], -1)
    mk = get_basis("Makhotkin3").evaluate(ring)
    np.testing.assert_allclose(mk[:, [1, 3, 4, 5, 7, 8]], 0, atol=1e-12)
    np.testing.assert_allclose(mk[:, [0, 2, 6]], mk[:1, [0, 2, 6]].repeat(7, 0), atol=1e-12)
    # the earlier, cosine-weighted reconstruction: orthonormal for z dω instead
    for nmax in (1, 2):
        B = makhotkin_cosine(nmax).evaluate(d)
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
    # Makhotkin = HSH, so the same IMSE; the cosine-weighted variant spans the same space but
    # its z dω projection is not the dω-optimal fit: never below
    np.testing.assert_allclose(imse(get_basis("Makhotkin3"), e), imse(get_basis("HSH3"), e),
                               rtol=1e-9)
    for nmax, name in ((1, "HSH2"), (2, "HSH3")):
        assert np.all(imse(makhotkin_cosine(nmax), e) >= imse(get_basis(name), e) * (1 - 1e-9))
    # SH → H6 through the rival interface equals T_h on the signal's bands
    np.testing.assert_allclose(get_basis("H6").sh_matrix(LMAX_SIGNAL),
                               sh_to_h_matrix(LMAX_SIGNAL), atol=1e-12)


def test_vmf_moments_closed_form_and_quadrature():
    from scipy.special import eval_legendre, ive

    k = np.array([0.5, 4.0, 20.0, 128.0, 3000.0])
    m = vmf_moments(k, 40)
    np.testing.assert_allclose(m[:, 0], 1.0, rtol=1e-14)
    np.testing.assert_allclose(m[:, 1], 1 / np.tanh(k) - 1 / k, rtol=1e-12)  # Langevin
    # P2 moment: 1 − 3 (coth κ − 1/κ)/κ
    np.testing.assert_allclose(m[:, 2], 1 - 3 * (1 / np.tanh(k) - 1 / k) / k, rtol=1e-12)
    # Bessel ratio I_{l+½}/I_{½} (scipy) ...
    l = np.arange(41)
    np.testing.assert_allclose(m, ive(l + 0.5, k[:, None]) / ive(0.5, k[:, None]), rtol=1e-11,
                               atol=1e-300)
    # ... and 2π ∫ v_κ P_l by Gauss–Legendre in u = κ(1 − t) on the lobe (κ = 20, 128)
    u, wu = np.polynomial.legendre.leggauss(200)
    for i in (2, 3):
        uu = 20 * (u + 1)  # u ∈ [0, 40]: e^{-40} of the peak beyond
        t = 1 - uu / k[i]
        v = k[i] * np.exp(-uu) / (2 * np.pi * -np.expm1(-2 * k[i]))
        q = 2 * np.pi * np.sum((20 * wu / k[i] * v)[:, None] * eval_legendre(l, t[:, None]), 0)
        np.testing.assert_allclose(m[i], q, atol=1e-12)
    with pytest.raises(ShprobeError):
        vmf_moments([1.0, 0.0], 2)


def theta_rule_sphere(n_theta, n_phi):
    d, w, _, _ = theta_quadrature(n_theta, n_phi, sphere=True)
    return d, w


def test_generator_radiance_is_non_negative_and_matches_its_sh():
    sig = random_signals(300, seed=7)
    assert sig.lobe_kappa.max() <= 128 and sig.ambient.min() > 0
    d = random_dirs(4000, seed=1)
    for i in range(0, 300, 7):
        # directions right on and around each of the signal's lobes, plus random ones
        ax = sig.lobe_axis[sig.lobe_signal == i]
        near = (ax[:, None, :] + 0.05 * random_dirs(50, seed=i)[None]).reshape(-1, 3)
        near /= np.linalg.norm(near, axis=1, keepdims=True)
        rad = sig.radiance(np.concatenate([d, ax, near]), i)
        assert rad.min() > 0 and np.all(np.isfinite(rad))
        assert rad.min() >= sig.ambient[i].min() * (1 - 1e-12)  # lobes only add light
    # the SH coefficients are those of this closed form: projection by an independent rule
    ws, ww = theta_rule_sphere(160, 320)
    L = sig.sh(6)
    for i in (0, 5, 11):
        proj = (sh_basis(ws, 6) * ww[:, None]).T @ sig.radiance(ws, i)
        np.testing.assert_allclose(L[i], proj, atol=1e-9 * np.abs(proj).max())


def test_generator_irradiance_is_exact_and_positive():
    """E from the generator equals the exact irradiance of its (closed-form, non-negative)
    radiance — computed independently pointwise by a 1-D integral per lobe and by 2-D
    quadrature of the radiance — within the bound it reports for its SH truncation, and it is
    positive everywhere."""
    sig = random_signals(40, seed=11)
    e = sig.irradiance_sh()
    assert e.shape == (40, (LMAX_SIGNAL + 1) ** 2, 3)
    n = random_dirs(6, seed=2)
    y = sh_basis(n, LMAX_SIGNAL)
    bound = sig.truncation_bound(pointwise=True)
    ws, ww = theta_rule_sphere(300, 600)  # κ ≤ 128: lobes ≥ 0.09 rad wide, well resolved
    for i in (0, 1, 17, 39):
        exact = sig.irradiance_exact(n, i)
        np.testing.assert_allclose(y @ e[i], exact, atol=bound[i].max() + 1e-9 * exact.max())
        # (the kink of max(n·ω, 0) across the grid limits this rule to ~1e-5)
        brute = np.maximum(n @ ws.T, 0) @ (sig.radiance(ws, i) * ww[:, None])
        np.testing.assert_allclose(brute, exact, rtol=2e-5)
    # a lone light: its irradiance at the axis and 90° away, against closed forms
    assert vmf_irradiance(50.0, 1.0) == pytest.approx(vmf_moments(50.0, 1)[1], rel=1e-10)
    # at 90° the lit half of the lobe: ∫ v(t) 2√(1−t²) dt over t (α = 0)
    from scipy.integrate import quad

    half = quad(lambda t: 50 * np.exp(50 * (t - 1)) / (2 * np.pi * -np.expm1(-100))
                * 2 * np.sqrt(1 - t * t), -1, 1, epsabs=0, epsrel=1e-13, points=[0.9, 0.99])[0]
    assert vmf_irradiance(50.0, 0.0) == pytest.approx(half, rel=1e-9)
    # positivity: the certificate π·ambient − (pointwise truncation bound) is a lower bound
    # of E everywhere, and positive for every signal the generator draws
    big = random_signals(2000, seed=3)
    cert = big.min_irradiance_certificate()
    assert cert.min() > 0
    dirs = random_dirs(1500, seed=4)
    vals = np.matmul(sh_basis(dirs, LMAX_SIGNAL), big.irradiance_sh()[:400])  # (400, N, 3)
    assert np.all(vals.min(axis=1) >= cert[:400] - 1e-12)
    # the L2 truncation bound is tiny next to the irradiance
    rel = big.truncation_bound() / np.linalg.norm(big.irradiance_sh(), axis=1)
    assert rel.max() < 1e-4
    assert clamped_cosine_factors(LMAX_SIGNAL)[3] == 0


def test_imse_quadratic_form_matches_direct_integration():
    e = random_irradiance(3, seed=4)  # (3, K, 3)
    d, w, _, _ = theta_quadrature(80, 160)
    E = np.einsum("nk,skc->snc", sh_basis(d, LMAX_SIGNAL), e)
    for name in ("H6", "HL2", "Zernike6", "HSH3", "SH9", "SH9 (LSQ)", "Makhotkin2"):
        b = get_basis(name)
        approx = np.einsum("ni,sic->snc", b.evaluate(d), b.sh_matrix(LMAX_SIGNAL) @ e)
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
    assert m["Zernike6"] < 2 * m["H6"]  # "close behind"
    assert m["Makhotkin2"] == pytest.approx(m["HSH2"], rel=1e-9)  # the same functions
    assert m["Makhotkin3"] == pytest.approx(m["HSH3"], rel=1e-9)
    assert 0 < r.trunc_rel_max < 1e-4
    assert "| 6 | H6 |" in r.markdown() and r.csv().startswith("basis,coefficients")


def _t_h_reference(s):
    return np.einsum("ij,...jc->...ic", sh_to_h_matrix(), np.asarray(s, dtype=np.float64))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("channels", [1, 3, 2])
def test_sh_to_h_kernels_and_out(rng, dtype, channels):
    """The numba kernels (one channel, RGB, any C; ≥ 4096 sets) equal T_h @ s, keep float32,
    and fill a preallocated ``out``; H4 is the first four rows."""
    s = rng.normal(size=(2, 2100, 9, channels)).astype(dtype)
    want = _t_h_reference(s)
    tol = 1e-13 if dtype == np.float64 else 3e-6
    got = sh_to_h(s)
    assert got.dtype == dtype and got.shape == (2, 2100, 6, channels)
    np.testing.assert_allclose(got, want, atol=tol * np.abs(want).max())
    out = np.full((2, 2100, 4, channels), np.nan, dtype=dtype)
    assert sh_to_h(s, 4, out=out) is out
    np.testing.assert_allclose(out, want[..., :4, :], atol=tol * np.abs(want).max())
    small = s[0, :5]  # numpy path, same result and out= too
    out6 = np.empty((5, 6, channels), dtype=dtype)
    assert sh_to_h(small, out=out6) is out6
    np.testing.assert_allclose(out6, want[0, :5], atol=tol * np.abs(want).max())
    for bad in (np.empty((2, 2100, 6, channels), dtype=np.float16),  # wrong type
                np.empty((2, 2100, 5, channels), dtype=dtype),  # wrong shape
                np.empty((2, 2100, 12, channels), dtype=dtype)[:, :, ::2]):  # not contiguous
        with pytest.raises(ShprobeError, match="out must be"):
            sh_to_h(s, out=bad)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("channels", [1, 3])
def test_sh_to_h_streaming_stores(rng, dtype, channels):
    """Outputs over STREAM_MIN_BYTES are written with streaming stores: the same values, and
    H4 as well as H6."""
    from shprobe.hbasis.basis import STREAM_MIN_BYTES

    n_sets = STREAM_MIN_BYTES // (4 * channels * np.dtype(dtype).itemsize) + 123
    s = rng.normal(size=(n_sets, 9, channels)).astype(dtype)
    want = _t_h_reference(s)
    tol = 1e-13 if dtype == np.float64 else 3e-6
    for n in (6, 4):
        got = sh_to_h(s, n)
        assert got.nbytes >= STREAM_MIN_BYTES
        np.testing.assert_allclose(got, want[:, :n], atol=tol * np.abs(want).max())


def test_h_basis_out(rng):
    d = random_dirs(5000, seed=3)
    out = np.empty((5000, 6))
    assert h_basis(d, out=out) is out
    np.testing.assert_array_equal(out, h_basis(d))
    o4 = np.empty((5000, 4), np.float32)
    assert h_basis(d.astype(np.float32), 4, out=o4) is o4
    np.testing.assert_allclose(o4, h_basis(d)[:, :4], atol=1e-6)
    with pytest.raises(ShprobeError, match="out must be"):
        h_basis(d, out=np.empty((5000, 6), np.float32))
    with pytest.raises(ShprobeError, match="out must be"):
        h_basis(d, out=np.empty((6, 5000)).T)  # not C-contiguous


def test_sh_to_h_layout_and_errors(rng):
    s = rng.normal(size=9)
    np.testing.assert_allclose(sh_to_h(s), sh_to_h_matrix() @ s, atol=1e-14)  # one set (K,)
    one = rng.normal(size=(1000, 9, 1))
    np.testing.assert_allclose(sh_to_h(one)[..., 0], one[..., 0] @ sh_to_h_matrix().T,
                               atol=1e-13)
    # (N, 9) is N coefficients of 9 channels by the layout: 1000 is not a square → explain it
    with pytest.raises(ShprobeError) as ei:
        sh_to_h(one[..., 0])
    msg = str(ei.value)
    assert "\n" not in msg and "(..., K, C)" in msg and "(..., K, 1)" in msg and "1000" in msg
    # (16, 9) is, by the same layout, l ≤ 3 with 9 channels: T_h for lmax = 3
    s16 = rng.normal(size=(16, 9))
    np.testing.assert_allclose(sh_to_h(s16), sh_to_h_matrix(3) @ s16, atol=1e-13)
    with pytest.raises(ShprobeError):
        sh_to_h(np.float64(1.0))
    with pytest.raises(ShprobeError, match="4 or 6"):
        sh_to_h(s, n=5)


def test_evaluate_h_layout_and_errors(rng):
    p = 7
    nrm = random_dirs(p, seed=5)
    b = h_basis(nrm)
    c = rng.normal(size=(p, 6, 4))  # (P, n=6, C=4)
    want = np.einsum("pi,pic->pc", b, c)
    np.testing.assert_allclose(evaluate_h(c, nrm), want, atol=1e-13)
    np.testing.assert_allclose(shade_h(c, nrm), want, atol=1e-13)
    c4 = rng.normal(size=(p, 4, 6))  # (P, n=4, C=6)
    np.testing.assert_allclose(evaluate_h(c4, nrm), np.einsum("pi,pic->pc", b[:, :4], c4),
                               atol=1e-13)
    sq = rng.normal(size=(6, 6))  # basis on axis -2: six functions, six channels
    np.testing.assert_allclose(evaluate_h(sq, nrm), b @ sq, atol=1e-13)
    np.testing.assert_allclose(evaluate_h(sq[:, 0], nrm), b @ sq[:, 0], atol=1e-13)  # (n,)
    # shared coefficients broadcast over normals (..., 3)
    grid = random_dirs(12, seed=6).reshape(3, 4, 3)
    np.testing.assert_allclose(evaluate_h(c[0], grid), h_basis(grid) @ c[0], atol=1e-13)
    for bad, normals in ((rng.normal(size=(p, 6)), nrm),  # basis-last one channel
                         (rng.normal(size=(p, 5, 3)), nrm),
                         (rng.normal(size=(5,)), nrm),
                         (c, random_dirs(p + 1, seed=1)),  # leading axes do not broadcast
                         (c, nrm[:, :2])):
        with pytest.raises(ShprobeError) as ei:
            evaluate_h(bad, normals)
        assert "\n" not in str(ei.value)
    with pytest.raises(ShprobeError, match=r"\(\.\.\., n, 1\)"):
        evaluate_h(rng.normal(size=(p, 6)), nrm)


def test_gram_report_matches_independent_quadrature_and_closed_form():
    d, w, _, _ = theta_quadrature(80, 128)
    r3 = np.sqrt(3) / 4  # ∫_Ω+ y00 y10 = √3/(4π) · ∫_Ω+ z dω = √3/4
    g4 = 0.5 * np.eye(4)
    g4[0, 2] = g4[2, 0] = r3
    g9 = 0.5 * np.eye(9)
    g9[0, 2] = g9[2, 0] = r3
    g9[1, 5] = g9[5, 1] = g9[3, 7] = g9[7, 3] = np.sqrt(45) / 16  # √(3·15)/(4π) ∫ y²z = π/4
    g9[2, 6] = g9[6, 2] = np.sqrt(15) / 16  # √3·√5/(8π) ∫ z(3z²−1) = π/2
    res = run_study(50, seed=2)
    reports = {g.name: g for g in res.grams}
    assert set(reports) == set(all_bases())
    for name, b in all_bases().items():
        B = b.evaluate(d)
        indep = (B * w[:, None]).T @ B
        g = reports[name]
        np.testing.assert_allclose(g.matrix, indep, atol=1e-10, err_msg=name)
        ev = np.linalg.eigvalsh(indep)
        assert g.eig_min == pytest.approx(ev[0], rel=1e-8)
        assert g.cond == pytest.approx(ev[-1] / ev[0], rel=1e-8)
        assert g.orthonormal == b.orthonormal, name
    np.testing.assert_allclose(reports["SH4 (LSQ)"].matrix, g4, atol=1e-13)
    np.testing.assert_allclose(reports["SH9"].matrix, g9, atol=1e-13)
    np.testing.assert_allclose(gram_report(get_basis("SH9 (LSQ)")).matrix, g9, atol=1e-13)
    md = res.markdown()
    assert "Gram matrix of SH9 = SH9 (LSQ)" in md and "Gram matrix of SH4 (LSQ)" in md
    assert "| 0.500000 | 0 | 0.433013 |" in md  # the y00 row of SH4's Gram matrix
    assert f"| SH9 | 9 | 5.0e-01 | {reports['SH9'].eig_min:.4g}" in md
