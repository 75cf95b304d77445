"""Layouts: known directions on known pixels, exact solid angles, round trips, and one synthetic
environment giving the same SH coefficients in every layout."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.layouts import Env, LatLong, detect_layout, env_from_function, get_layout, load_env

FOUR_PI = 4.0 * np.pi


def test_latlong_known_directions():
    lay = get_layout("latlong")
    h, w = 64, 128
    xy = lay.direction_to_pixel([[1, 0, 0], [0, 0, -1], [-1, 0, 0], [0, 1, 0], [0, -1, 0]],
                                (h, w))
    np.testing.assert_allclose(xy[:3], [[0.75 * w, h / 2], [0.5 * w, h / 2], [0.25 * w, h / 2]],
                               atol=1e-9)
    assert xy[3, 1] == pytest.approx(0.0) and xy[4, 1] == pytest.approx(h)
    d = lay.pixel_directions((h, w))
    # the pixel right of u = 0.75 on the row below the equator looks nearly along +X
    np.testing.assert_allclose(d[h // 2, 3 * w // 4], [1, 0, 0], atol=np.pi / h)
    assert d[0, 0, 1] > 0.99 and d[-1, 0, 1] < -0.99  # row 0 = +Y


def test_latlong_solid_angles_exact():
    lay = LatLong()
    for h in (1, 3, 64, 513):
        sa = lay.solid_angles((h, 2 * h))
        assert abs(sa.sum() - FOUR_PI) < 1e-9
    # a row's solid angle is the spherical zone area / W (independent closed form)
    h, w = 10, 20
    j = 3
    zone = 2 * np.pi * (np.cos(np.pi * j / h) - np.cos(np.pi * (j + 1) / h))
    assert LatLong.row_solid_angle(h, w)[j] * w == pytest.approx(zone, rel=1e-13)
    # separable helpers rebuild the directions
    d = lay.pixel_directions((h, w))
    cx, cz = LatLong.column_xz(w)
    st = LatLong.row_sin_theta(h)
    np.testing.assert_allclose(d[..., 1], np.repeat(LatLong.row_cos_theta(h)[:, None], w, 1))
    np.testing.assert_allclose(d[..., 0], st[:, None] * cx)
    np.testing.assert_allclose(d[..., 2], st[:, None] * cz)


def test_latlong_round_trip_and_sample():
    lay = LatLong()
    grid = (32, 64)
    d = lay.pixel_directions(grid)
    xy = lay.direction_to_pixel(d, grid)
    jj, ii = np.mgrid[0:32, 0:64] + 0.5
    np.testing.assert_allclose(xy, np.stack([ii, jj], -1), atol=1e-9)
    img = np.random.default_rng(1).random((32, 64, 3)).astype(np.float32)
    np.testing.assert_allclose(lay.sample(img, d), img, atol=1e-5)


def test_detect_layout():
    assert detect_layout((128, 256, 3)) == "latlong"
    assert detect_layout((100, 100)) == "angular"
    for shape in ((300, 400), (400, 300), (50, 300), (300, 50)):
        assert detect_layout(shape) == "cube"
    with pytest.raises(ShprobeError, match="cannot tell"):
        detect_layout((100, 150), "x.hdr")
    with pytest.raises(ShprobeError, match="zero size"):
        detect_layout((0, 0), "x.hdr")


def test_load_env_grace(grace_path):
    env = load_env(grace_path)
    assert env.layout.name == "latlong" and env.grid == (128, 256)
    assert env.radiance.dtype == np.float32 and env.radiance.shape == (128, 256, 3)
    dirs, rad, dw = env.samples()
    assert dirs.shape == (128 * 256, 3) and rad.shape == (128 * 256, 3)
    assert abs(dw.sum() - FOUR_PI) < 1e-9


def test_wrong_aspect_for_requested_layout(grace_path):
    with pytest.raises(ShprobeError, match=r"grace\.hdr") as e:
        load_env(grace_path, layout="angular")
    assert "\n" not in str(e.value)
    with pytest.raises(ShprobeError, match="2:1"):
        Env(np.zeros((10, 10, 3), np.float32), "latlong")


def test_env_from_function_latlong():
    env = env_from_function(lambda d: np.stack([d[..., 0], d[..., 1], d[..., 2]], -1) + 1,
                            "latlong", 16)
    assert env.grid == (16, 32)
    np.testing.assert_allclose(env.radiance, env.directions() + 1, atol=1e-6)
