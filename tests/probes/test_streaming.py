"""Streaming: images read a block of rows at a time (shprobe.probes.streaming.ImageRows) and
projected block by block (shprobe.lighting.projection.project_file) equal the whole-image
path, in memory bounded by the block, not the image."""

from __future__ import annotations

import json
import tracemalloc
import warnings

import numpy as np
import OpenImageIO as oiio
import pytest

from shprobe.cli.main import main
from shprobe.errors import ShprobeError
from shprobe.lighting import source as lighting_source
from shprobe.lighting.projection import cube_face_rows, project, project_file
from shprobe.probes.env import env_from_function, load_env, write_env
from shprobe.probes.environments import procedural_env
from shprobe.probes.images import LDRWarning, read_image, write_image
from shprobe.probes.layouts import Cube
from shprobe.probes.streaming import ImageRows, image_size
from tests.conftest import write_raw_pfm


def _image(h=37, w=74, seed=0):
    return (np.random.default_rng(seed).random((h, w, 3)) * 5 + 0.01).astype(np.float32)


def _stream(path, block_rows, **kw):
    with ImageRows(path, block_bytes=block_rows * 12 * image_size(path)[0], **kw) as im:
        blocks = list(im.blocks())
    ys = [y for y, _ in blocks]
    assert ys == sorted(ys) and ys[0] == 0
    return np.concatenate([b for _, b in blocks]), len(blocks)


@pytest.mark.parametrize("ext", [".exr", ".hdr", ".pfm", ".tif"])
def test_blocks_equal_read_image(tmp_path, ext):
    p = tmp_path / f"a{ext}"
    write_image(p, _image())
    got, n = _stream(p, 10)
    assert n == 4  # 37 rows in blocks of 10
    assert np.array_equal(got, read_image(p))
    assert image_size(p) == (74, 37)


def test_ldr_warns_once_and_decodes_srgb(tmp_path):
    p = tmp_path / "a.png"
    write_image(p, _image() / 5)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        got, _ = _stream(p, 8)
        full = read_image(p)
    assert sum(issubclass(w.category, LDRWarning) for w in caught) == 2  # one each
    assert np.array_equal(got, full)


def test_tiled_and_grey_exr(tmp_path):
    img = _image()
    p = tmp_path / "tiled.exr"
    out = oiio.ImageOutput.create(str(p))
    spec = oiio.ImageSpec(74, 37, 4, oiio.HALF)
    spec.tile_width = spec.tile_height = 16
    assert out.open(str(p), spec)
    assert out.write_image(np.concatenate([img, np.ones_like(img[..., :1])], axis=2))
    out.close()
    got, n = _stream(p, 5)  # rounded up to one row of 16-pixel tiles per block
    assert n == 3
    assert np.array_equal(got, read_image(p))
    g = tmp_path / "grey.exr"
    out = oiio.ImageOutput.create(str(g))
    assert out.open(str(g), oiio.ImageSpec(8, 4, 1, oiio.FLOAT))
    assert out.write_image(img[:4, :8, :1].copy())
    out.close()
    got, _ = _stream(g, 3)
    assert np.array_equal(got, np.repeat(img[:4, :8, :1], 3, axis=2))


def test_bad_pixels_and_truncation_are_one_line(tmp_path):
    img = _image()
    img[30, 5, 1] = np.nan
    p = write_raw_pfm(tmp_path / "nan.pfm", img)
    with pytest.raises(ShprobeError, match=r"nan\.pfm: image has 1 NaN"):
        _stream(p, 10)
    got, _ = _stream(p, 10, clamp=True)
    assert got[30, 5, 1] == 0 and np.isfinite(got).all()
    e = tmp_path / "cut.exr"
    write_image(e, _image(256, 512))
    raw = e.read_bytes()
    e.write_bytes(raw[: len(raw) // 2])
    with pytest.raises(ShprobeError, match=r"cut\.exr") as exc:
        _stream(e, 16)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("block_rows", [1, 7, 64])
def test_project_file_latlong_equals_project(tmp_path, block_rows):
    p = tmp_path / "ll.exr"
    write_env(p, procedural_env(128, 64))
    ref = project(load_env(p), 6)
    got = project_file(p, 6, block_bytes=block_rows * 128 * 12)
    assert (got.layout, got.width, got.height, got.streamed) == ("latlong", 128, 64, True)
    np.testing.assert_allclose(got.coeffs, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_project_file_hdr_matches_shared_probe(grace_path):
    """.hdr rows are decoded and summed in one pass (float32 sums in another order than the
    in-memory path's matrix product): equal to float32 rounding."""
    ref = project(load_env(grace_path), 2)
    got = project_file(grace_path, 2, block_bytes=3 * 256 * 12)
    np.testing.assert_allclose(got.coeffs, ref, rtol=0, atol=1e-6 * np.abs(ref).max())


def test_cube_face_rows_match_layout():
    n = 12
    c = Cube()
    d, w = c.pixel_directions((6, n, n)), c.solid_angles((6, n, n))
    for f in range(6):
        dd, ww = cube_face_rows(f, n, 4, 9)
        np.testing.assert_allclose(dd, d[f, 4:9], atol=1e-15)
        np.testing.assert_allclose(ww, w[f, 4:9], rtol=1e-12)


@pytest.mark.parametrize("arrangement", ["hcross", "vcross", "hstrip", "vstrip"])
def test_project_file_cube_equals_project(tmp_path, arrangement):
    env = env_from_function(lambda x: np.stack([1 + x[:, 0] ** 2, 2 + x[:, 1],
                                                1.5 + x[:, 2] * x[:, 0]], -1), "cube", 16)
    p = tmp_path / f"{arrangement}.exr"
    write_env(p, env, arrangement=arrangement)
    ref = project(load_env(p), 4)
    got = project_file(p, 4, block_bytes=5 * 64 * 12)  # blocks cut across faces
    assert got.layout == "cube" and got.streamed
    np.testing.assert_allclose(got.coeffs, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_project_file_disc_layout_reads_whole(tmp_path):
    p = tmp_path / "ang.exr"
    write_env(p, env_from_function(lambda x: 1 + x, "angular", 24))
    got = project_file(p, 2, block_bytes=1)
    assert got.layout == "angular" and not got.streamed
    np.testing.assert_allclose(got.coeffs, project(load_env(p), 2), atol=1e-12)
    with pytest.raises(ShprobeError, match="2:1"):
        project_file(p, 2, layout="latlong")


def _peak(fn) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_memory_grows_with_the_block_not_the_image(tmp_path):
    """numpy reports its buffers to tracemalloc: the whole-image path peaks above the decoded
    image, the streamed one at a few blocks, the same for an image 4× larger."""
    small, big = tmp_path / "s.exr", tmp_path / "b.exr"
    write_image(small, _image(192, 384, 1))
    write_image(big, _image(384, 768, 2))
    block = 96 << 10  # 96 KB: 8 rows of the big image
    project_file(small, 2, block_bytes=block)  # tables and kernels cached first
    project_file(big, 2, block_bytes=block)
    p_small = _peak(lambda: project_file(small, 2, block_bytes=block))
    p_big = _peak(lambda: project_file(big, 2, block_bytes=block))
    p_whole = _peak(lambda: project(load_env(big), 2))
    decoded = 384 * 768 * 12  # 3.5 MB
    assert p_whole > decoded
    assert p_big < 8 * block < decoded / 4
    assert p_big < 1.5 * p_small + (64 << 10)  # 4× the pixels, not 4× the memory


def test_prefilter_streams_big_probes(tmp_path, capsys, monkeypatch):
    p = tmp_path / "ll.hdr"
    write_env(p, procedural_env(128, 64))
    assert main(["prefilter", str(p), "-F", "json", "-n", "3"]) == 0
    whole = json.loads(capsys.readouterr().out)
    called = []
    real = lighting_source.project_file

    def spy(*a, **k):
        called.append(a)
        return real(*a, **k)

    monkeypatch.setattr(lighting_source, "STREAM_ABOVE_BYTES", 0)
    monkeypatch.setattr(lighting_source, "project_file", spy)
    assert main(["prefilter", str(p), "-F", "json", "-n", "3"]) == 0
    streamed = json.loads(capsys.readouterr().out)
    assert called
    assert streamed["layout"] == "latlong"
    # .hdr streamed: decode fused with float32 row sums, another order than the whole image's
    ref = np.asarray(whole["coefficients"])
    np.testing.assert_allclose(streamed["coefficients"], ref, atol=1e-6 * np.abs(ref).max())


_HDR_HEAD = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n"


def test_rgbe_decoder_agrees_with_openimageio(tmp_path):
    """shprobe's fused RGBE decoder (read_image's .hdr path) against OpenImageIO's decode plus
    Radiance's half step, on new-style RLE written by OpenImageIO, whole and streamed with a
    read buffer smaller than a block (resumed mid-file)."""
    from pathlib import Path

    from shprobe.probes.codecs import read_oiio, read_rgbe, rgbe_half_step

    img = _image(61, 122, 4) ** 3 * 100  # a wide dynamic range
    p = tmp_path / "a.hdr"
    write_image(p, img)
    ref = rgbe_half_step(read_oiio(Path(p))[0])[..., :3]
    assert np.array_equal(read_rgbe(p), ref)
    assert np.array_equal(read_image(p), ref)
    got, n = _stream(p, 3)  # 3-row blocks: 4 KB reads, each ending inside a scanline
    assert n == 21 and np.array_equal(got, ref)


def test_rgbe_streaming_old_rle_flipped_and_truncated(tmp_path):
    px, row1 = [128, 64, 32, 129], [10, 20, 30, 128] * 4
    old = tmp_path / "old.hdr"
    old.write_bytes(_HDR_HEAD + b"-Y 2 +X 4\n" + bytes([*px, 1, 1, 1, 3, *row1]))
    got, n = _stream(old, 1)
    assert n == 2 and np.array_equal(got, read_image(old))
    flip = tmp_path / "flip.hdr"
    flip.write_bytes(_HDR_HEAD + b"+Y 2 +X 1\n" + bytes([128, 0, 0, 128, 200, 0, 0, 128]))
    got, _ = _stream(flip, 1)
    assert np.array_equal(got, read_image(flip)) and got[0, 0, 0] > got[1, 0, 0]
    cut = tmp_path / "cut.hdr"
    write_image(cut, _image(64, 128))
    raw = cut.read_bytes()
    cut.write_bytes(raw[: len(raw) // 2])
    with pytest.raises(ShprobeError, match=r"cut\.hdr: truncated or corrupt"):
        _stream(cut, 4)


def _sums_by_blocks(path, weights, block_rows):
    with ImageRows(path, block_bytes=block_rows * 12 * image_size(path)[0]) as im:
        return np.concatenate([np.matmul(weights[None], b).astype(np.float64)
                               for _, b in im.blocks()])


def _sums(path, weights, block_rows):
    with ImageRows(path, block_bytes=block_rows * 12 * image_size(path)[0]) as im:
        parts = list(im.row_sums(weights))
    assert [y for y, _ in parts] == list(range(0, image_size(path)[1], block_rows))
    return np.concatenate([s for _, s in parts])


@pytest.mark.parametrize("ext", [".hdr", ".exr"])
def test_row_sums_equal_products_of_decoded_rows(tmp_path, ext):
    """ImageRows.row_sums (fused decode + sums for .hdr) = weights @ each decoded row, in
    float64 from the decoded pixels, to float32 rounding; a truncated .hdr is one line."""
    p = tmp_path / f"a{ext}"
    write_image(p, _image(37, 74))
    wts = np.random.default_rng(1).standard_normal((5, 74)).astype(np.float32)
    exact = np.einsum("mx,yxc->ymc", wts.astype(np.float64), read_image(p).astype(np.float64))
    scale = np.abs(wts).astype(np.float64) @ read_image(p).max(axis=(0, 2)).astype(np.float64)
    for rows in (1, 10, 37):
        got = _sums(p, wts, rows)
        assert got.shape == (37, 5, 3) and got.dtype == np.float64
        assert np.all(np.abs(got - exact) <= 1e-6 * scale[None, :, None])
        np.testing.assert_allclose(got, _sums_by_blocks(p, wts, rows), rtol=0,
                                   atol=1e-6 * scale.max())
    if ext == ".hdr":
        raw = p.read_bytes()
        p.write_bytes(raw[: len(raw) * 2 // 3])
        with pytest.raises(ShprobeError, match=r"a\.hdr: truncated or corrupt") as exc:
            _sums(p, wts, 10)
        assert "\n" not in str(exc.value)


def test_project_file_hdr_fused_equals_blocks(tmp_path):
    """The .hdr projection (decode fused with the row sums) and the block path (taken with
    on_block) agree to float32 rounding, and on_block sees every decoded row."""
    p = tmp_path / "ll.hdr"
    write_env(p, procedural_env(128, 64))
    seen = []
    fused = project_file(p, 4, block_bytes=7 * 128 * 12)
    blocks = project_file(p, 4, block_bytes=7 * 128 * 12,
                          on_block=lambda y0, b: seen.append((y0, b.shape[0])))
    assert sum(n for _, n in seen) == 64 and seen[0][0] == 0
    np.testing.assert_allclose(fused.coeffs, blocks.coeffs, rtol=0,
                               atol=1e-6 * np.abs(blocks.coeffs).max())
