"""Image layouts read from files and LDR decoding: known directions on known pixels of the
cube-map *files* (crosses and strips), and JPEG decoded from sRGB by an independent decoder."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from shprobe.probes.env import env_from_function, load_env, write_env
from shprobe.probes.images import LDRWarning, read_image

N = 9  # odd: the middle texel of a face looks exactly along its axis
S3 = 1.0 / np.sqrt(3.0)
AXES = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]


def texel(face_col, face_row, where="centre"):
    """(column, row) of the middle / top-left / bottom-right texel of the face at a place."""
    k = {"centre": N // 2, "top-left": 0, "bottom-right": N - 1}[where]
    return face_col * N + k, face_row * N + k


@pytest.mark.parametrize(("arrangement", "pixels"), [
    ("hcross", [(texel(2, 1), AXES[0]), (texel(0, 1), AXES[1]), (texel(1, 0), AXES[2]),
                (texel(1, 2), AXES[3]), (texel(1, 1), AXES[4]), (texel(3, 1), AXES[5]),
                # +Z face: image right = +X, image down = −Y
                (texel(1, 1, "top-left"), (-S3, S3, S3)),
                (texel(1, 1, "bottom-right"), (S3, -S3, S3))]),
    ("vcross", [(texel(2, 1), AXES[0]), (texel(0, 1), AXES[1]), (texel(1, 0), AXES[2]),
                (texel(1, 2), AXES[3]), (texel(1, 1), AXES[4]), (texel(1, 3), AXES[5]),
                # −Z below −Y, turned by 180°: image right = +X, image down = +Y
                (texel(1, 3, "top-left"), (-S3, -S3, -S3)),
                (texel(1, 3, "bottom-right"), (S3, S3, -S3))]),
    ("hstrip", [(texel(k, 0), d) for k, d in enumerate(AXES)]),
    ("vstrip", [(texel(0, k), d) for k, d in enumerate(AXES)]),
])
def test_cube_files_known_pixels(tmp_path, arrangement, pixels):
    """Write the map ω ↦ ω + 1 (positive, a valid radiance) in each arrangement, read the file
    back as plain pixels, and find the expected direction at the expected texel (a corner
    texel's centre is 1/N of a face from the corner: ≈ 0.1 off); the file reloads as the same
    cube map."""
    env = env_from_function(lambda d: d + 1.0, "cube", N)
    path = tmp_path / f"{arrangement}.pfm"
    write_env(path, env, arrangement=arrangement)
    img = read_image(path) - 1.0
    for (col, row), want in pixels:
        got = img[row, col] / np.linalg.norm(img[row, col])
        tol = 1e-6 if row % N == N // 2 else 0.15
        np.testing.assert_allclose(got, want, atol=tol)
    back = load_env(path)
    assert back.layout.name == "cube"
    np.testing.assert_allclose(back.radiance, env.radiance, rtol=1e-6)


def test_jpeg_decoded_from_srgb_with_a_warning(tmp_path):
    """JPEG pixels decoded by Pillow (an independent decoder), then the IEC 61966-2-1 curve."""
    from PIL import Image

    rng = np.random.default_rng(0)
    a = (rng.random((24, 48, 3)) * 255).round().astype(np.uint8)
    p = tmp_path / "probe.jpg"
    Image.fromarray(a).save(p, quality=95)
    v = np.asarray(Image.open(p), dtype=np.float64) / 255.0
    want = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        got = read_image(p)
    assert any(issubclass(w.category, LDRWarning) for w in caught)
    assert got.shape == (24, 48, 3) and got.dtype == np.float32
    # two JPEG decoders may differ by an IDCT rounding step (1/255 before the curve)
    assert np.abs(got - want).max() < 2.5 / 255
    assert np.abs(got - want).mean() < 0.2 / 255
