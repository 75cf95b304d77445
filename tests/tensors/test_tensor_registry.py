"""The convention registry (shprobe.sh.registry): each entry against an independent
evaluation of that convention's basis — published constants of 3DGS, kaolin and three.js
written out here, e3nn and pyshtools themselves, the shader polynomials of Unity and Filament
— plus round trips and the array-API path."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.lighting.irradiance import irradiance
from shprobe.sh import sh_basis
from shprobe.sh.registry import CONVENTIONS, convention_matrix, convert
from tests.tensors.tensor_support import coeffs, need, unit

D = unit(40, 11)


def value(c, lmax):
    """f(d) = Σ c_k y_k(d) in shprobe's basis, (40, C)."""
    return sh_basis(D, lmax) @ c


def gs_basis(d):
    """3D Gaussian splatting's eval_sh (l ≤ 3), its constants SH_C0..SH_C3 as published."""
    x, y, z = d.T
    c0, c1 = 0.28209479177387814, 0.4886025119029199
    c2 = [1.0925484305920792, -1.0925484305920792, 0.31539156525252005,
          -1.0925484305920792, 0.5462742152960396]
    c3 = [-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
          -0.4570457994644658, 1.445305721320277, -0.5900435899266435]
    xx, yy, zz = x * x, y * y, z * z
    return np.stack([
        c0 + 0 * x, -c1 * y, c1 * z, -c1 * x,
        c2[0] * x * y, c2[1] * y * z, c2[2] * (2 * zz - xx - yy), c2[3] * x * z,
        c2[4] * (xx - yy),
        c3[0] * y * (3 * xx - yy), c3[1] * x * y * z, c3[2] * y * (4 * zz - xx - yy),
        c3[3] * z * (2 * zz - 3 * xx - 3 * yy), c3[4] * x * (4 * zz - xx - yy),
        c3[5] * z * (xx - yy), c3[6] * x * (xx - 3 * yy)], axis=-1)


def kaolin_sh9(d):
    """kaolin's sh9 basis (render.lighting): CS-signed R&H constants."""
    x, y, z = d.T
    return np.stack([0.282095 + 0 * x, -0.488603 * y, 0.488603 * z, -0.488603 * x,
                     1.092548 * x * y, -1.092548 * y * z, 0.315392 * (3 * z * z - 1),
                     -1.092548 * x * z, 0.546274 * (x * x - y * y)], axis=-1)


def three_sh3(d):
    """three.js SphericalHarmonics3.getAt's basis."""
    x, y, z = d.T
    return np.stack([0.282095 + 0 * x, 0.488603 * y, 0.488603 * z, 0.488603 * x,
                     1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3 * z * z - 1),
                     1.092548 * x * z, 0.546274 * (x * x - y * y)], axis=-1)


@pytest.mark.parametrize("name,basis,lmax,tol", [
    ("3dgs", gs_basis, 3, 1e-13), ("kaolin", kaolin_sh9, 2, 2e-6), ("gltf", kaolin_sh9, 2, 2e-6),
    ("cs", gs_basis, 3, 1e-13), ("three", three_sh3, 2, 2e-6)])
def test_published_bases(name, basis, lmax, tol):
    c = coeffs(lmax)
    np.testing.assert_allclose(basis(D) @ convert(c, to=name), value(c, lmax), atol=tol * 20)


def test_e3nn_closed_form():
    c = coeffs(4)
    b = convert(c, to="e3nn")
    # l = 1 closed form: e3nn's integral-normalised Y1(v) = √(3/4π) (x, y, z)
    y1 = np.sqrt(3 / (4 * np.pi)) * D
    np.testing.assert_allclose(y1 @ b[1:4], sh_basis(D, 1)[:, 1:4] @ c[1:4], atol=1e-13)
    # higher bands: the relabelling of the axes is a rotation, so e3nn's basis of band l at v
    # is shprobe's at Qv; checked here against shprobe's own basis at the turned directions
    Q = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    np.testing.assert_allclose(sh_basis(D @ Q.T, 4) @ b, value(c, 4), atol=1e-12)


def test_e3nn_itself():
    """e3nn itself (a dev requirement) evaluates its own harmonics."""
    c = coeffs(4)
    b = convert(c, to="e3nn")
    torch = need("torch")
    o3 = need("e3nn.o3")
    Y = np.concatenate([o3.spherical_harmonics(l, torch.tensor(D), normalize=True,
                                               normalization="integral").numpy()
                        for l in range(5)], axis=-1)
    np.testing.assert_allclose(Y @ b, value(c, 4), atol=1e-12)


def test_four_pi_against_pyshtools():
    sht = pytest.importorskip("pyshtools")
    lmax = 4
    c = coeffs(lmax, 1)[:, 0]
    theta = np.degrees(np.arccos(D[:, 2]))
    phi = np.degrees(np.arctan2(D[:, 1], D[:, 0]))
    for name, cs in (("4pi", 1), ("4pi-cs", -1)):
        a = convert(c, to=name)
        f = np.zeros(len(D))
        for i in range(len(D)):
            Y = sht.expand.spharm(lmax, theta[i], phi[i], normalization="4pi", kind="real",
                                  csphase=cs)
            for k in range(len(c)):
                l = int(np.sqrt(k))
                m = k - l * (l + 1)
                f[i] += a[k] * (Y[0, l, m] if m >= 0 else Y[1, l, -m])
        np.testing.assert_allclose(f, value(c, lmax), atol=1e-12)


def test_shader_polynomials_unity_and_filament():
    c = coeffs(2)
    e = irradiance(c, D) / np.pi
    x, y, z = D.T
    u = convert(c, to="unity")  # (A.xyzw, B.xyzw, C)
    poly = np.stack([x, y, z, 1 + 0 * x, x * y, y * z, z * z, x * z, x * x - y * y], -1)
    np.testing.assert_allclose(poly @ u, e, atol=1e-13)
    f = convert(c, to="filament")  # Filament: c0 + c1 y + c2 z + c3 x + c4 yx + ...
    fpoly = np.stack([1 + 0 * x, y, z, x, y * x, y * z, 3 * z * z - 1, z * x, x * x - y * y], -1)
    np.testing.assert_allclose(fpoly @ f, e, atol=1e-13)


def test_round_trips_and_errors():
    for name, conv in CONVENTIONS.items():
        lmax = 2 if conv.lmax == 2 else 5
        c = coeffs(lmax, batch=(2,))
        np.testing.assert_allclose(convert(convert(c, to=name), from_=name), c, atol=1e-12)
        assert convention_matrix(name, lmax).shape == ((lmax + 1) ** 2,) * 2
    np.testing.assert_allclose(convert(coeffs(3), from_="3dgs", to="e3nn"),
                               convert(convert(coeffs(3), from_="3dgs"), to="e3nn"), atol=1e-13)
    with pytest.raises(ShprobeError):
        convert(coeffs(2), to="nope")
    with pytest.raises(ShprobeError):
        convert(coeffs(3), to="three")  # three.js holds l ≤ 2


def test_torch_and_jax_convert():
    torch = need("torch")
    need("array_api_compat")
    c = coeffs(3)
    for name in ("3dgs", "e3nn", "4pi"):
        t = convert(torch.tensor(c, requires_grad=True), from_="shprobe", to=name)
        assert isinstance(t, torch.Tensor)
        np.testing.assert_allclose(t.detach().numpy(), convert(c, to=name), atol=1e-12)
        t.sum().backward()
    x = torch.tensor(c, requires_grad=True)
    assert torch.autograd.gradcheck(lambda a: convert(a, from_="e3nn", to="cs"), (x,))
    jax = need("jax")
    jax.config.update("jax_enable_x64", True)
    out = jax.jit(lambda a: convert(a, to="e3nn"))(jax.numpy.asarray(c))
    np.testing.assert_allclose(np.asarray(out), convert(c, to="e3nn"), atol=1e-12)
