"""Hostile tensor inputs (and two small NumPy ones), one class per test: each is refused with
one ShprobeError line, printed (``pytest -s`` shows the line a user gets), or computed right
where the policy is to compute (float16: in float32, cast back). The inputs are made here."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.lighting.projection import project_samples
from shprobe.sh import sh_basis
from shprobe.sh.registry import convert
from shprobe.sh.rotation import from_euler_zyz, rotate, wigner_d
from shprobe.sh.zonal import convolve
from tests.tensors.tensor_support import coeffs, need, unit

torch = need("torch")
need("array_api_compat")


def one_line(f):
    """The ShprobeError ``f`` raises: one line, printed."""
    with pytest.raises(ShprobeError) as e:
        f()
    msg = str(e.value)
    assert msg and "\n" not in msg
    print(msg)
    return msg


def test_float16_basis_is_finite_at_high_degree():
    # float16 tops out at 65504; P̄_lm passes it from l ≈ 32: computed in float32, cast back
    d = torch.tensor(unit(64, seed=3), dtype=torch.float16)
    for lmax in (32, 48, 64):
        y = sh_basis(d, lmax)
        assert y.dtype == torch.float16 and bool(torch.isfinite(y).all())
        want = sh_basis(d.double().numpy(), lmax)
        assert np.abs(y.double().numpy() - want).max() <= 2e-2  # float16 rounding


def test_float16_rotations_computed_in_float32():
    R = torch.tensor(np.eye(3)[[1, 2, 0]], dtype=torch.float16)  # a proper rotation
    c = torch.tensor(coeffs(3), dtype=torch.float16)
    got = rotate(c, R)
    assert got.dtype == torch.float16
    np.testing.assert_allclose(got.double().numpy(),
                               rotate(c.double().numpy(), R.double().numpy()), atol=2e-2)
    assert wigner_d(R, 3).dtype == torch.float16


def test_meta_tensors_refused():
    assert "meta" in one_line(lambda: sh_basis(torch.empty((4, 3), device="meta"), 2))
    one_line(lambda: rotate(torch.empty((9, 3), device="meta"), torch.eye(3)))


def test_sparse_tensors_refused():
    assert "to_dense" in one_line(lambda: sh_basis(torch.eye(3).to_sparse(), 2))
    one_line(lambda: rotate(torch.ones(9, 3), torch.eye(3).to_sparse()))


def test_euler_broadcast_mismatch_refused():
    for a, b in ((torch.zeros(2), torch.zeros(3)), (np.zeros(2), np.zeros(3))):
        assert "broadcast" in one_line(lambda a=a, b=b: from_euler_zyz(a, b, 0.0))


@pytest.mark.parametrize("kind", ["numpy", "torch"])
def test_nan_refused_by_euler_convert_convolve(kind):
    nan = (lambda s: np.full(s, np.nan)) if kind == "numpy" else (
        lambda s: torch.full(s, float("nan"), dtype=torch.float64))
    one_line(lambda: from_euler_zyz(nan(()), 0.0, 0.0))
    one_line(lambda: convert(nan((9, 3)), "shprobe", "unity-l2"))
    one_line(lambda: convolve(nan((9, 3)), [1.0, 0.5, 0.25]))
    one_line(lambda: convolve(coeffs(2) if kind == "numpy" else torch.ones(9, 3),
                              [1.0, float("nan"), 0.25]))


@pytest.mark.parametrize("kind", ["numpy", "torch"])
def test_empty_project_samples_refused(kind):
    z = np.zeros((0, 3)) if kind == "numpy" else torch.zeros((0, 3), dtype=torch.float64)
    assert "at least one sample" in one_line(lambda: project_samples(z, z, None, 2))


def test_tensor_basis_memory_checked(monkeypatch):
    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "1M")
    d = torch.tensor(unit(10000), dtype=torch.float64)
    assert "over the limit" in one_line(lambda: sh_basis(d, 8))
    assert sh_basis(d[:10], 8).shape == (10, 81)


def test_batched_latlong_projection_memory_checked(monkeypatch):
    from shprobe.lighting.maps import project_latlong

    rad = torch.rand(16, 32, 64, 3, dtype=torch.float64)
    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "600K")  # the 16 maps alone are 786 kB
    assert "over the limit" in one_line(lambda: project_latlong(rad, 4))
    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "8M")
    got = project_latlong(rad, 4)
    np.testing.assert_allclose(got[3].numpy(), project_latlong(rad[3].numpy(), 4), atol=1e-12)


def test_jit_checks_shapes_dtypes_and_degree_before_tracing():
    jax = need("jax")
    import jax.numpy as jnp

    d = jnp.zeros((5, 3))
    assert "static" in one_line(lambda: jax.jit(lambda d, l: sh_basis(d, l))(d, 3))
    one_line(lambda: jax.jit(lambda d: sh_basis(d, 3))(jnp.zeros((5, 4))))
    one_line(lambda: jax.jit(lambda d: sh_basis(d, 3))(jnp.zeros((5, 3), jnp.complex64)))
    one_line(lambda: jax.jit(lambda c: rotate(c, jnp.eye(3)))(jnp.zeros((10, 3))))
    one_line(lambda: jax.jit(lambda d: project_samples(d, d, None, 2))(jnp.zeros((0, 3))))


def test_project_h_of_a_number_refused():
    from shprobe.hbasis.basis import project_h

    assert "function" in one_line(lambda: project_h(5))
    one_line(lambda: project_h(lambda d: np.full(len(d), np.nan)))
    one_line(lambda: project_h(lambda d: np.array(["x"] * len(d))))


def test_env_of_an_object_array_refused():
    from shprobe.probes.env import Env

    rad = np.full((8, 16, 3), None, dtype=object)
    assert "real numbers" in one_line(lambda: Env(rad, "latlong"))
    one_line(lambda: Env(np.full((8, 16, 3), "a"), "latlong"))
