"""Image I/O: round trips, hand-made files (PFM both endiannesses, RGBE old and new RLE),
sRGB decoding of LDR images, and bad input."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.probes.codecs import read_rgbe
from shprobe.probes.images import LDRWarning, read_image, write_image
from shprobe.probes.tonemap import srgb_to_linear
from tests.conftest import one_line_message


def _img(h=6, w=10, seed=0):
    return (np.random.default_rng(seed).random((h, w, 3)) * 5).astype(np.float32)


@pytest.mark.parametrize("ext", [".exr", ".pfm", ".tif"])
def test_float_round_trip_exact(tmp_path, ext):
    a = _img()
    write_image(tmp_path / f"a{ext}", a)
    np.testing.assert_array_equal(read_image(tmp_path / f"a{ext}"), a)


def test_exr_half_and_hdr_round_trip(tmp_path):
    a = _img()
    write_image(tmp_path / "h.exr", a, half=True)
    np.testing.assert_allclose(read_image(tmp_path / "h.exr"), a, rtol=2**-10)
    write_image(tmp_path / "a.hdr", a)
    b = read_image(tmp_path / "a.hdr")
    # shared exponent, 8-bit mantissa of the largest channel; decoded at the step's middle
    assert np.all(np.abs(b - a).max(-1) <= a.max(-1) * 2**-8)


def test_png_tonemapped_and_decoded_back(tmp_path):
    a = np.linspace(0, 1, 30, dtype=np.float32).reshape(1, 10, 3).repeat(4, 0)
    write_image(tmp_path / "a.png", a * 0.25, exposure=2.0)  # +2 stops undoes the 1/4
    with pytest.warns(LDRWarning, match="not radiance"):
        b = read_image(tmp_path / "a.png")
    # 8-bit sRGB quantisation: half a code value through the sRGB slope (≤ 12.92)
    np.testing.assert_allclose(b, a, atol=0.5 / 255 * 1.0 + 1e-6, rtol=0.01)


def test_srgb_decoding_known_values(tmp_path):
    import OpenImageIO as oiio

    g = np.array([[0, 10, 128, 255]], dtype=np.uint8)  # grey 8-bit PNG
    out = oiio.ImageOutput.create(str(tmp_path / "g.png"))
    out.open(str(tmp_path / "g.png"), oiio.ImageSpec(4, 1, 1, oiio.UINT8))
    out.write_image(g[:, :, None])
    out.close()
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        b = read_image(tmp_path / "g.png")
    assert any(issubclass(r.category, LDRWarning) for r in rec)
    assert b.shape == (1, 4, 3)
    expect = [0.0, 10 / 255 / 12.92, ((128 / 255 + 0.055) / 1.055) ** 2.4, 1.0]
    np.testing.assert_allclose(b[0, :, 1], expect, rtol=1e-5)
    np.testing.assert_allclose(srgb_to_linear([0.5]), [0.21404114], rtol=1e-6)


def test_16bit_png(tmp_path):
    import OpenImageIO as oiio

    v = np.array([[[0, 32768, 65535]]], dtype=np.uint16)
    out = oiio.ImageOutput.create(str(tmp_path / "s.png"))
    out.open(str(tmp_path / "s.png"), oiio.ImageSpec(1, 1, 3, oiio.UINT16))
    out.write_image(v)
    out.close()
    with pytest.warns(LDRWarning):
        b = read_image(tmp_path / "s.png")
    np.testing.assert_allclose(b[0, 0], srgb_to_linear(v[0, 0] / 65535.0), rtol=1e-5)


def test_rgba_exr_drops_alpha(tmp_path):
    import OpenImageIO as oiio

    a = np.random.default_rng(2).random((3, 4, 4)).astype(np.float32)
    out = oiio.ImageOutput.create(str(tmp_path / "a.exr"))
    out.open(str(tmp_path / "a.exr"), oiio.ImageSpec(4, 3, 4, oiio.HALF))
    out.write_image(a)
    out.close()
    b = read_image(tmp_path / "a.exr")
    assert b.shape == (3, 4, 3)
    np.testing.assert_allclose(b, a[:, :, :3], rtol=2**-10)


def test_rgba_png_colour_is_not_multiplied_by_alpha(tmp_path):
    """PNG stores unassociated alpha: the colour channels decode as stored (Pillow writes it)."""
    from PIL import Image

    a = np.zeros((2, 3, 4), np.uint8)
    a[..., 0], a[..., 1], a[..., 2], a[..., 3] = 200, 100, 30, 64
    Image.fromarray(a, "RGBA").save(tmp_path / "a.png")
    with pytest.warns(LDRWarning):
        b = read_image(tmp_path / "a.png")
    expect = [((v / 255 + 0.055) / 1.055) ** 2.4 for v in (200, 100, 30)]
    np.testing.assert_allclose(b, np.broadcast_to(expect, (2, 3, 3)), rtol=1e-5)


@pytest.mark.parametrize("little", [True, False])
def test_hand_written_pfm(tmp_path, little):
    """PFM rows are stored bottom-up; the sign of the scale gives the byte order."""
    a = np.arange(2 * 3 * 3, dtype=np.float32).reshape(2, 3, 3)
    p = tmp_path / "h.pfm"
    with open(p, "wb") as f:
        f.write(b"PF\n3 2\n" + (b"-1.0\n" if little else b"1.0\n"))
        f.write(a[::-1].astype("<f4" if little else ">f4").tobytes())
    np.testing.assert_array_equal(read_image(p), a)
    g = tmp_path / "g.pfm"
    with open(g, "wb") as f:
        f.write(b"Pf\n3 2\n-1.0\n" + a[::-1, :, 0].astype("<f4").tobytes())
    np.testing.assert_array_equal(read_image(g), np.repeat(a[:, :, :1], 3, 2))
    # our writer puts the bottom row first
    write_image(tmp_path / "w.pfm", a)
    raw = (tmp_path / "w.pfm").read_bytes()
    np.testing.assert_array_equal(np.frombuffer(raw[-36:], "<f4").reshape(3, 3), a[0])


_HDR_HEAD = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n"


def _expected(rgbe):
    rgbe = np.asarray(rgbe, dtype=np.float64)
    return (rgbe[..., :3] + 0.5) * 2.0 ** (rgbe[..., 3:] - 136)


def test_hdr_old_style_rle(tmp_path):
    """Old RLE: a pixel (1, 1, 1, n) repeats the previous pixel n times (consecutive markers
    shift n by 8 bits)."""
    p = tmp_path / "old.hdr"
    px = [128, 64, 32, 129]
    row1 = [10, 20, 30, 128] * 4
    p.write_bytes(_HDR_HEAD + b"-Y 2 +X 4\n" + bytes([*px, 1, 1, 1, 3, *row1]))
    b = read_image(p)
    want = _expected([[px] * 4, [[10, 20, 30, 128]] * 4])
    np.testing.assert_allclose(b, want, rtol=1e-7)
    np.testing.assert_array_equal(read_rgbe(p), b)


def test_hdr_new_style_rle_both_decoders_agree(tmp_path):
    """New RLE: per scanline 2 2 W_hi W_lo, then 4 channel planes of runs (>128: repeat) and
    literals. Hand-encode a 2×10 image; OpenImageIO and shprobe's decoder must agree."""
    w = 10
    rng = np.random.default_rng(5)
    rgbe = np.zeros((2, w, 4), dtype=np.uint8)
    rgbe[..., :3] = rng.integers(128, 256, (2, w, 3))
    rgbe[..., 3] = 130
    rgbe[0, :6, 0] = 200  # a run
    body = b""
    for y in range(2):
        body += bytes([2, 2, 0, w])
        for c in range(4):
            ch = rgbe[y, :, c]
            if c == 0 and y == 0:
                body += bytes([128 + 6, 200, 4, *ch[6:]])
            else:
                body += bytes([128 + w, ch[0]]) if np.all(ch == ch[0]) else bytes([w, *ch])
    p = tmp_path / "new.hdr"
    p.write_bytes(_HDR_HEAD + b"-Y 2 +X 10\n" + body)
    a = read_image(p)
    np.testing.assert_allclose(a, _expected(rgbe), rtol=1e-7)
    np.testing.assert_array_equal(read_rgbe(p), a)


def test_hdr_orientation_plus_y(tmp_path):
    p = tmp_path / "flip.hdr"
    p.write_bytes(_HDR_HEAD + b"+Y 2 +X 1\n" + bytes([1 + 127, 0, 0, 128, 200, 0, 0, 128]))
    b = read_rgbe(p)
    assert b[0, 0, 0] > b[1, 0, 0]  # the file's first scanline is the bottom one


# ----------------------------------------------------------------------------- bad input


def _one_line_error(path, match=None, **kw):
    with pytest.raises(ShprobeError, match=match) as e:
        read_image(path, **kw)
    msg = one_line_message(e)
    assert str(path) in msg
    return msg


def test_missing_empty_unknown(tmp_path):
    _one_line_error(tmp_path / "nope.hdr", "no such file")
    (tmp_path / "empty.exr").write_bytes(b"")
    _one_line_error(tmp_path / "empty.exr", "empty")
    (tmp_path / "x.bmpx").write_bytes(b"123")
    _one_line_error(tmp_path / "x.bmpx", "unknown image extension")


@pytest.mark.parametrize("ext", [".hdr", ".exr", ".png", ".pfm", ".tif"])
def test_truncated_and_corrupt(tmp_path, ext):
    a = _img(64, 128)
    write_image(tmp_path / f"a{ext}", a)
    raw = (tmp_path / f"a{ext}").read_bytes()
    (tmp_path / f"t{ext}").write_bytes(raw[: len(raw) // 2])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LDRWarning)
        _one_line_error(tmp_path / f"t{ext}")
        (tmp_path / f"c{ext}").write_bytes(b"this is not an image at all" * 10)
        _one_line_error(tmp_path / f"c{ext}")


def test_hdr_truncated_old_rle_and_zero_size(tmp_path):
    p = tmp_path / "t.hdr"
    p.write_bytes(_HDR_HEAD + b"-Y 2 +X 4\n" + bytes([128, 64, 32, 129]))
    _one_line_error(p, "truncated or corrupt")
    z = tmp_path / "z.hdr"
    z.write_bytes(_HDR_HEAD + b"-Y 0 +X 4\n")
    _one_line_error(z)
    zp = tmp_path / "z.pfm"
    zp.write_bytes(b"PF\n0 0\n-1.0\n")
    _one_line_error(zp, "zero size")


def test_nan_inf_negative(tmp_path):
    a = _img()
    a[0, 0, 0] = np.nan
    a[1, 1, 1] = np.inf
    a[2, 2, 2] = -1.0
    a[2, 3, 2] = -2.0
    import OpenImageIO as oiio  # write_image itself refuses NaN/Inf, so write the file raw

    out = oiio.ImageOutput.create(str(tmp_path / "bad.exr"))
    out.open(str(tmp_path / "bad.exr"), oiio.ImageSpec(a.shape[1], a.shape[0], 3, oiio.FLOAT))
    out.write_image(a)
    out.close()
    msg = _one_line_error(tmp_path / "bad.exr", "1 NaN")
    assert "1 infinite" in msg and "2 negative" in msg
    b = read_image(tmp_path / "bad.exr", clamp=True)
    assert np.all(np.isfinite(b)) and b.min() == 0.0
    assert b[0, 0, 0] == 0 and b[1, 1, 1] == np.nanmax(np.where(np.isinf(a), np.nan, a))


def test_write_refuses_existing_and_bad_extension(tmp_path):
    a = _img()
    write_image(tmp_path / "a.exr", a)
    before = (tmp_path / "a.exr").read_bytes()
    with pytest.raises(ShprobeError, match="already exists"):
        write_image(tmp_path / "a.exr", a * 2)
    assert (tmp_path / "a.exr").read_bytes() == before
    write_image(tmp_path / "a.exr", a * 2, overwrite=True)
    np.testing.assert_array_equal(read_image(tmp_path / "a.exr"), a * 2)
    with pytest.raises(ShprobeError, match="cannot write extension"):
        write_image(tmp_path / "a.gif", a)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.exr"]  # no temp files left


def test_write_refuses_nan_and_inf(tmp_path):
    from shprobe.errors import ShprobeError
    from shprobe.probes.images import write_image

    a = np.ones((4, 8, 3), np.float32)
    a[1, 2, 0] = np.nan
    a[3, 3, 1] = np.inf
    for ext in (".exr", ".hdr", ".pfm", ".png"):
        out = tmp_path / f"bad{ext}"
        with pytest.raises(ShprobeError, match="2 NaN or Inf"):
            write_image(out, a)
        assert not out.exists() and not list(tmp_path.iterdir())
