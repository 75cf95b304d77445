"""Irradiance normal mapping with the H-basis: frames, rotation direction, bake/shade against
direct evaluation of E at the perturbed normal, probe loader, CLI."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.cli.main import main
from shprobe.hbasis import get_basis, h_basis, project_h
from shprobe.hbasis.frames import tangent_frames, to_tangent_sh
from shprobe.hbasis.normalmap import bake_normalmap, bump_normals, shade_h, shade_sh
from shprobe.hbasis.study import LMAX_SIGNAL, imse, random_irradiance
from shprobe.sh import sh_basis
from shprobe.sh.rotation import frame_from_normal
from shprobe.sh.zonal import clamped_cosine_factors, convolve
from tests.conftest import random_dirs


def theta_quadrature_hemisphere(n_theta, n_phi):
    """Independent rule: Gauss–Legendre in θ ∈ [0, π/2] with sin θ, uniform φ."""
    t, w = np.polynomial.legendre.leggauss(n_theta)
    th = np.pi / 4 * (t + 1)
    wt = np.pi / 4 * w * np.sin(th)
    ph = 2 * np.pi * (np.arange(n_phi) + 0.5) / n_phi
    T, P = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    return d, np.repeat(wt, n_phi) * (2 * np.pi / n_phi), T.ravel(), P.ravel()


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
    bk = bake_normalmap(e, F, n=6, lmax=None)
    for i in range(len(F)):
        direct = project_h(lambda v, i=i: sh_basis(v @ F[i].T, 4) @ e)  # ∫ E(F v) Hⁱ(v) dv
        np.testing.assert_allclose(bk.h[i], direct, atol=1e-10)
    # l ≤ 2 only: the paper's 6×9 T_h
    bk2 = bake_normalmap(e, F, lmax=2)
    np.testing.assert_allclose(bk2.h, bake_normalmap(e[:9], F, lmax=None).h, atol=1e-12)
    assert bk.sh.shape == (5, 9, 3)


def test_shaded_error_is_the_study_basis_error():
    """Shading the bake at perturbed normals v equals E(F v) up to exactly the IMSE the study
    measures for that signal (integrated over all v); the default bake (bands ≤ 4, the paper's
    T_h + Appendix A) stays within that basis error plus what the dropped bands carry."""
    e = random_irradiance(8, seed=8)  # (8, K, 3), lmax = LMAX_SIGNAL
    lmax = LMAX_SIGNAL
    F = frame_from_normal(random_dirs(8, seed=7))
    from shprobe.hbasis.basis import hemisphere_quadrature

    v, w = hemisphere_quadrature(40, 80)
    tsh = np.stack([to_tangent_sh(e[i], F[i][None])[0] for i in range(len(F))])
    study = imse(get_basis("H6"), tsh)  # (8, 3): what run_study computes for these signals
    y = sh_basis(v, lmax)
    for i in range(len(F)):
        direct = sh_basis(v @ F[i].T, lmax) @ e[i]  # E at the perturbed world normal F v
        bk = bake_normalmap(e[i], F[i][None], lmax=None)
        err = np.einsum("n,nc->c", w, (shade_h(bk.h[0], v) - direct) ** 2)
        np.testing.assert_allclose(err, study[i], rtol=1e-6)
        # default bake: |√err4 − √IMSE| ≤ ‖h4 − h‖ (H orthonormal: triangle inequality in
        # coefficient space) ≤ ‖E − E_≤4‖ on Ω+ (‖P‖ = 1)
        bk4 = bake_normalmap(e[i], F[i][None])
        err4 = np.einsum("n,nc->c", w, (shade_h(bk4.h[0], v) - direct) ** 2)
        dh = np.linalg.norm(bk4.h[0] - bk.h[0], axis=0)
        dropped = np.sqrt(np.einsum("n,nc->c", w, (y[:, 25:] @ tsh[i][25:]) ** 2))
        assert np.all(np.abs(np.sqrt(err4) - np.sqrt(study[i])) <= dh * (1 + 1e-9) + 1e-12)
        assert np.all(dh <= dropped * (1 + 1e-9))
        assert np.all(dh < 0.1 * np.sqrt(study[i]))  # Appendix A's "imperceptible" corrections
        # SH9 in the same frame is the truncated tangent SH
        np.testing.assert_allclose(shade_sh(bk.sh[0], v), y[:, :9] @ tsh[i][:9], atol=1e-10)


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
    """The shared lighting pipeline the H-basis now uses: the probe's SH (l ≤ 16, project) against
    the brute-force reference (reference_irradiance)."""
    from shprobe.lighting import project, reference_irradiance
    from shprobe.probes.env import load_env
    from shprobe.sh.zonal import clamped_cosine_factors, convolve

    env = load_env(grace_path)
    L = project(env, 16)
    n = random_dirs(40, seed=12)
    ref = reference_irradiance(env, n)
    e = convolve(L, clamped_cosine_factors(16))
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
    from shprobe.lighting import project
    from shprobe.probes.env import load_env
    from shprobe.sh.zonal import clamped_cosine_factors, convolve

    L = project(load_env(grace_path), 16)[:25]  # the bake keeps l ≤ 16, uses bands ≤ 4
    e = convolve(L, clamped_cosine_factors(4))
    want = bake_normalmap(e, z["frames"][:20]).h
    np.testing.assert_allclose(z["h"][:20], want, rtol=1e-12, atol=1e-14 * np.abs(want).max())
    assert main(["hbasis", "bake", str(bunny_path), str(grace_path), "-o", str(out)]) == 1
    assert "already exists" in capsys.readouterr().err
    png = tmp_path / "r.png"
    assert main(["hbasis", "render", str(bunny_path), str(grace_path), "-o", str(png),
                 "--size", "48", "--table"]) == 0
    text = capsys.readouterr().out
    assert "| H6 |" in text and "| SH9 |" in text
    from PIL import Image

    from shprobe.probes.figures import read_panels

    meta = read_panels(png)  # a labelled figure: 4 images over 3 error maps on one colour bar
    titles = [q["title"] for q in meta["panels"]]
    assert titles[:4] == ["reference (exact)", "H6", "H4", "SH9"]
    assert [q["kind"] for q in meta["panels"][4:]] == ["error"] * 3
    assert all(q.startswith(f"|{k} − ref|, rel. RMS") for q, k in zip(titles[4:],
                                                                      ("H6", "H4", "SH9"),
                                                                      strict=True))
    # bake → render: the baked coefficients give the same render as baking in place
    png2 = tmp_path / "r2.png"
    assert main(["hbasis", "render", str(bunny_path), str(grace_path), "--coeffs", str(out),
                 "-o", str(png2), "--size", "48", "--table"]) == 0
    assert capsys.readouterr().out == text
    np.testing.assert_array_equal(np.asarray(Image.open(png2)), np.asarray(Image.open(png)))
    # the bake in place of PROBE: its coefficients and its stored radiance SH (l ≤ 16)
    png3 = tmp_path / "r3.png"
    assert main(["hbasis", "render", str(bunny_path), str(out), "-o", str(png3),
                 "--size", "48", "--table"]) == 0
    text3 = capsys.readouterr().out
    assert "SH (l ≤ 16) of the baked probe" in text3 and "| H6 |" in text3
    np.testing.assert_allclose(z["L"], project(load_env(grace_path), 16), rtol=1e-12)
    # an H4 bake renders without the H6 panel
    out4 = tmp_path / "c4.npz"
    assert main(["hbasis", "bake", str(bunny_path), str(grace_path), "-o", str(out4),
                 "--basis", "h4"]) == 0
    png4 = tmp_path / "r4.png"
    assert main(["hbasis", "render", str(bunny_path), str(grace_path), "--coeffs", str(out4),
                 "-o", str(png4), "--size", "32", "--table"]) == 0
    text4 = capsys.readouterr().out
    assert "| H6 |" not in text4 and "| H4 |" in text4
    assert [q["title"] for q in read_panels(png4)["panels"]][:3] == ["reference (exact)", "H4",
                                                                     "SH9"]
    # a bake for another mesh is refused with one line
    import trimesh

    other = tmp_path / "ball.obj"
    trimesh.creation.icosphere(subdivisions=2).export(other)
    rc = main(["hbasis", "render", str(other), str(grace_path), "--coeffs", str(out), "-o",
               str(tmp_path / "x.png")])
    err = capsys.readouterr().err
    assert rc == 1 and err.count("\n") == 1 and "another mesh" in err and "c.npz" in err
    assert not (tmp_path / "x.png").exists()
    rc = main(["hbasis", "render", str(bunny_path), str(grace_path), "--coeffs",
               str(grace_path), "-o", str(tmp_path / "x.png")])
    err = capsys.readouterr().err
    assert rc == 1 and err.count("\n") == 1 and "grace.hdr" in err


def test_cli_study_and_errors(tmp_path, capsys, monkeypatch):
    assert main(["hbasis", "study", "--signals", "50", "-o", str(tmp_path / "s")]) == 0
    for ext in ("md", "csv", "png"):
        assert (tmp_path / "s" / f"hbasis_study.{ext}").stat().st_size > 100
    out = capsys.readouterr().out
    assert out == ""  # the tables are the files' (--table prints them too)
    md = (tmp_path / "s" / "hbasis_study.md").read_text()
    assert "| 6 | H6 |" in md and "Gram matrix of SH4 (LSQ)" in md
    # existing outputs are refused before the study runs, not after
    import shprobe.hbasis.study as study_mod

    def boom(*a, **k):
        raise AssertionError("the study ran before the output check")

    monkeypatch.setattr(study_mod, "run_study", boom)
    (tmp_path / "t").mkdir()
    (tmp_path / "t" / "hbasis_study.png").write_bytes(b"x")
    rc = main(["hbasis", "study", "--signals", "50", "-o", str(tmp_path / "t")])
    err = capsys.readouterr().err
    assert rc == 1 and "already exists" in err and err.count("\n") == 1
    assert (tmp_path / "t" / "hbasis_study.png").read_bytes() == b"x"
    assert not (tmp_path / "t" / "hbasis_study.md").exists()
    monkeypatch.undo()
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

    from shprobe.hbasis.normalmap import read_normal_map
    from shprobe.hbasis.rendering import render_normal_mapped
    from shprobe.lighting.source import resolve_lighting
    from shprobe.sh.zonal import clamped_cosine_factors, convolve

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
    light = resolve_lighting(coeffs=tmp_path / "L.npy", lmax=None).coeffs
    res = render_normal_mapped(mesh, light, size=16, normal_map=nmap)
    t = nmap[0, 0]
    world = np.array([t[0], -t[1] if mirror else t[1], t[2]])
    e = convolve(L, clamped_cosine_factors(2))
    expect = sh_basis(world, 2) @ e
    ref = res.irradiance[res.mask]
    assert res.mask.mean() > 0.5
    np.testing.assert_allclose(ref, np.broadcast_to(expect, ref.shape), rtol=1e-10)
    # l ≤ 2 lighting: SH9 is exact, and H6 is its hemispherical projection
    np.testing.assert_allclose(res.layers["SH9"][res.mask], ref, rtol=1e-10)
    assert res.info["rel_rms"]["SH9"] < 1e-10
    # H6 at the looked-up tangent normal (green flipped on the mirrored chart), one flat frame
    fr = tangent_frames(verts, np.array(faces), uvs=uv)
    np.testing.assert_allclose(fr.handedness, -1 if mirror else 1)
    vt = np.array([t[0], -t[1] if mirror else t[1], t[2]])
    h6 = shade_h(bake_normalmap(e, fr.matrix[:1]).h[0], vt)
    np.testing.assert_allclose(res.layers["H6"][res.mask], np.broadcast_to(h6, ref.shape),
                               rtol=1e-10)


@pytest.mark.parametrize("probe", ["grace", "ennis"])
def test_render_pixels_match_independent_projection(bunny_path, probe):
    """Rendered pixels of `hbasis render` against an independent per-pixel computation that
    uses neither SH, rotation nor T_h: brute-force irradiance straight from the probe's pixels,
    projected onto H6 by quadrature in each vertex's frame (and in each pixel's own frame)."""
    from shprobe.hbasis.rendering import render_normal_mapped
    from shprobe.lighting import project
    from shprobe.probes.env import load_env
    from shprobe.scene import load_mesh
    from tests.conftest import data_file

    path = data_file("probes", f"{probe}.hdr")
    mesh = load_mesh(bunny_path)
    env = load_env(path)
    res = render_normal_mapped(mesh, env, size=40)
    d, rad, sa = env.samples()
    ld = np.asarray(rad, dtype=np.float64) * sa[:, None]

    def irr(n):  # E(n) = Σ_pixels L max(n·ω, 0) dω
        return np.maximum(np.asarray(n) @ d.T, 0) @ ld

    u, wu, _, _ = theta_quadrature_hemisphere(16, 32)
    hu = h_basis(u) * wu[:, None]
    rng = np.random.default_rng(3)
    hit_pixels = np.flatnonzero(res.mask)  # flat pixel index of each hit, row-major
    pick = rng.choice(len(hit_pixels), 12, replace=False)
    pix = hit_pixels[pick]
    world_normals = res.normals.reshape(-1, 3)[pix]
    e_true = irr(world_normals)
    np.testing.assert_allclose(res.irradiance.reshape(-1, 3)[pix], e_true, rtol=1e-10)
    rendered = res.layers["H6"].reshape(-1, 3)[pix]
    hv = h_basis(res.layers["tangent_normals"].reshape(-1, 3)[pix])
    frames = tangent_frames(mesh.vertices, mesh.faces, np.asarray(mesh.vertex_normals)).matrix
    faces = np.asarray(mesh.faces)[res.face.reshape(-1)[pix]]
    bary = res.bary.reshape(-1, 3)[pix].astype(np.float64)
    pixel_frames = res.layers["frames"].reshape(-1, 3, 3)[pix]
    e = convolve(project(env, 16), clamped_cosine_factors(16))
    # what the bake leaves out (bands 5..16 of E) bounds the coefficient difference per vertex
    dropped = np.sqrt(np.sum(e[25:] ** 2, axis=0))
    indep_interp, indep_pixel = [], []
    for k in range(len(pick)):
        coeffs = sum(bary[k, j] * (hu.T @ irr(u @ frames[faces[k, j]].T)) for j in range(3))
        indep_interp.append(hv[k] @ coeffs)
        indep_pixel.append(hv[k] @ (hu.T @ irr(u @ pixel_frames[k].T)))
    indep_interp, indep_pixel = np.array(indep_interp), np.array(indep_pixel)
    # 1. the renderer interpolates exactly the per-vertex H6 projections, up to the bands ≥ 5
    #    its bake drops: |H(v)·Δh| ≤ ‖H(v)‖ ‖E − E_≤4‖
    tol = np.linalg.norm(hv, axis=1)[:, None] * dropped[None] * 1.02 + 1e-6 * e_true.max()
    assert np.all(np.abs(rendered - indep_interp) <= tol)
    scale = np.sqrt(np.mean(e_true**2))
    assert np.abs(rendered - indep_interp).max() < 0.05 * scale  # measured: 0.4 % / 2.4 %
    # 2. its error against brute force is the basis error: per-pixel H6 projection error
    basis_err = np.sqrt(np.mean((indep_pixel - e_true) ** 2)) / scale
    render_err = np.sqrt(np.mean((rendered - e_true) ** 2)) / scale
    assert 0.8 * basis_err <= render_err <= 1.25 * basis_err
    assert res.info["rel_rms"]["H6"] <= 1.5 * basis_err
