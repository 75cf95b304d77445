"""Irradiance normal mapping with the H-basis: frames, rotation direction, bake/shade against
direct evaluation of E at the perturbed normal, probe loader, CLI."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.cli.main import main
from shprobe.hbasis import get_basis, h_basis, project_h
from shprobe.hbasis.normalmap import (
    bake,
    bump_normals,
    frame_from_normal,
    shade_h,
    shade_sh,
    tangent_frames,
    to_tangent_sh,
)
from shprobe.hbasis.study import imse, random_irradiance
from shprobe.sh import sh_basis

from .conftest import random_dirs


def _orthonormal_right_handed(f):
    np.testing.assert_allclose(np.swapaxes(f, -1, -2) @ f, np.broadcast_to(np.eye(3), f.shape),
                               atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(f), 1.0, atol=1e-12)


def test_frame_from_normal():
    n = random_dirs(200, seed=1)
    n[0] = [0, 0, 1]
    n[1] = [0, 0, -0.999999]
    n[1] /= np.linalg.norm(n[1])
    f = frame_from_normal(n)
    _orthonormal_right_handed(f)
    np.testing.assert_allclose(f[..., 2], n, atol=1e-12)


def test_tangent_frames_follow_uv_and_report_mirroring():
    # a quad in the plane z = 0 tilted; u runs along +x, v along +y
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    uv = v[:, :2].copy()
    fr = tangent_frames(v, faces, uvs=uv)
    _orthonormal_right_handed(fr.matrix)
    np.testing.assert_allclose(fr.matrix[:, :, 0], np.tile([1.0, 0, 0], (4, 1)), atol=1e-12)
    np.testing.assert_allclose(fr.matrix[:, :, 2], np.tile([0, 0, 1.0], (4, 1)), atol=1e-12)
    np.testing.assert_array_equal(fr.handedness, 1)
    mirrored = tangent_frames(v, faces, uvs=uv * [1, -1])  # v runs along −y
    np.testing.assert_array_equal(mirrored.handedness, -1)
    np.testing.assert_allclose(mirrored.matrix[:, :, 0], fr.matrix[:, :, 0], atol=1e-12)
    # rotated mesh: the frame rotates with it
    R = frame_from_normal(random_dirs(1, seed=9))[0]
    rot = tangent_frames(v @ R.T, faces, uvs=uv)
    np.testing.assert_allclose(rot.matrix, R @ fr.matrix, atol=1e-12)
    # no UVs: the normal-only frame
    nouv = tangent_frames(v, faces)
    np.testing.assert_allclose(nouv.matrix, frame_from_normal(np.tile([0, 0, 1.0], (4, 1))))


def test_tangent_sh_is_function_in_frame(rng):
    e = rng.normal(size=(25, 3))
    F = frame_from_normal(random_dirs(6, seed=4))
    g = to_tangent_sh(e, F)
    v = random_dirs(30, seed=5)
    direct = np.einsum("fsk,kc->fsc", sh_basis(np.einsum("fij,sj->fsi", F, v), 4), e)
    np.testing.assert_allclose(np.einsum("sk,fkc->fsc", sh_basis(v, 4), g), direct, atol=1e-12)


def test_bake_equals_projection_of_direct_evaluation():
    e = random_irradiance(1, seed=3)[0][:25]  # l ≤ 4
    F = frame_from_normal(random_dirs(5, seed=6))
    bk = bake(e, F, n=6, lmax=None)
    for i in range(len(F)):
        direct = project_h(lambda v, i=i: sh_basis(v @ F[i].T, 4) @ e)  # ∫ E(F v) Hⁱ(v) dv
        np.testing.assert_allclose(bk.h[i], direct, atol=1e-10)
    # l ≤ 2 only: the paper's 6×9 T_h
    bk2 = bake(e, F, lmax=2)
    np.testing.assert_allclose(bk2.h, bake(e[:9], F, lmax=None).h, atol=1e-12)
    assert bk.sh.shape == (5, 9, 3)


def test_shaded_error_is_the_study_basis_error():
    """Shading the bake at perturbed normals v equals E(F v) up to exactly the IMSE the study
    measures for that signal (integrated over all v), and is close pointwise."""
    e = random_irradiance(8, seed=8)  # (8, 289, 3), lmax 16
    F = frame_from_normal(random_dirs(8, seed=7))
    from shprobe.hbasis.basis import hemisphere_quadrature

    v, w = hemisphere_quadrature(40, 80)
    tsh = np.stack([to_tangent_sh(e[i], F[i][None])[0] for i in range(len(F))])
    study = imse(get_basis("H6"), tsh)  # (8, 3)
    y = sh_basis(v, 16)
    rel = []
    for i in range(len(F)):
        bk = bake(e[i], F[i][None], lmax=None)
        direct = sh_basis(v @ F[i].T, 16) @ e[i]  # E at the perturbed world normal F v
        err = np.einsum("n,nc->c", w, (shade_h(bk.h[0], v) - direct) ** 2)
        np.testing.assert_allclose(err, study[i], rtol=1e-6)
        # SH9 in the same frame is the truncated tangent SH
        np.testing.assert_allclose(shade_sh(bk.sh[0], v), y[:, :9] @ tsh[i][:9], atol=1e-10)
        rel.append(err / np.einsum("n,nc->c", w, direct**2))
    # the study (10,000 signals) measures mean IMSE/∫E² ≈ 1.7e-2 for H6
    assert np.mean(rel) < 0.05


def test_bump_normals_are_unit_and_tilt():
    u, v = np.meshgrid(np.linspace(0, 1, 17), np.linspace(0, 1, 17))
    n = bump_normals(u, v, amplitude=0.2, frequency=2)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1, atol=1e-12)
    # steepest where |∇h| = A·2πf: z = 1/√(1 + (A·2πf)²)
    assert n[..., 2].min() == pytest.approx(1 / np.sqrt(1 + (0.2 * 4 * np.pi) ** 2))
    # slope along u at v = 1/8 (sin(2π·2·v) = 1) where u = 0: −∂h/∂u = −A·2π·2
    nn = bump_normals(0.0, 1 / 8, amplitude=0.2, frequency=2)
    assert nn[0] / nn[2] == pytest.approx(-0.2 * 4 * np.pi)
    assert h_basis(n).shape == (17, 17, 6)


def test_probe_sh_matches_brute_force(grace_path):
    from shprobe.hbasis._env import brute_force_irradiance, load_lighting
    from shprobe.zonal import clamped_cosine_factors, convolve

    L = load_lighting(grace_path, 16)
    n = random_dirs(40, seed=12)
    ref = brute_force_irradiance(L, n)
    e = convolve(L.sh, clamped_cosine_factors(16))
    assert np.sqrt(np.mean((sh_basis(n, 16) @ e - ref) ** 2)) / ref.mean() < 0.02
    # R&H: 9 coefficients give an irradiance error of a few percent
    rel9 = np.sqrt(np.mean((sh_basis(n, 2) @ e[:9] - ref) ** 2)) / ref.mean()
    assert rel9 < 0.12


def test_cli_bake_and_render(tmp_path, bunny_path, grace_path, capsys):
    out = tmp_path / "c.npz"
    assert main(["hbasis", "bake", str(bunny_path), str(grace_path), "-o", str(out)]) == 0
    z = np.load(out)
    assert z["h"].shape[1:] == (6, 3) and z["frames"].shape[1:] == (3, 3)
    _orthonormal_right_handed(z["frames"])
    # the file's coefficients are T_h applied to the frame-rotated irradiance
    from shprobe.hbasis._env import load_lighting
    from shprobe.zonal import clamped_cosine_factors, convolve

    L = load_lighting(grace_path, 4)
    e = convolve(L.sh, clamped_cosine_factors(4))
    np.testing.assert_allclose(z["h"][:20], bake(e, z["frames"][:20]).h, rtol=1e-12)
    assert main(["hbasis", "bake", str(bunny_path), str(grace_path), "-o", str(out)]) == 1
    assert "already exists" in capsys.readouterr().err
    png = tmp_path / "r.png"
    assert main(["hbasis", "render", str(bunny_path), str(grace_path), "-o", str(png),
                 "--size", "48"]) == 0
    text = capsys.readouterr().out
    assert "| H6 |" in text and "| SH9 |" in text
    from PIL import Image

    assert Image.open(png).size == (4 * 48, 2 * 48)


def test_cli_study_and_errors(tmp_path, capsys):
    assert main(["hbasis", "study", "--signals", "50", "-o", str(tmp_path / "s")]) == 0
    for ext in ("md", "csv", "png"):
        assert (tmp_path / "s" / f"hbasis_study.{ext}").stat().st_size > 100
    assert "| 6 | H6 |" in capsys.readouterr().out
    bad = tmp_path / "bad.hdr"
    bad.write_text("not an image")
    rc = main(["hbasis", "render", str(bad), str(bad), "-o", str(tmp_path / "x.png")])
    err = capsys.readouterr().err
    assert rc == 1 and err.count("\n") == 1 and "bad.hdr" in err


@pytest.mark.parametrize("mirror", [False, True])
def test_render_with_normal_map_image_on_uv_plane(tmp_path, mirror):
    """A constant normal-map tilt along the map's +v (green) on a plane facing +Z must shade
    with the world normal tilted along the direction in which v grows (−y when mirrored)."""
    import trimesh
    from PIL import Image

    from shprobe.hbasis._env import load_lighting
    from shprobe.hbasis.normalmap import read_normal_map, render_normal_mapped
    from shprobe.zonal import clamped_cosine_factors, convolve

    g = np.linspace(-1, 1, 5)
    X, Y = np.meshgrid(g, g)
    verts = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], -1)
    faces = []
    for j in range(4):
        for i in range(4):
            a = j * 5 + i
            faces += [[a, a + 1, a + 6], [a, a + 6, a + 5]]
    uv = 0.5 * (verts[:, :2] + 1)
    if mirror:
        uv[:, 1] = 1 - uv[:, 1]
    mesh = trimesh.Trimesh(verts, np.array(faces), process=False,
                           visual=trimesh.visual.TextureVisuals(uv=uv))
    tilt = np.array([0.0, 0.3, 1.0]) / np.linalg.norm([0.0, 0.3, 1.0])
    img = np.broadcast_to(np.round(255 * (tilt + 1) / 2), (8, 8, 3)).astype(np.uint8)
    Image.fromarray(img).save(tmp_path / "n.png")
    nmap = read_normal_map(tmp_path / "n.png")
    rng = np.random.default_rng(2)
    L = rng.normal(size=(9, 3))
    L[0] += 6
    np.save(tmp_path / "L.npy", L)
    light = load_lighting(tmp_path / "L.npy")
    res = render_normal_mapped(mesh, light, size=16, normal_map=nmap)
    t = nmap[0, 0]
    world = np.array([t[0], -t[1] if mirror else t[1], t[2]])
    e = convolve(L, clamped_cosine_factors(2))
    expect = sh_basis(world, 2) @ e
    ref = res.images["reference"][res.mask]
    assert res.mask.mean() > 0.5
    np.testing.assert_allclose(ref, np.broadcast_to(expect, ref.shape), rtol=1e-10)
    # l ≤ 2 lighting: SH9 is exact, and H6 is its hemispherical projection
    np.testing.assert_allclose(res.images["SH9"][res.mask], ref, rtol=1e-10)
    assert res.rel_rms["SH9"] < 1e-10
    # H6 at the looked-up tangent normal (green flipped on the mirrored chart), one flat frame
    fr = tangent_frames(verts, np.array(faces), uvs=uv)
    np.testing.assert_allclose(fr.handedness, -1 if mirror else 1)
    vt = np.array([t[0], -t[1] if mirror else t[1], t[2]])
    h6 = shade_h(bake(e, fr.matrix[:1]).h[0], vt)
    np.testing.assert_allclose(res.images["H6"][res.mask], np.broadcast_to(h6, ref.shape),
                               rtol=1e-10)
