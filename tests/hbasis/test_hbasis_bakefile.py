"""H-basis bake files (hbasis.bakefile save_bake / load_bake): the round trip, atomic output,
and one-line refusals of truncated, malformed, oversized or foreign files — checked from the
.npy headers before anything is inflated."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.hbasis import bakefile as bf
from shprobe.hbasis import normalmap as nm
from shprobe.hbasis.basis import sh_to_h_matrix
from shprobe.scene import mesh_hash, sphere_mesh
from tests.conftest import one_line_message


@pytest.fixture(scope="module")
def ball():
    return sphere_mesh(1)  # 42 vertices


@pytest.fixture(scope="module")
def lighting():
    rng = np.random.default_rng(4)
    L = rng.normal(size=(25, 3))
    L[0] += 5
    return L


def test_round_trip_keeps_everything(tmp_path, ball, lighting):
    bk = nm.bake_mesh(ball, lighting, n=6, bands=4)
    assert bk.mesh_hash == mesh_hash(ball.vertices, ball.faces) and bk.bands == 4
    path = tmp_path / "b.npz"
    bf.save_bake(path, bk)
    back = bf.load_bake(path, ball)
    for name in ("h", "sh", "frames", "handedness", "lighting"):
        np.testing.assert_array_equal(getattr(back, name), getattr(bk, name))
    assert (back.bands, back.mesh_hash, back.basis) == (4, bk.mesh_hash, "H6")
    assert repr(back).startswith("NormalMapBake(42 vertices, H6, 3 channels, bands ≤ 4, mesh ")
    with np.load(path) as z:  # the documented layout, readable without shprobe
        np.testing.assert_array_equal(z["t_h"], sh_to_h_matrix(4, 6))
        assert str(z["basis"]) == "H6" and str(z["format"]) == bf.BAKE_FORMAT
    assert bf.is_bake(path) and not bf.is_bake(tmp_path / "none.npz")
    # the coefficients are the bake of the mesh's frames under E = Â L (bands ≤ 4)
    from shprobe.lighting import irradiance_coeffs

    want = nm.bake_normalmap(irradiance_coeffs(lighting), bk.frames, n=6, lmax=4)
    np.testing.assert_allclose(back.h, want.h, rtol=1e-12, atol=1e-14)
    # outputs are atomic and never replace a file unasked
    with pytest.raises(ShprobeError, match="already exists"):
        bf.save_bake(path, bk)
    bf.save_bake(path, bk, overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.npz"]
    # a bake without a mesh (bare frames) cannot be saved: it could never be checked
    with pytest.raises(ShprobeError, match="bake_mesh"):
        bf.save_bake(tmp_path / "x.npz", want)


def test_foreign_mesh_and_missing_arrays(tmp_path, ball, lighting):
    path = tmp_path / "b.npz"
    bf.save_bake(path, nm.bake_mesh(ball, lighting))
    with pytest.raises(ShprobeError) as e:
        bf.load_bake(path, sphere_mesh(2))
    assert "another mesh" in one_line_message(e) and "b.npz" in str(e.value)
    with np.load(path) as z:
        arrays = dict(z)
    del arrays["frames"]
    np.savez(tmp_path / "m.npz", **arrays)
    with pytest.raises(ShprobeError, match="missing frames"):
        bf.load_bake(tmp_path / "m.npz")


def _rewrite(src, dst, **changes):
    with np.load(src) as z:
        arrays = dict(z)
    arrays.update(changes)
    np.savez(dst, **arrays)


@pytest.mark.parametrize("change, msg", [
    ({"h": np.zeros((42, 5, 3))}, "inconsistent"),
    ({"sh9": np.zeros((41, 9, 3))}, "inconsistent"),
    ({"frames": np.zeros((42, 3, 2))}, "inconsistent"),
    ({"h": np.zeros((42, 6, 3), np.int64)}, "must hold floats"),
    ({"mesh_hash": np.array([1, 2])}, "one string"),
    ({"L": np.zeros((24, 3))}, "array L"),
    ({"handedness": np.zeros(7)}, "array handedness"),
    ({"format": np.array("something-else")}, "format 'something-else'"),
    ({"h": np.full((42, 6, 3), np.nan)}, "NaN"),
])
def test_malformed_arrays_are_refused(tmp_path, ball, lighting, change, msg):
    good = tmp_path / "g.npz"
    bf.save_bake(good, nm.bake_mesh(ball, lighting))
    _rewrite(good, tmp_path / "bad.npz", **change)
    with pytest.raises(ShprobeError, match=msg) as e:
        bf.load_bake(tmp_path / "bad.npz")
    assert "bad.npz" in one_line_message(e)


def test_truncated_and_lying_files_are_refused_before_inflating(tmp_path, ball, lighting,
                                                                 monkeypatch):
    good = tmp_path / "g.npz"
    bf.save_bake(good, nm.bake_mesh(ball, lighting))
    raw = good.read_bytes()
    for cut in (0, 10, len(raw) // 2, len(raw) - 5):
        (tmp_path / "t.npz").write_bytes(raw[:cut])
        with pytest.raises(ShprobeError) as e:
            bf.load_bake(tmp_path / "t.npz")
        assert "t.npz" in one_line_message(e)
    # an h.npy whose header promises 10⁹ vertices over a few bytes of data: refused from the
    # header (stored size ≠ promised size) without allocating anything
    with zipfile.ZipFile(good) as z:
        members = {n: z.read(n) for n in z.namelist()}
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False,
                                              "shape": (10**9, 6, 3)})
    members["h.npy"] = buf.getvalue() + b"\0" * 64
    with zipfile.ZipFile(tmp_path / "lie.npz", "w") as z:
        for n, data in members.items():
            z.writestr(n, data)
    with pytest.raises(ShprobeError, match="truncated or malformed") as e:
        bf.load_bake(tmp_path / "lie.npz")
    assert "lie.npz" in one_line_message(e)
    # an honest file larger than the memory limit is refused before reading
    monkeypatch.setattr(bf, "MAX_BAKE_BYTES", 1000)
    with pytest.raises(ShprobeError, match="would take"):
        bf.load_bake(good)
