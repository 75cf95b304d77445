"""Images ↔ coefficients (shprobe.lighting.maps): equal to ``project`` on the same lat-long
and cube images, synthesis equal to the basis summed at the pixel centres, batched, and
differentiable on torch (gradcheck) and JAX (jit)."""

from __future__ import annotations

import numpy as np

from shprobe.lighting.irradiance import irradiance
from shprobe.lighting.maps import (
    latlong_irradiance,
    latlong_radiance,
    project_cube,
    project_latlong,
)
from shprobe.lighting.projection import project
from shprobe.probes.env import Env
from shprobe.probes.layouts import get_layout
from shprobe.sh import sh_basis
from tests.conftest import data_file
from tests.tensors.tensor_support import coeffs, need


def test_latlong_projection_equals_project():
    from shprobe import load_env

    env = load_env(data_file("probes", "grace.hdr"))
    for lmax in (2, 8):
        want = project(env, lmax)  # float32 per-row products: equal to float32 rounding
        got = project_latlong(env.radiance, lmax)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * np.abs(want).max())
    # the independent sum: every pixel's y_lm times its exact solid angle
    rad = np.random.default_rng(0).random((16, 32, 2))
    lay = get_layout("latlong")
    d, dw = lay.pixel_directions((16, 32)), lay.solid_angles((16, 32))
    brute = np.einsum("hwk,hwc->kc", sh_basis(d, 5) * dw[..., None], rad)
    np.testing.assert_allclose(project_latlong(rad, 5), brute, atol=1e-13)


def test_cube_projection_equals_project():
    rad = np.random.default_rng(1).random((6, 12, 12, 3)).astype(np.float32)
    env = Env(rad, get_layout("cube"))
    np.testing.assert_allclose(project_cube(rad, 4), project(env, 4), atol=1e-12)


def test_maps_from_coefficients_and_batching():
    c = coeffs(5, seed=3)
    lay = get_layout("latlong")
    d = lay.pixel_directions((20, 40))
    np.testing.assert_allclose(latlong_radiance(c, 20), sh_basis(d, 5) @ c, atol=1e-12)
    np.testing.assert_allclose(latlong_irradiance(c, 20), irradiance(c, d), atol=1e-12)
    batch = coeffs(3, batch=(2, 3), seed=4)
    maps = latlong_radiance(batch, 8)
    assert maps.shape == (2, 3, 8, 16, 3)
    np.testing.assert_allclose(maps[1, 2], latlong_radiance(batch[1, 2], 8), atol=1e-13)
    # a band-limited map projects back to its coefficients (to the quadrature's accuracy)
    back = project_latlong(latlong_radiance(batch, 64), 3)
    np.testing.assert_allclose(back, batch, atol=2e-3 * np.abs(batch).max())


def test_torch_maps_values_and_gradcheck():
    torch = need("torch")
    need("array_api_compat")
    rad = np.random.default_rng(2).random((2, 8, 16, 3))
    t = torch.tensor(rad)
    got = project_latlong(t, 3)
    assert isinstance(got, torch.Tensor) and got.shape == (2, 16, 3)
    np.testing.assert_allclose(got.numpy(), project_latlong(rad, 3), atol=1e-12)
    cube = torch.tensor(np.random.default_rng(3).random((6, 4, 4, 1)))
    np.testing.assert_allclose(project_cube(cube, 2).numpy(), project_cube(cube.numpy(), 2),
                               atol=1e-12)
    c = torch.tensor(coeffs(2, seed=5))
    for f, x in ((lambda r: project_latlong(r, 3), t[:1, :4, :8]),
                 (lambda r: project_cube(r, 2), cube),
                 (lambda c: latlong_radiance(c, 4), c),
                 (lambda c: latlong_irradiance(c, 4), c)):
        x = x.detach().clone().requires_grad_(True)
        assert torch.autograd.gradcheck(f, (x,), fast_mode=True)
    f32 = latlong_irradiance(c.float(), 8)
    assert f32.dtype == torch.float32
    np.testing.assert_allclose(f32.numpy(), latlong_irradiance(c.numpy(), 8), rtol=1e-5,
                               atol=1e-5)


def test_jax_maps_jit():
    jax = need("jax")
    need("array_api_compat")
    jax.config.update("jax_enable_x64", True)
    rad = np.random.default_rng(2).random((8, 16, 3))
    c = coeffs(2, seed=6)
    cube = np.random.default_rng(3).random((6, 4, 4, 3))
    for f, x in ((lambda r: project_latlong(r, 2), rad), (lambda c: latlong_irradiance(c, 8), c),
                 (lambda r: project_cube(r, 2), cube), (lambda c: latlong_radiance(c, 8), c)):
        want = f(x)
        np.testing.assert_allclose(np.asarray(jax.jit(f)(jax.numpy.asarray(x))), want,
                                   atol=1e-12)
        g = jax.grad(lambda a, f=f: jax.numpy.sum(f(a) ** 2))(jax.numpy.asarray(x))
        assert np.all(np.isfinite(np.asarray(g))) and float(jax.numpy.abs(g).max()) > 0
