"""The worked example of docs/tensors.md: lighting fitted to an image of a known object (a
diffuse sphere seen from +Z, noisy) by gradient descent in torch through the public
``irradiance`` equals the linear least-squares solution of ``shprobe fit``
(:func:`shprobe.fitting.objects.fit_normals`, plain least squares)."""

from __future__ import annotations

import numpy as np

from shprobe import load_env
from shprobe.fitting.objects import fit_normals
from shprobe.lighting.irradiance import irradiance
from shprobe.lighting.projection import project
from tests.conftest import data_file
from tests.tensors.tensor_support import need


def sphere_normals(n: int = 64) -> np.ndarray:
    """(n, n, 3) normals of a unit sphere seen orthographically along −Z; 0 outside."""
    v, u = np.mgrid[0:n, 0:n]
    x, y = (u + 0.5) / n * 2 - 1, 1 - (v + 0.5) / n * 2
    r2 = x * x + y * y
    z = np.sqrt(np.clip(1 - r2, 0, None))
    return np.where((r2 < 1)[..., None], np.stack([x, y, z], -1), 0.0)


def test_gradient_descent_equals_linear_fit():
    torch = need("torch")
    need("array_api_compat")
    truth = project(load_env(data_file("probes", "grace.hdr")), 2)
    normals = sphere_normals()
    inside = np.linalg.norm(normals, axis=-1) > 0.5
    image = np.zeros((64, 64, 3), np.float32)
    noise = 1 + 0.05 * np.random.default_rng(0).standard_normal((int(inside.sum()), 3))
    image[inside] = (irradiance(truth, normals[inside]) / np.pi * noise).astype(np.float32)

    linear = fit_normals(image, normals, robust=False).coeffs  # shprobe fit's solution

    n = torch.tensor(normals[inside])
    target = torch.tensor(image[inside], dtype=torch.float64)
    L = torch.zeros(9, 3, dtype=torch.float64, requires_grad=True)
    opt = torch.optim.LBFGS([L], max_iter=200, tolerance_grad=1e-14,
                            tolerance_change=1e-16, line_search_fn="strong_wolfe")

    def loss():
        opt.zero_grad()
        value = ((irradiance(L, n) / np.pi - target) ** 2).sum()
        value.backward()
        return value

    for _ in range(10):
        opt.step(loss)
    fitted = L.detach().numpy()
    np.testing.assert_allclose(fitted, linear, rtol=0, atol=1e-7 * np.abs(linear).max())
    # both recover the true lighting to the noise's level
    assert np.abs(fitted - truth).max() < 0.05 * np.abs(truth).max()
