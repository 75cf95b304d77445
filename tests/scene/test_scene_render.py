"""Scene renderer (R&H 2001 §3.2): checked against closed-form sphere geometry and the SH
sum; the camera's orbit and framing."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.lighting.irradiance import quadratic_form, shade_irradiance
from shprobe.probes.tonemap import tonemap
from shprobe.scene import (
    Camera,
    load_mesh,
    render,
    render_vertex_colors,
    save_image,
    sphere_mesh,
)
from shprobe.sh import sh_basis
from shprobe.sh.rotation import rotate
from shprobe.sh.zonal import clamped_cosine_factors
from tests.conftest import random_dirs


def brute_E(L: np.ndarray, n: np.ndarray) -> np.ndarray:
    """E(n) = Σ Â_l L_lm y_lm(n) straight from the definition (R&H eq. 7)."""
    lmax = int(np.sqrt(L.shape[0])) - 1
    a = clamped_cosine_factors(lmax)
    Y = sh_basis(np.asarray(n, np.float64), lmax)
    ls = np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)
    return (Y * a[ls]) @ L


def lighting(lmax=2, seed=0):
    L = np.random.default_rng(seed).normal(size=((lmax + 1) ** 2, 3))
    L[0] += 4.0
    return L


def ortho_sphere_normals(w, h):
    """Pixel-centre normals of the unit sphere seen by an orthographic camera on +Z whose view
    is 2 units tall (so the sphere just fills the height); independent of the renderer."""
    aspect = w / h
    x = ((np.arange(w) + 0.5) / w * 2 - 1) * aspect
    y = 1 - (np.arange(h) + 0.5) / h * 2
    X, Y = np.meshgrid(x, y)
    r2 = X**2 + Y**2
    inside = r2 < 1
    n = np.stack([X, Y, np.sqrt(np.maximum(1 - r2, 0))], -1)
    return n, inside


def test_quadratic_form_and_kernel_values():
    L = lighting()
    M = quadratic_form(L)
    # lmax 1 lighting is zero-padded: same M as the padded 9 coefficients
    np.testing.assert_array_equal(quadratic_form(L[:4]), quadratic_form(np.r_[L[:4], 0 * L[4:]]))
    n = random_dirs(500, seed=3)
    nh = np.concatenate([n, np.ones((500, 1))], 1)
    quad = np.einsum("pi,cij,pj->pc", nh, M, nh)
    np.testing.assert_allclose(quad, brute_E(L, n), atol=1e-12)
    np.testing.assert_allclose(shade_irradiance(L, n, dtype=np.float64), brute_E(L, n),
                               atol=1e-12)
    L4 = lighting(4)
    np.testing.assert_allclose(shade_irradiance(L4, n, dtype=np.float64), brute_E(L4, n),
                               atol=1e-12)


@pytest.mark.parametrize("lmax", [2, 4])
def test_sphere_per_pixel_is_E_at_pixel_normal(tmp_path, lmax):
    """Linear EXR of the analytic sphere = E(n)/π at the independently computed normal."""
    import OpenImageIO as oiio

    w, h = 48, 40
    L = lighting(lmax)
    cam = Camera(w, h, projection="orthographic", ortho_height=2.0)
    res = render(None, L, cam)
    n, inside = ortho_sphere_normals(w, h)
    np.testing.assert_array_equal(res.mask, inside)
    save_image(tmp_path / "s.exr", res.image)
    img = oiio.ImageBuf(str(tmp_path / "s.exr")).get_pixels(oiio.FLOAT)
    expect = brute_E(L, n[inside]) / np.pi
    np.testing.assert_allclose(img[inside], expect, rtol=1e-5, atol=1e-6)
    assert np.all(img[~inside] == 0)


def test_mesh_sphere_per_pixel_is_E_at_interpolated_normal():
    """On a tessellated sphere each pixel shows E at its own smooth normal, and that normal is
    within the tessellation error of the true sphere normal."""
    w = h = 40
    L = lighting()
    cam = Camera(w, h, projection="orthographic", ortho_height=2.0)
    res = render(sphere_mesh(5), L, cam)
    m = res.mask
    np.testing.assert_allclose(res.irradiance[m], brute_E(L, res.normals[m]), rtol=1e-5,
                               atol=1e-5)
    n, inside = ortho_sphere_normals(w, h)
    core = inside & m & (n[..., 2] > 0.3)
    assert np.degrees(np.arccos(np.clip((n[core] * res.normals[core]).sum(-1), -1, 1))).max() < 1


def test_per_vertex_agrees_with_per_pixel_on_fine_sphere():
    """R&H's per-vertex procedural shader on an icosphere (5 subdivisions, 10242 vertices) is
    within 1% of the peak radiance of per-pixel shading."""
    L = lighting()
    cam = Camera(64, 64)
    mesh = sphere_mesh(5)
    px = render(mesh, L, cam, mode="pixel")
    vx = render(mesh, L, cam, mode="vertex")
    np.testing.assert_array_equal(px.mask, vx.mask)
    peak = px.image[px.mask].max()
    assert np.abs(px.image - vx.image).max() < 0.01 * peak
    assert np.abs(px.image - vx.image).max() > 0  # really two different shaders


def _quad(z=0.0):
    import trimesh

    v = np.array([[-1, -1, z], [1, -1, z], [1, 1, z], [-1, 1, z]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    return trimesh.Trimesh(v, f, process=False)


def test_render_vertex_colors_interpolates_linear_field():
    """Barycentric interpolation reproduces a linear function of position exactly; pixel
    centres of an orthographic view of the quad z=0 are known in closed form."""
    mesh = _quad()
    coef = np.array([[0.3, -0.2, 0.1], [0.05, 0.4, -0.1], [0.0, 0.0, 0.0]])
    vr = mesh.vertices @ coef + np.array([1.0, 2.0, 3.0])
    w, h = 32, 32
    cam = Camera(w, h, projection="orthographic", ortho_height=1.5)
    res = render_vertex_colors(mesh, vr, cam)
    x = ((np.arange(w) + 0.5) / w * 2 - 1) * 0.75
    y = (1 - (np.arange(h) + 0.5) / h * 2) * 0.75
    X, Y = np.meshgrid(x, y)
    p = np.stack([X, Y, np.zeros_like(X)], -1)
    assert res.mask.all()
    np.testing.assert_allclose(res.image, p @ coef + [1.0, 2.0, 3.0], atol=2e-5)
    with pytest.raises(ShprobeError):
        render_vertex_colors(mesh, vr[:3], cam)


def test_camera_orbit_directions():
    """Azimuth 90° puts the camera on +X, elevation 90° above (+Y): the centre pixel's normal
    on the unit sphere points back at the camera."""
    for az, el, expect in [(0, 0, [0, 0, 1]), (90, 0, [1, 0, 0]), (180, 0, [0, 0, -1]),
                           (0, 90, [0, 1, 0]), (-90, 0, [-1, 0, 0])]:
        res = render(None, np.eye(9)[0], Camera(11, 11, azimuth=az, elevation=el))
        np.testing.assert_allclose(res.normals[5, 5], expect, atol=1e-6)
    _fwd, right, up = Camera().basis()
    np.testing.assert_allclose(right, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(up, [0, 1, 0], atol=1e-12)


def test_albedo_constant_vertex_and_texture():
    from PIL import Image
    from trimesh.visual import TextureVisuals
    from trimesh.visual.material import SimpleMaterial

    L = lighting()
    cam = Camera(16, 16, projection="orthographic", ortho_height=1.0)
    mesh = _quad()
    base = render(mesh, L, cam)
    # constant colour
    res = render(mesh, L, cam, albedo=[0.5, 0.25, 1.0])
    np.testing.assert_allclose(res.image, base.image * [0.5, 0.25, 1.0], rtol=1e-6)
    # per-vertex albedo, all equal → same as constant
    res = render(mesh, L, cam, albedo=np.full((4, 3), 0.5))
    np.testing.assert_allclose(res.image, base.image * 0.5, rtol=1e-5)
    # texture: left half red, right half blue (sRGB 255 = linear 1)
    tex = np.zeros((8, 8, 3), np.uint8)
    tex[:, :4, 0] = 255
    tex[:, 4:, 2] = 255
    uv = (mesh.vertices[:, :2] + 1) / 2
    tm = mesh.copy()
    tm.visual = TextureVisuals(uv=uv, material=SimpleMaterial(image=Image.fromarray(tex)))
    res = render(tm, L, cam)
    # the view covers x in [-0.5, 0.5]: u in [0.25, 0.75]; pixel columns 0..5 sample texels 2..3
    left, right = res.image[:, :6], res.image[:, -6:]
    np.testing.assert_allclose(left[..., 0], base.image[:, :6, 0], rtol=1e-5)
    assert np.all(left[..., 1:] == 0) and np.all(right[..., :2] == 0)
    np.testing.assert_allclose(right[..., 2], base.image[:, -6:, 2], rtol=1e-5)


def test_background_is_environment_lookup():
    """Env radiance = direction + 1 on a lat-long grid: an orthographic camera sees one
    direction, its view direction, in every background pixel."""
    from shprobe.probes.env import Env
    from shprobe.probes.layouts import get_layout

    d = get_layout("latlong").pixel_directions((64, 128))
    env = Env((d + 1).astype(np.float32), "latlong")
    for az, view in [(0, [0, 0, -1]), (90, [-1, 0, 0]), (180, [0, 0, 1])]:
        cam = Camera(12, 10, projection="orthographic", azimuth=az)
        res = render(None, lighting(), cam, background=env)
        bg = res.image[~res.mask]
        assert len(bg) > 0
        np.testing.assert_allclose(bg, np.tile(np.add(view, 1), (len(bg), 1)), atol=0.02)
    # perspective: each background pixel shows the env in its own ray direction
    cam = Camera(12, 10, fov=60)
    res = render(None, lighting(), cam, background=env.radiance)
    _, dirs = cam.rays(np.zeros(3), 1.0)
    miss = ~res.mask.reshape(-1)
    np.testing.assert_allclose(res.image.reshape(-1, 3)[miss], env.sample(dirs[miss]),
                               rtol=1e-6)
    np.testing.assert_allclose(res.image.reshape(-1, 3)[miss], dirs[miss] + 1, atol=0.02)
    res2 = render(None, lighting(), Camera(9, 9), background=[0.1, 0.2, 0.3])
    np.testing.assert_allclose(res2.image[~res2.mask], np.tile([0.1, 0.2, 0.3], (
        (~res2.mask).sum(), 1)), rtol=1e-6)


def test_bunny_renders_without_holes(bunny_path, tmp_path):
    from PIL import Image
    from scipy import ndimage

    mesh = load_mesh(bunny_path)
    L = lighting()
    for mode in ("pixel", "vertex"):
        res = render(mesh, L, Camera(160, 160, azimuth=30, elevation=15), mode=mode,
                     background=[0.2, 0.2, 0.2])
        assert np.isfinite(res.image).all()
        assert 0.1 < res.mask.mean() < 0.9
        filled = ndimage.binary_fill_holes(res.mask)
        assert (filled & ~res.mask).sum() == 0
        assert (res.radiance[res.mask] > 0).all()
    save_image(tmp_path / "b.png", res.image)
    with pytest.raises(ShprobeError):
        save_image(tmp_path / "b.png", res.image)
    im = np.asarray(Image.open(tmp_path / "b.png"))
    assert im.shape == (160, 160, 3) and im.dtype == np.uint8
    np.testing.assert_array_equal(im, tonemap(res.image))


def test_rotation_equivalence():
    """Rotating the lighting by R equals rotating the normals by R⁻¹ (R&H §3.2)."""
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("zyx", [30, -50, 70], degrees=True).as_matrix()
    L = lighting()
    mesh = sphere_mesh(4)
    cam = Camera(48, 48, azimuth=20, elevation=10)
    res = render(mesh, rotate(L, R), cam)
    n = res.normals[res.mask].astype(np.float64)
    # E of the original lighting at R⁻¹ n: rotate normals the inverse way
    expect = shade_irradiance(L, n @ R, dtype=np.float64) / np.pi
    np.testing.assert_allclose(res.image[res.mask], expect, rtol=1e-4, atol=1e-5)
