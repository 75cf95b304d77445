"""Basis images (R&H Fig. 4) and the relighting identity; the render / basis-images / edit /
window / export commands."""

from __future__ import annotations

import json

import numpy as np
import pytest

from shprobe.cli.main import main
from shprobe.lighting.export import import_coeffs
from shprobe.scene import Camera, basis_images, load_mesh, relight, render, sphere_mesh


def _L(seed=3):
    L = np.random.default_rng(seed).normal(size=(9, 3))
    L[0] += 3
    return L


@pytest.mark.parametrize("mode", ["pixel", "vertex"])
def test_relighting_identity(mode):
    """image under L == Σ_k L_k · basis_k, to float32 rounding (R&H §3.3)."""
    mesh = sphere_mesh(3)
    cam = Camera(40, 32, azimuth=40, elevation=20)
    B = basis_images(mesh, cam, mode=mode)
    assert B.image.shape == (32, 40, 9)
    for seed in range(3):
        L = _L(seed)
        img = render(mesh, L, cam, mode=mode).image
        np.testing.assert_allclose(relight(B.image, L), img, rtol=1e-5, atol=1e-6)


def test_basis_image_values_are_Ahat_y_over_pi():
    """Channel k on the analytic sphere is Â_l y_k(n)/π at the pixel normal."""
    from shprobe.sh import sh_basis
    from shprobe.sh.zonal import clamped_cosine_factors

    B = basis_images(None, Camera(24, 24))
    n = B.normals[B.mask].astype(np.float64)
    A = clamped_cosine_factors(2)[[0, 1, 1, 1, 2, 2, 2, 2, 2]]
    np.testing.assert_allclose(B.image[B.mask], sh_basis(n, 2) * A / np.pi, atol=1e-6)


def run(*args):
    return main([str(a) for a in args])


def test_cli_render_png_and_exr(tmp_path, capsys):
    import OpenImageIO as oiio

    (tmp_path / "L.json").write_text(json.dumps({"format": "shprobe-coeffs",
                                                 "coefficients": _L().tolist()}))
    out, exr = tmp_path / "s.png", tmp_path / "s.exr"
    assert run("render", "--coeffs", tmp_path / "L.json", "--sphere", "--size", "32x24",
               "--ortho", "-o", out, "--exr", exr) == 0
    img = oiio.ImageBuf(str(exr)).get_pixels(oiio.FLOAT)
    ref = render(None, _L(), Camera(32, 24, projection="orthographic")).image
    assert ref.min() < 0  # the SH irradiance dips below zero: the file holds radiance >= 0
    np.testing.assert_allclose(img, np.maximum(ref, 0), rtol=1e-6)
    assert run("render", "--coeffs", tmp_path / "L.json", "--sphere", "-o", out) == 1
    assert "already exists" in capsys.readouterr().err


def test_cli_render_bunny_probe(tmp_path, grace_path, bunny_path):
    from PIL import Image

    out = tmp_path / "b.png"
    assert run("render", grace_path, "--mesh", bunny_path, "--size", "64x64", "--mode",
               "vertex", "-o", out) == 0
    im = np.asarray(Image.open(out))
    assert im.shape == (64, 64, 3)
    assert im.std() > 5  # background shows the probe, the bunny is shaded


def test_cli_basis_images(tmp_path, capsys):
    from PIL import Image

    d = tmp_path / "basis"
    assert run("basis-images", "--sphere", "--size", "25x25", "--ortho", "-o", d) == 0
    names = sorted(p.name for p in d.iterdir())
    assert len([n for n in names if n.endswith(".exr")]) == 9
    assert "basis.png" in names and "basis_l1_m-1.png" in names
    # R&H Fig. 4 colouring: positive green, negative blue. Orthographic camera on +Z: the
    # centre pixel sees n = +Z, where y_10 > 0 and y_20 > 0; the right edge n ≈ +X, where
    # y_20 = 0.315(3z² − 1) < 0 and y_11 > 0, the left edge n ≈ −X with y_11 < 0.
    px = {k: np.asarray(Image.open(d / f"basis_{k}.png")).astype(int)
          for k in ("l1_m+0", "l2_m+0", "l1_m+1")}
    c, e = 12, 23
    assert px["l1_m+0"][c, c, 1] > 100 and px["l1_m+0"][c, c, 2] == 0
    assert px["l2_m+0"][c, c, 1] > 50 and px["l2_m+0"][c, e, 2] > 30
    assert px["l2_m+0"][c, e, 1] == 0
    assert px["l1_m+1"][c, e, 1] > 100 and px["l1_m+1"][c, 1, 2] > 100
    assert px["l1_m+1"][c, 1, 1] == 0 and np.all(px["l1_m+1"][..., 0] == 0)
    # one existing output: refused before anything is written
    d2 = tmp_path / "b2"
    d2.mkdir()
    (d2 / "basis.png").write_bytes(b"keep")
    capsys.readouterr()
    assert run("basis-images", "--sphere", "--size", "8x8", "-o", d2) == 1
    assert "basis.png" in capsys.readouterr().err
    assert [p.name for p in d2.iterdir()] == ["basis.png"]


def test_cli_edit_lights_and_edits(tmp_path, capsys):
    from shprobe.lighting import design

    out = tmp_path / "e.json"
    assert run("edit", "--sky", "1,1,1:0.2,0.2,0.2", "--directional", "0,1,0:3,2,1",
               "--scale", "1,1=2", "--negate-band", "2", "-o", out) == 0
    L = import_coeffs(out)
    ref = design.sky_light((0, 1, 0), [1, 1, 1], [0.2, 0.2, 0.2]) + design.directional_light(
        (0, 1, 0), [3, 2, 1])
    ref = design.negate_band(design.scale_coeff(ref, 1, 1, 2), 2)
    np.testing.assert_allclose(L, ref, atol=1e-12)
    # rotate, and start from that file
    out2 = tmp_path / "r.json"
    assert run("edit", "--coeffs", out, "--rotate", "0,1,0:90", "-o", out2) == 0
    from shprobe.sh.rotation import rotate

    R = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], float)  # 90° about +Y
    np.testing.assert_allclose(import_coeffs(out2), rotate(L, R), atol=1e-10)
    assert run("edit", "--set", "1,5=1", "-o", tmp_path / "bad.json") == 1
    assert run("edit", "--cone", "0,0,1:200:1", "-o", tmp_path / "bad.json") == 1
    assert "degrees" in capsys.readouterr().err
    # edits above --lmax are refused, not silently grown
    for args in (["--set", "3,0=1"], ["--negate-band", "5"], ["--scale-band", "3=2"]):
        assert run("edit", "--preset", "grace", *args, "-o", tmp_path / "x.json") == 1
    assert not (tmp_path / "x.json").exists()
    assert run("edit", "--preset", "grace", "--lmax", "3", "--set", "3,0=1",
               "-o", tmp_path / "x.json") == 0
    assert import_coeffs(tmp_path / "x.json").shape == (16, 3)


def test_cli_edit_blends_a_probe_image(tmp_path, grace_path, ennis_path):
    """--blend PROBE:W projects the image: grace + 0.5·ennis."""
    from shprobe.lighting.projection import project
    from shprobe.probes.env import load_env

    out = tmp_path / "b.json"
    assert run("edit", grace_path, "--blend", f"{ennis_path}:0.5", "-o", out) == 0
    want = project(load_env(grace_path), 2) + 0.5 * project(load_env(ennis_path), 2)
    np.testing.assert_allclose(import_coeffs(out), want, rtol=1e-6, atol=1e-9)


def test_cli_window_ennis(tmp_path, ennis_path, capsys):
    out = tmp_path / "w.json"
    assert run("window", ennis_path, "-o", out) == 0
    text = capsys.readouterr().out
    before = next(ln for ln in text.splitlines() if ln.startswith("before"))
    after = next(ln for ln in text.splitlines() if ln.startswith("after"))
    assert "-" in before.split("=")[1].split("[")[0]  # a negative minimum before
    assert "-" not in after.split("=")[1].split("[")[0].replace("e-", "e")
    assert "chosen:" in text
    from shprobe.lighting.windows import min_irradiance

    assert min_irradiance(import_coeffs(out)).nonnegative


@pytest.mark.parametrize("fmt", ["glsl", "three", "cmgen"])
def test_cli_export_round_trip(tmp_path, fmt):
    src = tmp_path / "L.json"
    src.write_text(json.dumps({"format": "shprobe-coeffs", "coefficients": _L().tolist()}))
    out = tmp_path / f"x.{fmt}"
    assert run("export", "--coeffs", src, "--format", fmt, "-o", out) == 0
    np.testing.assert_allclose(import_coeffs(out), _L(), atol=1e-8)


def test_cli_bad_mesh_is_one_line(tmp_path, capsys):
    (tmp_path / "m.obj").write_text("garbage\n")
    (tmp_path / "L.json").write_text(json.dumps({"coefficients": _L().tolist()}))
    assert run("render", "--coeffs", tmp_path / "L.json", "--mesh", tmp_path / "m.obj",
               "-o", tmp_path / "x.png") == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("shprobe: error:") and "m.obj" in err and "\n" not in err
    # a point and a flat sliver: no extent / no normals, named
    (tmp_path / "p.obj").write_text("v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n")
    (tmp_path / "s.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    for name, what in (("p.obj", "zero extent"), ("s.obj", "non-zero area")):
        assert run("render", "--coeffs", tmp_path / "L.json", "--mesh", tmp_path / name,
                   "-o", tmp_path / "x.png") == 1
        err = capsys.readouterr().err.strip()
        assert name in err and what in err and "\n" not in err, err


def test_bunny_loads(bunny_path):
    m = load_mesh(bunny_path)
    assert len(m.faces) > 1000


def test_cli_prefilter_export_feeds_render(tmp_path, grace_path):
    """`shprobe prefilter --format gltf` → `render --coeffs` uses the same lighting as the probe."""
    from shprobe.lighting.projection import project
    from shprobe.probes.env import load_env

    out = tmp_path / "g.gltf.json"
    assert run("prefilter", grace_path, "--format", "gltf", "-o", out) == 0
    np.testing.assert_allclose(import_coeffs(out), project(load_env(grace_path), 2),
                               rtol=1e-9, atol=1e-12)
    assert run("render", "--coeffs", out, "--sphere", "--size", "16x16", "-o",
               tmp_path / "g.png") == 0
    assert run("render", "--preset", "grace", "--sphere", "--size", "16x16", "-o",
               tmp_path / "p.png") == 0
