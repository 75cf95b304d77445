"""Pictures carry their exposure: what shprobe writes records the stops it applied and its
colour encoding in the file's metadata, and `shprobe fit` undoes it, so the README tour's
round trip (render a grey ball to PNG, fit it) returns the probe's own lighting."""

from __future__ import annotations

import json
import os
import warnings

import numpy as np
import pytest

from shprobe.cli.main import main
from shprobe.fitting import read_photo
from shprobe.probes.codecs import read_exposure
from shprobe.probes.images import LDRWarning, read_image, write_image
from shprobe.probes.presets import get_preset


@pytest.mark.parametrize("ext", [".png", ".jpg", ".exr", ".tif"])
def test_written_pictures_record_exposure_and_encoding(tmp_path, ext):
    import OpenImageIO as oiio

    a = np.full((8, 8, 3), 0.2, np.float32)
    p = write_image(tmp_path / f"x{ext}", a, exposure=1.25)
    ldr = ext in (".png", ".jpg")
    assert read_exposure(p) == pytest.approx(1.25 if ldr else 0.0, abs=1e-6)
    inp = oiio.ImageInput.open(str(p))
    spec = inp.spec()
    inp.close()
    cs = str(spec.getattribute("oiio:ColorSpace")).lower()
    if ldr:
        assert "srgb" in cs, cs
    elif ext == ".exr":  # TIFF keeps no colour-space tag: its float samples are linear
        assert "lin" in cs and "srgb" not in cs, cs
    assert str(spec.getattribute("Software")).startswith("shprobe")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LDRWarning)
        back = read_image(p) * 2.0 ** -read_exposure(p)
    # 8-bit sRGB near 0.2 · 2^1.25 ≈ 0.48: one code step is ≈ 0.4 % of the value (JPEG ≈ 1)
    np.testing.assert_allclose(back, a, rtol=0.01 if ldr else 1e-6)


def test_png_exposure_is_a_text_chunk(tmp_path):
    """PNG keeps it as a tEXt chunk any PNG tool can read (here: the raw bytes)."""
    p = write_image(tmp_path / "x.png", np.ones((4, 4, 3), np.float32), exposure=-0.5)
    raw = p.read_bytes()
    i = raw.index(b"tEXtshprobe:exposure\x00")
    assert raw[i + 21:i + 25] == b"-0.5"


def test_photo_without_metadata_is_read_as_it_is(tmp_path):
    from PIL import Image

    img = np.zeros((16, 16, 3), np.uint8) + 128
    Image.fromarray(img).save(tmp_path / "camera.png")  # a PNG shprobe did not write
    assert read_exposure(tmp_path / "camera.png") is None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LDRWarning)
        ph = read_photo(tmp_path / "camera.png")
        raw = read_image(tmp_path / "camera.png")
    assert ph.exposure is None and ph.ldr and ph.scale == 1.0
    np.testing.assert_array_equal(ph.image, raw)
    assert ph.saturation() == pytest.approx(0.999)
    # a camera's own Exif exposure bias is not a scale of its pixels: not believed
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(tmp_path / "cam.jpg"))
    spec = oiio.ImageSpec(16, 16, 3, oiio.UINT8)
    spec.attribute("Exif:ExposureBiasValue", 1.0)
    out.open(str(tmp_path / "cam.jpg"), spec)
    out.write_image(img)
    out.close()
    assert read_exposure(tmp_path / "cam.jpg") is None


def test_saturation_scales_with_the_undone_exposure(tmp_path):
    p = write_image(tmp_path / "x.png", np.full((4, 4, 3), 0.1, np.float32), exposure=2.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LDRWarning)
        ph = read_photo(p)
    assert ph.exposure == pytest.approx(2.0)
    assert ph.saturation() == pytest.approx(0.999 / 4)  # the top code value, in radiance
    assert ph.saturation(0.5) == pytest.approx(0.5 / 4)
    np.testing.assert_allclose(ph.image, 0.1, rtol=0.01)


def test_readme_round_trip_returns_the_preset(tmp_path, capsys, monkeypatch):
    """`shprobe render --preset grace --sphere --ortho --size 256 -o ball.png` then `shprobe
    fit grey-ball ball.png -F json -o fitted.json` (README tour): the render auto-exposes
    (+1.53 EV), the PNG records it, the fit undoes it and returns grace's own coefficients.

    Tolerance from the fit's own error: 10 × the standard error it reports per coefficient.
    Measured: at most 6.1 × (8-bit rounding of a smooth ball is correlated from pixel to pixel,
    which the independent-residual standard error does not see); the exposure not undone would
    be off by 2.88× — about 2,000 standard errors."""
    monkeypatch.chdir(tmp_path)
    assert main(["render", "--preset", "grace", "--sphere", "--ortho", "--size", "256",
                 "-o", "ball.png"]) == 0
    ev = read_exposure("ball.png")
    assert ev is not None and ev > 1.0  # auto-exposed, recorded
    assert main(["fit", "grey-ball", "ball.png", "-F", "json", "-o", "fitted.json"]) == 0
    err = capsys.readouterr().err
    assert "EV recorded in its metadata was undone" in err
    doc = json.loads(open("fitted.json").read())
    c, L = np.array(doc["coefficients"]), get_preset("grace")
    stderr = np.array(doc["fit"]["stderr"])
    assert doc["fit"]["photo_exposure"] == pytest.approx(ev)
    assert np.all(np.abs(c - L) <= 10 * stderr), (c - L) / stderr
    assert np.all(np.abs(c * 2.0 ** ev - L) > 100 * stderr[0].max())  # the bug this fixes
    assert os.path.getsize("fitted.json") > 0


def test_chrome_ball_refuses_nan_saturation_as_grey_ball_does(tmp_path, capsys):
    const = np.zeros((32, 32, 3), np.float32)
    jj, ii = np.mgrid[0:32, 0:32]
    const[np.hypot(ii + 0.5 - 16, jj + 0.5 - 16) < 13] = 0.7
    write_image(tmp_path / "chrome.exr", const)
    for kind in ("grey-ball", "chrome-ball"):
        rc = main(["fit", kind, str(tmp_path / "chrome.exr"), "--saturation", "nan"])
        err = capsys.readouterr().err
        lines = [ln for ln in err.splitlines() if ln]
        assert rc != 0 and len(lines) == 1 and "saturation" in lines[0], err
        assert "Traceback" not in err
    from shprobe.errors import ShprobeError
    from shprobe.fitting import fit_chrome_ball

    with pytest.raises(ShprobeError, match="saturation"):
        fit_chrome_ball(const, saturation=float("nan"))
