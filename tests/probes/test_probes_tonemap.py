"""The one tone map and exposure (probes.images): sRGB operator, auto exposure."""

from __future__ import annotations

import numpy as np

from shprobe.probes.tonemap import auto_exposure, tonemap


def test_tonemap_operator():
    v = np.array([[[0.0, 0.1, 0.5]]])
    out = tonemap(v, exposure=1.0)
    lin = np.clip(v * 2, 0, 1)
    srgb = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)
    np.testing.assert_array_equal(out, np.round(srgb * 255).astype(np.uint8))
    assert out[0, 0, 2] == 255


def test_auto_exposure_puts_the_99th_percentile_at_target():
    """The 99th percentile of the largest channel lands exactly on ``target`` after × 2^stops;
    no light gives 0 stops (not a division by zero)."""
    rng = np.random.default_rng(5)
    rad = rng.gamma(2.0, 0.3, size=(500, 3))
    for target in (0.8, 1.0):
        stops = auto_exposure(rad, target)
        peak = np.sort(rad.max(axis=1))
        p99 = np.interp(0.99 * (len(peak) - 1), np.arange(len(peak)), peak)  # numpy's linear
        assert abs(p99 * 2.0**stops - target) < 1e-12
        # ≈ 1 % of the values clip at white, the rest do not
        clipped = (tonemap(rad * 2.0 ** (stops - np.log2(target))) == 255).any(axis=1).mean()
        assert 0.005 <= clipped <= 0.02
    assert auto_exposure(np.zeros((4, 3))) == 0.0
    assert auto_exposure(np.zeros((0, 3))) == 0.0
    # a list of frames counts as one set of values (a turntable shares one exposure)
    assert auto_exposure([rad[:250], rad[250:]]) == auto_exposure(rad)
