"""Rendering PRT (Lisle & Huang 2007 §4): rendered pictures against independent
quadrature and geometry, the turntable against a window turned by hand, and bad input."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shprobe.cli.main import main
from shprobe.errors import ShprobeError
from shprobe.probes.images import read_image, write_image
from shprobe.prt import bake, load_transfer
from shprobe.sh import sh_basis
from tests.conftest import fails_with_one_line, write_raw_pfm


@pytest.fixture
def sphere_transfer(tmp_path, sphere_obj):
    out = tmp_path / "t.npz"
    assert main(["prt", "bake", str(sphere_obj), "--mode", "unshadowed", "--lmax", "6",
                 "--albedo", "1", "-o", str(out)]) == 0
    return out


def irradiance_by_quadrature(coeffs, n, lmax):
    """∫ L(ω) max(0, n·ω) dω over n's hemisphere, Gauss–Legendre in cos θ × uniform φ (exact
    for band-limited L; no Â_l)."""
    mu, wmu = np.polynomial.legendre.leggauss(lmax + 4)
    mu, wmu = 0.5 * (mu + 1.0), 0.5 * wmu
    nphi = 2 * lmax + 6
    phi = 2.0 * np.pi * np.arange(nphi) / nphi
    t1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    s = np.sqrt(1.0 - mu**2)[:, None, None]
    w = s * (np.cos(phi)[None, :, None] * t1 + np.sin(phi)[None, :, None] * t2) \
        + mu[:, None, None] * n
    f = sh_basis(w.reshape(-1, 3), lmax) @ np.asarray(coeffs).reshape(len(coeffs), -1)
    return np.repeat(wmu * mu * 2.0 * np.pi / nphi, nphi) @ f


# ----------------------------------------------------------------------------- pictures


def test_rendered_sphere_lit_from_the_window_side(tmp_path, sphere_transfer):
    """Camera at +Z (azimuth 0, elevation 0) with +X to the right: a window on +X lights the
    right half; the pixel at the image centre (normal +Z) has ρ/π E(+Z), E by quadrature."""
    from shprobe.sh.zonal import circular_window

    out = tmp_path / "x.pfm"
    assert main(["prt", "render", str(sphere_transfer), "--cone", "1,0,0:60", "--size",
                 "65x65", "--elevation", "0", "-o", str(out)]) == 0
    img = read_image(out, clamp=True)[..., 0]  # SH ringing: negatives -> 0
    n = 65
    assert img[:, n // 2 + 4:].sum() > 3 * img[:, : n // 2 - 4].sum()  # lit from the right (≈ 5×)
    row, col = np.unravel_index(np.argmax(img), img.shape)
    assert col > 0.7 * n and abs(row - n // 2) <= 0.1 * n  # brightest towards +X
    want = irradiance_by_quadrature(circular_window(np.array([1.0, 0, 0]), np.radians(60), 6),
                                    np.array([0.0, 0.0, 1.0]), 6)[0] / np.pi
    # vertex colours interpolated over the icosphere's ~8° triangles: a few per cent
    assert img[n // 2, n // 2] == pytest.approx(want, rel=0.05, abs=0.01 * float(img.max()))


def test_turntable_frame_is_the_window_turned_by_hand(tmp_path, sphere_transfer):
    """Frame i turns the lighting by 360°·i/N about +Y: frame 1 of 4 under a window on +X is the
    still render of the window on R_y(90°)·X = −Z (LH §3.2 window about R a; no Wigner)."""
    assert main(["prt", "render", str(sphere_transfer), "--cone", "1,0,0:40", "--size",
                 "48x40", "--turntable", "4", "-o", str(tmp_path / "f.pfm")]) == 0
    assert main(["prt", "render", str(sphere_transfer), "--cone", "0,0,-1:40", "--size",
                 "48x40", "-o", str(tmp_path / "still.pfm")]) == 0
    frame = read_image(tmp_path / "f_001.pfm", clamp=True)
    still = read_image(tmp_path / "still.pfm", clamp=True)
    np.testing.assert_allclose(frame, still, atol=1e-4 * still.max())
    f0 = read_image(tmp_path / "f_000.pfm", clamp=True)
    assert np.abs(f0 - frame).max() > 0.1 * still.max()


def test_auto_exposure_neither_blown_out_nor_dark(tmp_path, sphere_transfer, capsys):
    from PIL import Image

    png = tmp_path / "w.png"
    # a 30° window of total power 4π: radiance ≈ 15, far above white at exposure 0
    assert main(["prt", "render", str(sphere_transfer), "--cone", "0,1,0:30", "--size",
                 "64x64", "-o", str(png)]) == 0
    img = np.asarray(Image.open(png)).max(axis=2)
    lit = img[img > 0]
    assert 180 <= lit.max() <= 255
    assert (lit == 255).mean() < 0.02
    fails_with_one_line(capsys, ["prt", "render", str(sphere_transfer), "--cone", "0,1,0:30",
                            "--exposure", "nan", "-o", str(tmp_path / "n.png")], "exposure")


# ----------------------------------------------------------------------------- bad input


def test_render_checks_output_format_first(tmp_path, sphere_transfer, capsys):
    for args in ([], ["--turntable", "2"]):
        fails_with_one_line(capsys, ["prt", "render", str(sphere_transfer), "--cone", "0,1,0:30",
                                *args, "-o", str(tmp_path / "x.bmp")], "x.bmp", ".bmp")
    assert list(tmp_path.glob("x*")) == []


def test_render_layout_option_reaches_the_probe(tmp_path, sphere_transfer, capsys):
    probe = tmp_path / "probe.exr"
    write_image(probe, np.ones((32, 48, 3), np.float32))  # 3:2: no layout fits
    fails_with_one_line(capsys, ["prt", "render", str(sphere_transfer), str(probe), "--layout",
                            "latlong", "-o", str(tmp_path / "x.png")], "probe.exr", "2:1")
    a = np.ones((16, 32, 3), np.float32)
    a[2, 3, 0] = np.nan
    nan = write_raw_pfm(tmp_path / "nan.pfm", a)
    fails_with_one_line(capsys, ["prt", "render", str(sphere_transfer), str(nan), "-o",
                            str(tmp_path / "x.png")], "nan.pfm", "NaN", "--clamp")
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("content", [b"", b"hello\n", b"PK\x03\x04 truncated"])
def test_bad_transfer_files_are_one_line(tmp_path, capsys, content):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(content)
    fails_with_one_line(capsys, ["prt", "render", str(bad), "--cone", "0,1,0:30", "-o",
                            str(tmp_path / "x.png")], "bad.npz", "not a transfer file")
    other = tmp_path / "other.npz"
    np.savez(other, a=np.zeros(3))
    with pytest.raises(ShprobeError, match="no vertices, normals"):
        load_transfer(other)


def test_truncated_transfer_file(tmp_path, sphere_transfer, capsys):
    data = sphere_transfer.read_bytes()
    cut = tmp_path / "cut.npz"
    cut.write_bytes(data[: len(data) // 2])
    fails_with_one_line(capsys, ["prt", "render", str(cut), "--cone", "0,1,0:30", "-o",
                            str(tmp_path / "x.png")], "cut.npz")


def test_hash_check_with_ground_and_several_meshes(tmp_path, capsys):
    a, b = tmp_path / "a.obj", tmp_path / "b.obj"
    trimesh.creation.icosphere(subdivisions=1).export(a)
    trimesh.creation.box().apply_translation([3.0, 0.0, 0.0]).export(b)
    out = tmp_path / "t.npz"
    assert main(["prt", "bake", str(a), str(b), "--ground", "--mode", "unshadowed", "--lmax",
                 "2", "-o", str(out)]) == 0
    t = load_transfer(out, scene=[a, b])  # the ground is rebuilt from the meshes
    assert t.metadata["ground"] is True
    assert t.n_vertices > len(trimesh.load(a).vertices) + len(trimesh.load(b).vertices)
    with pytest.raises(ShprobeError, match="baked for mesh"):
        load_transfer(out, scene=[a])
    with pytest.raises(ShprobeError, match="baked for mesh"):
        load_transfer(out, scene=[b, a])
    fails_with_one_line(capsys, ["prt", "render", str(out), "--cone", "0,1,0:30", "--scene",
                            str(a), "-o", str(tmp_path / "x.png")], "baked for mesh")


def test_zero_normals_are_refused(tmp_path, capsys):
    bad = tmp_path / "flat.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")  # a triangle of zero area
    with pytest.raises(ShprobeError, match=r"flat\.obj.*(zero or non-finite normal|no normals)"):
        bake(bad, mode="unshadowed", lmax=2)
    fails_with_one_line(capsys, ["prt", "bake", str(bad), "-o", str(tmp_path / "x.npz")],
                   "flat.obj", "normal")
    assert not (tmp_path / "x.npz").exists()


def test_turntable_frames_the_object_not_the_ground(tmp_path):
    """With a ground plane (several times the object) the camera frames the object: the
    frame sphere is the object's bounding sphere, and the rendered object fills as much of
    the picture as without the ground."""
    from shprobe.prt import bake
    from shprobe.prt.view import object_frame, render_frame
    from shprobe.scene import Camera, sphere_mesh

    mesh = sphere_mesh(2)
    plain = bake(mesh, mode="unshadowed", lmax=2)
    grounded = bake(mesh, mode="unshadowed", lmax=2, ground=True)
    assert object_frame(plain) is None
    c, r = object_frame(grounded)
    np.testing.assert_allclose(c, 0.0, atol=1e-9)
    assert abs(r - 1.0) < 1e-6  # the unit sphere, not the ground's half-diagonal
    L = np.zeros((9, 3))
    L[0] = 1.0
    cam = Camera(64, 64, elevation=0.0)
    a = render_frame(plain, L, camera=cam)
    b = render_frame(grounded, L, camera=cam)
    assert a.mask.sum() > 0.4 * 64 * 64  # framed: the sphere fills the picture
    # the same framing with the ground: the sphere covers the same pixels, the ground more
    assert b.mask.sum() >= a.mask.sum() and (b.mask | ~a.mask).all()
