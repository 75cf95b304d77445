"""Prefiltering (R&H 2001 eq. 10), irradiance (eq. 7, 11–13), brute force and the error metric,
checked against closed forms, independent quadrature and the paper's numbers."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.lighting.coeffs import RH_CONSTANTS
from shprobe.lighting.document import coeffs_document, read_coeffs_json
from shprobe.lighting.irradiance import (
    irradiance,
    irradiance_from_matrix,
    irradiance_map,
    irradiance_matrix,
    irradiance_quadratic,
)
from shprobe.lighting.projection import project, project_samples, total_intensity
from shprobe.lighting.reference import error_report, reference_irradiance
from shprobe.probes.env import Env
from shprobe.probes.layouts import get_layout
from shprobe.sh import sh_basis
from tests.conftest import data_file, random_dirs

# ----------------------------------------------------------------------------- helpers


def rh_basis9(d: np.ndarray) -> np.ndarray:
    """The nine l ≤ 2 functions of R&H eq. 3, written out with exact constants."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    k0 = 0.5 * math.sqrt(1 / math.pi)
    k1 = math.sqrt(3 / (4 * math.pi))
    k2 = 0.5 * math.sqrt(15 / math.pi)
    k20 = 0.25 * math.sqrt(5 / math.pi)
    k22 = 0.25 * math.sqrt(15 / math.pi)
    return np.stack([np.full_like(x, k0), k1 * y, k1 * z, k1 * x, k2 * x * y, k2 * y * z,
                     k20 * (3 * z * z - 1), k2 * x * z, k22 * (x * x - y * y)], axis=-1)


def own_latlong_quadrature(img: np.ndarray) -> np.ndarray:
    """Straightforward midpoint quadrature of a lat-long image, written independently of
    shprobe.probes.layouts: row 0 = +Y, u = 0 → +Z, u = 0.5 → −Z, u = 0.75 → +X."""
    h, w = img.shape[:2]
    out = np.zeros((9, 3))
    u = (np.arange(w) + 0.5) / w
    for j in range(h):
        t0, t1 = math.pi * j / h, math.pi * (j + 1) / h
        theta = 0.5 * (t0 + t1)
        dw = (2 * math.pi / w) * (math.cos(t0) - math.cos(t1))
        d = np.stack([-np.sin(2 * np.pi * u) * math.sin(theta),
                      np.full(w, math.cos(theta)),
                      np.cos(2 * np.pi * u) * math.sin(theta)], axis=-1)
        out += rh_basis9(d).T @ img[j].astype(np.float64) * dw
    return out


def pole_disc_env(h: int, alpha: float, radiance: float = 1.0) -> Env:
    """A uniform disc of angular radius ``alpha`` about +Y, each row covered exactly by the
    solid-angle fraction that lies inside the cap (so ∫L dω = radiance · 2π(1 − cos α))."""
    w = 2 * h
    edges = np.cos(np.pi * np.arange(h + 1) / h)
    ca = math.cos(alpha)
    top, bot = edges[:-1], edges[1:]
    frac = np.clip((top - np.maximum(bot, ca)) / (top - bot), 0.0, 1.0)
    rad = np.repeat((radiance * frac)[:, None, None], w, axis=1)
    return Env(np.repeat(rad, 3, axis=2).astype(np.float32), "latlong")


def legendre(l: int, t: np.ndarray) -> np.ndarray:
    return np.polynomial.legendre.legval(t, [0] * l + [1])


def disc_sh_irradiance(alpha: float, radiance: float, cos_beta: np.ndarray,
                       lmax: int) -> np.ndarray:
    """Closed form of the order-lmax SH irradiance of a uniform cap: L_l0 along the axis from
    ∫_{cos α}^1 P_l = (P_{l−1} − P_{l+1})(cos α)/(2l+1), then Â_l (R&H eq. 8–9)."""
    ca = math.cos(alpha)
    a_hat = {0: math.pi, 1: 2 * math.pi / 3, 2: math.pi / 4, 3: 0.0, 4: -math.pi / 24}
    e = np.zeros_like(cos_beta)
    for l in range(lmax + 1):
        pm1 = 1.0 if l == 0 else legendre(l - 1, np.array(ca))
        integral = (pm1 - legendre(l + 1, np.array(ca))) / (2 * l + 1)
        e += a_hat[l] * radiance * 2 * math.pi * integral * (2 * l + 1) / (4 * math.pi) \
            * legendre(l, cos_beta)
    return e


# ----------------------------------------------------------------------------- projection


@pytest.mark.parametrize("lmax", [0, 2, 6, 16])
def test_latlong_separable_projection_equals_direct_sum(lmax):
    rad = np.random.default_rng(1).random((24, 48, 3)).astype(np.float32)
    env = Env(rad, "latlong")
    d, L, dw = env.samples()
    direct = (sh_basis(d, lmax) * dw[:, None]).T @ L.astype(np.float64)
    np.testing.assert_allclose(project(env, lmax), direct, atol=1e-6 * np.abs(direct).max())
    # the rows split over threads (done by default for large images) give the same sums
    from shprobe.lighting.projection import _project_latlong

    for threads in (2, 3, 7):
        np.testing.assert_array_equal(_project_latlong(rad, lmax, threads),
                                      _project_latlong(rad, lmax, 1))


def test_latlong_threads_by_size_and_idle_cores(monkeypatch):
    # one thread for small images; above LATLONG_THREAD_MIN_WORK the cores left idle
    import shprobe.lighting.projection as pf

    monkeypatch.setattr(pf.os, "cpu_count", lambda: 4)
    big = pf.LATLONG_THREAD_MIN_WORK
    for load, want in ((0.0, 4), (0.8, 4), (1.5, 3), (2.9, 2), (3.5, 1), (40.0, 1)):
        monkeypatch.setattr(pf.os, "getloadavg", lambda load=load: (load, load, load))
        assert pf._latlong_threads(big - 1) == 1
        assert pf._latlong_threads(big) == want, load
    # 512×256 and 1024×512 RGB at lmax 8 stay on one thread, 4096×2048 at lmax 2 may split
    assert 512 * 256 * 3 * 17 < 1024 * 512 * 3 * 17 < big <= 4096 * 2048 * 3 * 5


def test_project_samples_equals_direct_sum():
    d = random_dirs(500, seed=3)
    v = np.random.default_rng(4).random((500, 3))
    w = np.random.default_rng(5).random(500)
    direct = (sh_basis(d, 5) * w[:, None]).T @ v
    np.testing.assert_allclose(project_samples(d, v, w, 5), direct, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(project_samples(d, v[:, 0], w, 5), direct[:, 0], atol=1e-12)


@pytest.mark.parametrize("name", ["angular", "cube", "mirrorball"])
def test_other_layouts_project_the_same_function(name):
    """A smooth l ≤ 2 function gives the same coefficients in every layout."""
    lay = get_layout(name)
    coeffs = np.random.default_rng(7).normal(size=(9, 3))
    size = 48 if name == "cube" else 256
    from shprobe.probes.env import env_from_function

    env = env_from_function(lambda d: rh_basis9(d) @ coeffs, lay, size)
    got = project(env, 2)
    tol = 5e-3 if name != "cube" else 2e-3
    np.testing.assert_allclose(got, coeffs, atol=tol * np.abs(coeffs).max())


def test_latlong_projection_recovers_known_coefficients():
    coeffs = np.random.default_rng(8).normal(size=(9, 3))
    from shprobe.probes.env import env_from_function

    env = env_from_function(lambda d: rh_basis9(d) @ coeffs, "latlong", 256)
    np.testing.assert_allclose(project(env, 2), coeffs, atol=2e-4 * np.abs(coeffs).max())
    # higher bands of an l ≤ 2 function vanish
    assert np.abs(project(env, 4)[9:]).max() < 2e-4 * np.abs(coeffs).max()


@pytest.mark.parametrize("probe", ["grace", "ennis"])
def test_probe_coefficients_equal_independent_quadrature(probe):
    from shprobe.probes.env import load_env
    from shprobe.probes.images import read_image
    from tests.conftest import data_file

    path = data_file("probes", f"{probe}.hdr")
    img = read_image(path)
    ref = own_latlong_quadrature(img)
    got = project(load_env(path), 2)
    np.testing.assert_allclose(got, ref, rtol=1e-5, atol=1e-6 * np.abs(ref).max())


def test_constant_environment_gives_pi_everywhere():
    env = Env(np.full((128, 256, 3), 1.0, np.float32), "latlong")
    n = random_dirs(200, seed=11)
    for lmax in (0, 2, 4):
        np.testing.assert_allclose(irradiance(project(env, lmax), n), np.pi, rtol=2e-4)
    np.testing.assert_allclose(reference_irradiance(env, n), np.pi, rtol=1e-3)
    np.testing.assert_allclose(total_intensity(env), 4 * np.pi, rtol=1e-12)


# ----------------------------------------------------------------------------- disc lobe


def test_small_disc_gives_clamped_cosine_lobe():
    alpha, L0 = math.radians(8.0), 50.0
    env = pole_disc_env(256, alpha, L0)
    beta = np.linspace(0.0, np.pi, 181)
    n = np.stack([np.sin(beta), np.cos(beta), np.zeros_like(beta)], axis=-1)
    cb = np.cos(beta)
    # brute force: fully lit normals follow π L0 sin²α cos β; fully dark ones are 0
    ref = reference_irradiance(env, n)[:, 0]
    lit = beta < np.pi / 2 - alpha - 0.02
    dark = beta > np.pi / 2 + alpha + 0.02
    exact = np.pi * L0 * math.sin(alpha) ** 2 * cb
    np.testing.assert_allclose(ref[lit], exact[lit], atol=2e-3 * exact.max())
    np.testing.assert_allclose(ref[dark], 0.0, atol=1e-12)
    # SH: the analytic order-l truncation of the disc's clamped-cosine lobe
    for lmax in (1, 2, 4):
        sh = irradiance(project(env, lmax), n)[:, 0]
        want = disc_sh_irradiance(alpha, L0, cb, lmax)
        np.testing.assert_allclose(sh, want, atol=1e-3 * exact.max())


def test_tilted_disc_lobe_follows_its_direction():
    """A disc away from the pole (pixel-centre coverage): E_SH depends on n·d only."""
    from shprobe.probes.env import env_from_function

    alpha = math.radians(10.0)
    d0 = np.array([0.6, -0.3, 0.74])
    d0 /= np.linalg.norm(d0)
    env = env_from_function(lambda d: np.where((d @ d0 >= math.cos(alpha))[:, None], 1.0, 0.0),
                            "latlong", 512)
    omega = total_intensity(env)[0]  # discrete disc area, ≈ 2π(1 − cos α)
    assert omega == pytest.approx(2 * np.pi * (1 - math.cos(alpha)), rel=1e-2)
    n = random_dirs(300, seed=12)
    sh = irradiance(project(env, 2), n)[:, 0]
    scale = omega / (2 * np.pi * (1 - math.cos(alpha)))
    want = scale * disc_sh_irradiance(alpha, 1.0, n @ d0, 2)
    np.testing.assert_allclose(sh, want, atol=3e-3 * want.max())


# ----------------------------------------------------------------------------- eq. 7/11/13


def test_eq7_eq11_eq13_agree():
    rng = np.random.default_rng(21)
    coeffs = rng.normal(size=(9, 3))
    n = random_dirs(400, seed=22)
    e7 = irradiance(coeffs, n)
    e11 = irradiance_from_matrix(irradiance_matrix(coeffs), n)
    e13 = irradiance_quadratic(coeffs, n)
    np.testing.assert_allclose(e11, e7, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(e13, e7, rtol=1e-12, atol=1e-12)
    # independent: E = Σ Â_l L_lm y_lm with the written-out basis
    a = np.array([np.pi] + [2 * np.pi / 3] * 3 + [np.pi / 4] * 5)
    np.testing.assert_allclose(rh_basis9(n) @ (a[:, None] * coeffs), e7, atol=1e-12)
    m = irradiance_matrix(coeffs)
    assert m.shape == (3, 4, 4)
    np.testing.assert_allclose(m, np.swapaxes(m, -1, -2))


def test_rh_constants_round_to_the_paper():
    printed = (0.429043, 0.511664, 0.743125, 0.886227, 0.247708)
    # R&H rounded from 6-digit normalisations: within 2e-6 of the exact values
    for exact, p in zip(RH_CONSTANTS, printed, strict=True):
        assert abs(exact - p) < 2e-6


def test_irradiance_any_lmax_and_shapes():
    coeffs = np.random.default_rng(2).normal(size=(25, 3))
    n = random_dirs(12, seed=2).reshape(3, 4, 3)
    e = irradiance(coeffs, n)
    assert e.shape == (3, 4, 3)
    a4 = np.repeat([np.pi, 2 * np.pi / 3, np.pi / 4, 0.0, -np.pi / 24], [1, 3, 5, 7, 9])
    np.testing.assert_allclose(e, sh_basis(n, 4) @ (a4[:, None] * coeffs), atol=1e-12)
    assert irradiance(coeffs[:, 0], n).shape == (3, 4)
    with pytest.raises(ShprobeError):
        irradiance_matrix(coeffs[:4])
    with pytest.raises(ShprobeError):
        irradiance(np.zeros((8, 3)), n)


# ----------------------------------------------------------------------------- maps


def test_irradiance_map_latlong_and_angular_view():
    coeffs = np.random.default_rng(31).normal(size=(9, 3))
    emap = irradiance_map(coeffs, "latlong", (64, 32))
    assert emap.radiance.shape == (32, 64, 3) and emap.layout.name == "latlong"
    np.testing.assert_allclose(emap.radiance, irradiance(coeffs, emap.directions()),
                               rtol=1e-5, atol=1e-5)
    n = 65  # odd: the centre pixel is the centre of the disc
    ang = irradiance_map(coeffs, "angular", n).radiance
    # R&H Fig. 3: centre = +Z; half radius to the right = +X; corners outside the disc = 0
    np.testing.assert_allclose(ang[n // 2, n // 2], irradiance(coeffs, [0, 0, 1]), rtol=1e-5)
    j = n // 2 + n // 4 + 1  # half radius to the right
    d = get_layout("angular").pixel_directions((n, n))[n // 2, j]
    assert d[0] > 0.99
    np.testing.assert_allclose(ang[n // 2, j], irradiance(coeffs, d), rtol=1e-5, atol=1e-5)
    assert np.all(ang[0, 0] == 0)


# ----------------------------------------------------------------------------- reference / error


def test_directional_light_max_error_is_9_4_percent():
    """R&H §3.1: one directional light, lmax = 2, max error 9.4 % of the total intensity
    (the l ≤ 2 approximation of the clamped cosine is off by 3/32 at the horizon)."""
    env = pole_disc_env(1024, math.radians(0.2), 1e4)
    beta = np.linspace(0.0, np.pi, 181)
    n = np.stack([np.sin(beta), np.cos(beta), np.zeros_like(beta)], axis=-1)
    rep = error_report(env, (1, 2, 4), normals=n)
    r2 = rep.row(2)
    assert r2.max_frac == pytest.approx(3 / 32, abs=1e-3)
    assert rep.row(4).max_frac < r2.max_frac < rep.row(1).max_frac


@pytest.mark.parametrize("probe", ["grace", "ennis"])
def test_rh_claim_on_natural_light(probe):
    from shprobe.probes.env import load_env
    from tests.conftest import data_file

    env = load_env(data_file("probes", f"{probe}.hdr"))
    rep = error_report(env, (1, 2, 3, 4))
    r2 = rep.row(2)
    assert r2.mean_frac < 0.02 and r2.max_frac < 0.05
    assert rep.row(4).mean_frac < r2.mean_frac < rep.row(1).mean_frac


def test_brute_force_converges_with_subdivision(grace_path):
    from shprobe.probes.env import load_env

    env = load_env(grace_path)
    n = random_dirs(64, seed=41)
    e1 = reference_irradiance(env, n)
    e2 = reference_irradiance(env, n, subdivide=2)
    e3 = reference_irradiance(env, n, subdivide=3, chunk=5000)
    rel12 = np.abs(e2 - e1).max() / np.abs(e1).max()
    rel23 = np.abs(e3 - e2).max() / np.abs(e2).max()
    assert rel12 < 1e-3 and rel23 < 1e-3
    assert rel23 < rel12


def test_reference_chunking_and_generic_path_agree():
    rad = np.random.default_rng(51).random((16, 32, 3)).astype(np.float32)
    env = Env(rad, "latlong")
    n = random_dirs(20, seed=52)
    d, L, dw = env.samples()
    direct = np.maximum(n @ d.T, 0.0) @ (L * dw[:, None])
    np.testing.assert_allclose(reference_irradiance(env, n, chunk=7), direct, rtol=1e-10)
    np.testing.assert_allclose(reference_irradiance(env, n), direct, rtol=1e-10)
    # the generic (sample) path of the other layouts, with subdivision
    from shprobe.probes.env import env_from_function

    for name, size in (("angular", 24), ("cube", 8)):
        genv = env_from_function(lambda d: 1.0 + d * [0.5, 0.2, -0.3], name, size)
        d, L, dw = genv.samples()
        direct = np.maximum(n @ d.T, 0.0) @ (L * dw[:, None])
        np.testing.assert_allclose(reference_irradiance(genv, n, chunk=100), direct,
                                   rtol=1e-10)
        sub = reference_irradiance(genv, n, subdivide=2)
        np.testing.assert_allclose(sub, direct, rtol=2e-2)


def test_reference_blocks_over_normals_and_reports_progress():
    """Many normals and few samples: the work is split over normals too, and the progress
    reported (one stage of the progress protocol) moves steadily to T·S while the result stays
    the direct sum."""
    from shprobe.progress import Recorder

    rad = np.random.default_rng(53).random((16, 32, 3)).astype(np.float32)
    env = Env(rad, "latlong")
    n = random_dirs(200_000, seed=54)
    rec = Recorder()
    got = reference_irradiance(env, n, progress=rec)
    d, L, dw = env.samples()
    np.testing.assert_allclose(got[::97], np.maximum(n[::97] @ d.T, 0.0) @ (L * dw[:, None]),
                               rtol=1e-10)
    assert rec.events[0] == ("begin", "exact irradiance at 200,000 normals (brute force)",
                             200_000 * 512)
    done = [e[1] for e in rec.events if e[0] == "update"]
    assert len(done) >= 10 and done == sorted(done)
    assert done[-1] == 200_000 * 512 and rec.events[-1][0] == "end"


# ----------------------------------------------------------------------------- JSON


def test_json_document_round_trip(tmp_path):
    from shprobe.files import write_json

    c = np.random.default_rng(61).normal(size=(9, 3))
    doc = coeffs_document(c, "x.hdr", "latlong")
    assert {"shprobe_version", "source", "layout", "lmax", "convention", "coefficients",
            "irradiance_coefficients", "M"} <= set(doc)
    assert np.asarray(doc["M"]).shape == (3, 4, 4)
    np.testing.assert_allclose(np.asarray(doc["irradiance_coefficients"])[1:4],
                               2 * np.pi / 3 * c[1:4])
    write_json(tmp_path / "c.json", doc)
    np.testing.assert_array_equal(read_coeffs_json(tmp_path / "c.json"), c)
    assert "M" not in coeffs_document(c[:4])
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(ShprobeError, match=r"bad\.json"):
        read_coeffs_json(tmp_path / "bad.json")
    (tmp_path / "five.json").write_text('{"coefficients": [[1,2,3],[1,2,3]]}')
    with pytest.raises(ShprobeError, match="lmax"):
        read_coeffs_json(tmp_path / "five.json")
    from shprobe.lighting.export import export_coeffs

    (tmp_path / "cs.json").write_text(export_coeffs(c, "cs-phase"))  # other signs: refused
    with pytest.raises(ShprobeError, match=r"cs\.json.*cs-phase"):
        read_coeffs_json(tmp_path / "cs.json")


# ----------------------------------------------------------------------------- presets / env


def test_presets_match_the_seed_tables():
    from shprobe.probes.presets import PRESETS, get_preset

    assert set(PRESETS) == {"grace", "eucalyptus", "stpeters"}
    seed = data_file("seeds", "ramamoorthi-hanrahan-2001-irradiance-environment-maps.md")
    rows = [ln for ln in seed.read_text().splitlines() if ln.startswith("$L_{")]
    table = np.array([[float(v) for v in re.split(r"\t+", ln)[1:10]] for ln in rows[:9]])
    for i, name in enumerate(("grace", "eucalyptus", "stpeters")):
        np.testing.assert_array_equal(get_preset(name), table[:, 3 * i: 3 * i + 3])
    with pytest.raises(ShprobeError, match="unknown preset"):
        get_preset("nowhere")


def test_procedural_env_is_deterministic_and_lit_from_above():
    from shprobe.probes.environments import SUN_DIRECTION, procedural_env

    a, b = procedural_env(128, 64), procedural_env(128, 64)
    np.testing.assert_array_equal(a.radiance, b.radiance)
    c = project(a, 2)
    assert np.all(c[1] > 0)  # L1-1: the upper hemisphere is brighter
    brightest = a.directions().reshape(-1, 3)[np.argmax(a.radiance[..., 0].ravel())]
    assert brightest @ SUN_DIRECTION > math.cos(math.radians(5))
    with pytest.raises(ShprobeError):
        procedural_env(100, 60)
