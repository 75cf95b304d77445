"""PRT (Lisle & Huang 2007 §4): transfer vectors checked against quadrature, closed-form form
factors, brute-force ray/box geometry and the energy bounds of interreflection.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shprobe.errors import ShprobeError
from shprobe.prt import bake, ground_plane, load_transfer, relight, sample_directions
from shprobe.prt.directions import OFFSET_FRACTION
from shprobe.sh import num_coeffs, sh_basis
from tests.conftest import random_dirs

FOUR_PI = 4.0 * np.pi


def hemisphere_irradiance(normals, coeffs, lmax):
    """E(n) = ∫ L(ω) max(0, n·ω) dω by Gauss–Legendre in cos θ × uniform φ in n's frame.

    Exact for band-limited L (the integrand is a polynomial on the hemisphere); uses no Â_l.
    """
    mu, wmu = np.polynomial.legendre.leggauss(lmax + 4)
    mu, wmu = 0.5 * (mu + 1.0), 0.5 * wmu
    nphi = 2 * lmax + 6
    phi = 2.0 * np.pi * np.arange(nphi) / nphi
    out = []
    for n in normals:
        a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        t1 = np.cross(n, a)
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)
        s = np.sqrt(1.0 - mu**2)[:, None, None]
        w = (s * (np.cos(phi)[None, :, None] * t1 + np.sin(phi)[None, :, None] * t2)
             + mu[:, None, None] * n)
        f = sh_basis(w.reshape(-1, 3), lmax) @ coeffs  # (M, C)
        wt = np.repeat(wmu * mu * (2.0 * np.pi / nphi), nphi)
        out.append(wt @ f)
    return np.array(out)


def box_scene(box_albedo=0.8, plane_albedo=0.8, res=40):
    """A 6×6 plane at y = 0 (a vertex at the origin) and a unit box floating over y ∈ [0.5, 1.5]."""
    plane = ground_plane([0.0, 0.0], 6.0, 0.0, res)
    return [plane, unit_box()], [plane_albedo, box_albedo], len(plane.vertices)


def unit_box(res=8):
    """Box [−½, ½] × [½, 3/2] × [−½, ½] from six separate grids (flat normals, outward)."""
    faces = []
    top = ground_plane([0.0, 0.0], 1.0, 0.5, res)  # the +Y face, centred at the origin
    for axis, ang in (([1, 0, 0], 0.0), ([1, 0, 0], np.pi / 2), ([1, 0, 0], np.pi),
                      ([1, 0, 0], -np.pi / 2), ([0, 0, 1], np.pi / 2), ([0, 0, 1], -np.pi / 2)):
        f = top.copy()
        f.apply_transform(trimesh.transformations.rotation_matrix(ang, axis))
        f.vertex_normals = np.tile(f.face_normals[0], (len(f.vertices), 1))
        faces.append(f)
    box = trimesh.util.concatenate(faces)
    box.apply_translation([0.0, 1.0, 0.0])
    return box


def ray_hits_box(p, d, lo, hi):
    """Slab test (float64) for rays p + t d, t > 0, against the axis-aligned box [lo, hi]."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - p[:, None, :]) / d[None, :, :]
        t2 = (hi - p[:, None, :]) / d[None, :, :]
    tmin = np.nanmax(np.minimum(t1, t2), axis=2)
    tmax = np.nanmin(np.maximum(t1, t2), axis=2)
    return (tmax >= np.maximum(tmin, 0.0))


def icosphere():
    m = trimesh.creation.icosphere(subdivisions=2)
    m.vertex_normals = m.vertices / np.linalg.norm(m.vertices, axis=1, keepdims=True)
    return m


def uniform_light(c=1.0):
    """Constant radiance c in every direction: L_00 = c √(4π)."""
    L = np.zeros((1, 3))
    L[0] = c * np.sqrt(FOUR_PI)
    return L


def test_unshadowed_equals_rho_over_pi_irradiance():
    lmax = 6
    m = icosphere()
    rng = np.random.default_rng(3)
    L = rng.normal(size=(num_coeffs(lmax), 3))
    t = bake(m, mode="unshadowed", lmax=lmax, albedo=0.6)
    assert t.transfer.shape == (len(m.vertices), num_coeffs(lmax))
    got = relight(t, L)
    want = 0.6 / np.pi * hemisphere_irradiance(t.normals, L, lmax)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5 * np.abs(want).max())


def test_unshadowed_matches_prefilter_irradiance():
    from shprobe import lighting

    m = trimesh.creation.icosphere(1)
    L = np.random.default_rng(5).normal(size=(9, 3))
    t = bake(m, mode="unshadowed", lmax=2, albedo=1.0)
    want = lighting.irradiance(L, t.normals) / np.pi
    np.testing.assert_allclose(relight(t, L), want, rtol=1e-5, atol=1e-6)


def test_coloured_albedo_gives_three_channel_transfer():
    m = icosphere()
    rng = np.random.default_rng(6)
    alb = rng.uniform(0.1, 0.9, size=(len(m.vertices), 3))
    t = bake(m, mode="unshadowed", lmax=3, mesh_albedo=[alb])
    assert t.transfer.shape == (len(m.vertices), 16, 3)
    L = rng.normal(size=(16, 3))
    want = alb / np.pi * hemisphere_irradiance(t.normals, L, 3)
    np.testing.assert_allclose(relight(t, L), want, rtol=1e-5, atol=1e-5)


def test_truncation_equals_lower_degree_bake():
    m = icosphere()
    hi = bake(m, mode="shadowed", lmax=10, samples=256, seed=2)
    lo = bake(m, mode="shadowed", lmax=4, samples=256, seed=2)
    np.testing.assert_allclose(hi.truncated(4).transfer, lo.transfer, rtol=1e-5, atol=1e-7)
    L = np.random.default_rng(1).normal(size=(num_coeffs(10), 3))
    np.testing.assert_allclose(relight(hi, L, lmax=4), relight(lo, L), rtol=1e-4, atol=1e-6)


def test_sample_directions_seeded_and_well_spread():
    a, b, c = sample_directions(512, 1), sample_directions(512, 1), sample_directions(512, 2)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1.0, rtol=1e-12)
    # QMC quadrature: ∫ y_lm = 0 for l > 0, here to better than 1e-2 for l ≤ 4
    y = sh_basis(a, 4).mean(axis=0) * FOUR_PI
    assert abs(y[0] - np.sqrt(FOUR_PI)) < 1e-12
    assert np.abs(y[1:]).max() < 1e-2


def test_convex_mesh_all_three_models_agree():
    """On a convex mesh nothing is blocked: shadowed = unshadowed within the quadrature error
    bound 3 σ 4π/√N of plain Monte Carlo (σ² the variance of max(0, n·ω) y_lm(ω)), and
    interreflected = shadowed exactly (no ray hits anything)."""
    m = icosphere()
    n_samples, lmax = 2048, 4
    un = bake(m, mode="unshadowed", lmax=lmax, albedo=1.0).transfer
    sh = bake(m, mode="shadowed", lmax=lmax, samples=n_samples, albedo=1.0, seed=7).transfer
    ir = bake(m, mode="interreflected", lmax=lmax, samples=n_samples, bounces=3, albedo=1.0,
              seed=7).transfer
    np.testing.assert_array_equal(ir, sh)
    # σ per coefficient, computed from a dense independent sample
    w = random_dirs(200_000, seed=11)
    f = np.maximum(w @ m.vertex_normals[:1].T, 0.0) * sh_basis(w, lmax)  # vertex 0
    sigma = f.std(axis=0).max() / np.pi  # ρ/π with ρ = 1
    bound = 3.0 * sigma * FOUR_PI / np.sqrt(n_samples)
    err = np.abs(sh - un).max()
    assert err < bound, (err, bound)
    # the randomised Fibonacci set beats plain MC by far (observed err ≈ 7e-5, bound ≈ 0.036)
    assert err < 0.05 * bound


def test_box_over_plane_shadows_exactly_by_geometry():
    meshes, albedo, nplane = box_scene()
    n_samples, lmax = 512, 2
    t = bake(meshes, mode="shadowed", lmax=lmax, samples=n_samples, mesh_albedo=albedo, seed=3)
    un = bake(meshes, mode="unshadowed", lmax=lmax, mesh_albedo=albedo)
    P = t.vertices[:nplane]
    assert np.allclose(P[:, 1], 0.0)
    # brute force: the same directions from the same offset origins, blocked where the ray meets
    # the box (float64 slabs)
    d = sample_directions(n_samples, 3)
    up = d[:, 1] > 0
    eps = OFFSET_FRACTION * np.linalg.norm(np.ptp(t.vertices, axis=0))
    origins = P + np.array([0.0, eps, 0.0])
    blocked = ray_hits_box(origins, d, np.array([-0.5, 0.5, -0.5]), np.array([0.5, 1.5, 0.5]))
    wts = np.where(up[None, :] & ~blocked, d[None, :, 1], 0.0) * FOUR_PI / n_samples
    want = 0.8 / np.pi * wts @ sh_basis(d, lmax)
    one_ray = 0.8 / np.pi * FOUR_PI / n_samples * np.abs(sh_basis(d, lmax)).max()
    diff = np.abs(t.transfer[:nplane] - want).max(axis=1)
    assert (diff > 1e-5).sum() <= 3  # at most a few grazing rays disagree
    assert diff.max() < 2.5 * one_ray
    # darker exactly where the box blocks part of the hemisphere
    L = uniform_light()
    b_sh, b_un = relight(t, L)[:nplane, 0], relight(un, L)[:nplane, 0]
    any_block = (blocked & up).any(axis=1)
    assert np.all(b_sh[any_block] < b_un[any_block] - 1e-4)
    np.testing.assert_allclose(b_sh[~any_block], b_un[~any_block], atol=0.02 * b_un.max())
    under = (np.abs(P[:, 0]) < 0.5) & (np.abs(P[:, 2]) < 0.5)
    far = np.hypot(P[:, 0], P[:, 2]) > 2.5
    assert b_sh[under].max() < b_sh[far].min()


def test_box_over_plane_matches_form_factor():
    """Under the box centre the box face (1×1 at height 0.5) blocks the cosine-weighted fraction
    F = 4 F_corner (point-to-parallel-rectangle form factor, a = b = c = 0.5)."""
    meshes, albedo, nplane = box_scene()
    t = bake(meshes, mode="shadowed", lmax=0, samples=8192, mesh_albedo=albedo, seed=5)
    i0 = int(np.argmin(np.linalg.norm(t.vertices[:nplane], axis=1)))
    assert np.allclose(t.vertices[i0], 0.0)
    A = B = 0.5 / 0.5
    corner = (A / np.sqrt(1 + A * A) * np.arctan(B / np.sqrt(1 + A * A))
              + B / np.sqrt(1 + B * B) * np.arctan(A / np.sqrt(1 + B * B))) / (2 * np.pi)
    F = 4 * corner
    E = relight(t, uniform_light())[i0, 0] * np.pi / 0.8  # irradiance under L = 1
    # 8192 QMC samples: the open fraction is known to ~1e-2 (plain-MC 3σ ≈ 0.03)
    assert abs(E / np.pi - (1.0 - F)) < 0.02


def test_interreflected_zero_albedo_equals_shadowed():
    """With a black box the plane gets no bounced light (it cannot see itself): the plane's
    interreflected transfer equals its shadowed transfer; the black box itself is 0."""
    meshes, albedo, nplane = box_scene(box_albedo=0.0)
    sh = bake(meshes, mode="shadowed", lmax=3, samples=256, mesh_albedo=albedo, seed=1)
    ir = bake(meshes, mode="interreflected", lmax=3, samples=256, bounces=3, mesh_albedo=albedo,
              seed=1)
    np.testing.assert_allclose(ir.transfer, sh.transfer, atol=1e-7)
    assert np.all(ir.transfer[nplane:] == 0)
    # and ρ = 0 everywhere: no light at all
    z = bake(meshes, mode="interreflected", lmax=3, samples=256, bounces=2, albedo=0.0)
    assert np.all(z.transfer == 0)


def test_interreflection_bounces_add_light_geometrically():
    rho = 0.7
    meshes, albedo, _ = box_scene(box_albedo=rho, plane_albedo=rho, res=24)
    kw = dict(mode="interreflected", lmax=2, samples=512, mesh_albedo=albedo, seed=4)
    full = bake(meshes, bounces=3, **kw)  # every bounce count picked from one bake
    ts = [full.select(bounces=k) for k in range(4)]
    sh = bake(meshes, mode="shadowed", lmax=2, samples=512, mesh_albedo=albedo, seed=4).transfer
    np.testing.assert_allclose(ts[0], sh, atol=1e-7)
    # quadrature weight of the whole upper hemisphere, per vertex (≈ 1 for a good point set)
    d = sample_directions(512, 4)
    normals = bake(meshes, mode="unshadowed", lmax=0, mesh_albedo=albedo).normals
    s = (np.maximum(normals @ d.T, 0).sum(axis=1) * FOUR_PI / 512 / np.pi).max()
    assert abs(s - 1) < 0.02
    sky = np.zeros((4, 3))
    sky[0] = np.sqrt(FOUR_PI)
    sky[1] = 0.9 * np.sqrt(FOUR_PI / 3)  # L(ω) = 1 + 0.9 ω_y > 0
    # power leaving the surfaces: radiance × π × lumped vertex area
    scene = trimesh.util.concatenate(meshes)
    area = np.zeros(len(scene.vertices))
    np.add.at(area, scene.faces.ravel(), np.repeat(scene.area_faces / 3.0, 3))
    for L in (uniform_light(), sky):
        b = [relight(t, L)[:, 0] for t in ts]
        added = [b[k + 1] - b[k] for k in range(3)]
        power = [np.pi * area @ a for a in added]
        for a, p in zip(added, power, strict=True):
            assert a.min() > -1e-6 and p > 0  # each bounce only adds light
        for k in range(2):
            # a bounce re-emits at most ρ of what reached it (per vertex: ρ × the largest
            # incoming bounce radiance; in total: ρ × the previous bounce's power)
            assert added[k + 1].max() <= rho * s * added[k].max() * (1 + 1e-6)
            assert power[k + 1] <= rho * s * power[k]
        assert power[2] / power[1] <= power[1] / power[0] * 1.5  # geometric, not growing


def test_scene_rotation_rotates_lighting_by_inverse():
    """Turning the scene by R: relight(T(n), L, R) = transfer of the turned normals R n."""
    m = icosphere()
    ang = 0.7
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + np.sin(ang) * K + (1 - np.cos(ang)) * K @ K
    turned = m.copy()
    turned.apply_transform(np.block([[R, np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]]))
    turned.vertex_normals = m.vertex_normals @ R.T
    L = np.random.default_rng(8).normal(size=(num_coeffs(4), 3))
    t = bake(m, mode="unshadowed", lmax=4)
    t_turned = bake(turned, mode="unshadowed", lmax=4)
    np.testing.assert_allclose(relight(t, L, rotation=R), relight(t_turned, L), atol=1e-5)


def test_transfer_file_round_trip_and_hash_refusal(tmp_path):
    m = icosphere()
    t = bake(m, mode="shadowed", lmax=4, samples=64, seed=9, albedo=0.5)
    path = tmp_path / "t.npz"
    t.save(path)
    with pytest.raises(ShprobeError, match="already exists"):
        t.save(path)
    back = load_transfer(path, scene=m)
    np.testing.assert_array_equal(back.transfer, t.transfer)
    for key in ("mesh_hash", "mode", "lmax", "samples", "bounces", "seed", "albedo"):
        assert back.metadata[key] == t.metadata[key]
    other = m.copy()
    other.vertices[0] += 1e-3
    with pytest.raises(ShprobeError, match="baked for mesh") as e:
        load_transfer(path, scene=other)
    assert str(path) in str(e.value)
    # a file whose stored mesh was altered is refused too
    with np.load(path) as d:
        arrays = dict(d)
    arrays["vertices"] = arrays["vertices"] + 1.0
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    with pytest.raises(ShprobeError, match="mesh hash"):
        load_transfer(bad)


def test_bad_input_is_refused(tmp_path):
    m = icosphere()
    with pytest.raises(ShprobeError, match="mode"):
        bake(m, mode="glossy")
    with pytest.raises(ShprobeError, match="no such mesh"):
        bake(tmp_path / "missing.obj")
    with pytest.raises(ShprobeError, match="albedo"):
        bake(m, mode="unshadowed", albedo=1.5)
    t = bake(m, mode="unshadowed", lmax=2)
    with pytest.raises(ShprobeError, match="lmax"):
        relight(t, np.zeros((9, 3)), lmax=3)


def test_turning_the_light_is_turning_the_scene_back():
    """A window about axis a turned by R is the window about R a (LH §3.2, independent of the
    Wigner matrices); relighting with scene rotation R⁻¹ must give the same radiance."""
    from shprobe.sh.zonal import circular_window

    m = icosphere()
    t = bake(m, mode="shadowed", lmax=8, samples=256, seed=2)
    a = np.array([0.3, 0.8, -0.52])
    a /= np.linalg.norm(a)
    ang = 1.1
    axis = np.array([0.0, 1.0, 0.0])
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + np.sin(ang) * K + (1 - np.cos(ang)) * K @ K
    turned = relight(t, circular_window(a, np.radians(30), 8), rotation=R.T)
    direct = relight(t, circular_window(R @ a, np.radians(30), 8))
    np.testing.assert_allclose(turned, direct, atol=1e-5 * np.abs(direct).max())


@pytest.mark.parametrize("suffix", [".ply", ".glb", ".obj"])
def test_mesh_formats_load(tmp_path, suffix):
    m = trimesh.creation.icosphere(subdivisions=1)
    p = tmp_path / f"m{suffix}"
    m.export(p)
    t = bake(p, mode="shadowed", lmax=2, samples=64)
    assert t.n_vertices == len(m.vertices)
    # closed convex mesh under uniform light: ρ/π · π = ρ on every vertex (QMC, 64 samples)
    np.testing.assert_allclose(relight(t, uniform_light())[:, 0], 0.8, rtol=0.05)
