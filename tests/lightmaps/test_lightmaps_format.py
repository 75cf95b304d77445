"""The SHPROBE_lightmap format: the reference bases against the library's own, and the
writer/reader pair round-trips."""

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.hbasis import get_basis, h_basis, hemisphere_quadrature
from shprobe.lightmaps import format as fmt
from shprobe.sh import sh_basis


def _normals(n=200, seed=1):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_bases_equal_the_library_definitions():
    d = _normals()
    np.testing.assert_allclose(fmt.basis_values("h6", d), h_basis(d, 6), atol=1e-12)
    np.testing.assert_allclose(fmt.basis_values("h4", d), h_basis(d, 4), atol=1e-12)
    np.testing.assert_allclose(fmt.basis_values("sh9", d), sh_basis(d, 2), atol=2e-6)
    np.testing.assert_allclose(fmt.basis_values("sh4", d), sh_basis(d, 1), atol=2e-6)
    np.testing.assert_allclose(fmt.basis_values("hl2", d), get_basis("HL2").evaluate(d),
                               atol=1e-12)
    np.testing.assert_array_equal(fmt.basis_values("plain", d), np.ones((200, 1)))


@pytest.mark.parametrize("enc", ["hl2", "h4", "h6"])
def test_hemispherical_bases_are_orthonormal(enc):
    nodes, w = hemisphere_quadrature(16, 32)
    b = fmt.basis_values(enc, nodes)
    np.testing.assert_allclose((b * w[:, None]).T @ b, np.eye(fmt.N_COEFFS[enc]), atol=1e-12)


@pytest.mark.parametrize("enc", fmt.ENCODINGS)
def test_pack_unpack_and_document_round_trip(enc):
    n = fmt.N_COEFFS[enc]
    rng = np.random.default_rng(3)
    c = rng.uniform(-2, 5, size=(5, 7, n, 3))
    tex = fmt.pack(enc, c)
    assert all(t.shape == (5, 7, 4) and t.dtype == np.float16 for t in tex)
    np.testing.assert_array_equal(fmt.unpack(enc, tex), c.astype(np.float16))
    doc, binary = {"asset": {"version": "2.0"}}, bytearray()
    fmt.add_lightmap(doc, binary, enc, c * 1e5, [(0, 0)])
    doc2, bin2 = fmt.parse_glb(fmt.encode_glb(doc, binary))
    got = fmt.read_lightmap(doc2, bin2)
    assert got.encoding == enc and got.primitives == ((0, 0),) and got.scale > 1
    np.testing.assert_allclose(got.coeffs, c * 1e5, rtol=2e-3, atol=got.scale * 1e-3)
    assert fmt.EXTENSION in doc2["extensionsUsed"]
    assert fmt.EXTENSION not in doc2.get("extensionsRequired", [])


def test_evaluate_is_the_basis_sum():
    d = _normals(10)
    c = np.random.default_rng(0).normal(size=(10, 6, 3))
    want = np.einsum("pi,pic->pc", h_basis(d, 6), c)
    np.testing.assert_allclose(fmt.evaluate("h6", c, d), want, atol=1e-12)


def test_bad_input_is_one_error():
    with pytest.raises(ShprobeError, match="unknown lightmap encoding"):
        fmt.basis_values("sh16", [0, 0, 1])
    with pytest.raises(ShprobeError, match="half-float"):
        fmt.pack("plain", np.full((1, 1, 1, 3), 1e6))
    with pytest.raises(ShprobeError, match="not a binary glTF"):
        fmt.parse_glb(b"hello world, not a glb file")
    with pytest.raises(ShprobeError, match="no SHPROBE_lightmap"):
        fmt.read_lightmap({"asset": {}}, b"")
