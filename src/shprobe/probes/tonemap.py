"""Display encoding: the sRGB transfer functions, the one tone map and the one exposure rule.

Every 8-bit picture shprobe writes goes through `tonemap` (linear radiance scaled by
2**exposure, clamped, sRGB-encoded); `auto_exposure` picks the exposure when none is given.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def srgb_to_linear(v: ArrayLike) -> NDArray[np.float32]:
    """sRGB EOTF (IEC 61966-2-1), values in [0, 1]."""
    v = np.asarray(v, dtype=np.float32)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(v: ArrayLike) -> NDArray[np.float32]:
    """sRGB OETF (inverse of `srgb_to_linear`), input clamped to [0, 1]."""
    v = np.clip(np.asarray(v, dtype=np.float32), 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055).astype(np.float32)



def tonemap(rgb: ArrayLike, exposure: float = 0.0) -> NDArray[np.uint8]:
    """Linear RGB → 8-bit sRGB: scale by 2**exposure, clamp to [0, 1], sRGB OETF, round.

    The one tone map: every PNG shprobe writes goes through it
    ([`write_image`][shprobe.probes.images.write_image])."""
    v = np.asarray(rgb, dtype=np.float32) * np.float32(2.0 ** exposure)
    v = np.nan_to_num(v, nan=0.0, posinf=1.0, neginf=0.0)
    return np.round(linear_to_srgb(v) * 255.0).astype(np.uint8)


def auto_exposure(radiance: ArrayLike, target: float = 0.8, percentile: float = 99.0) -> float:
    """Exposure in stops for `tonemap` that maps the ``percentile``-th percentile of the
    largest channel of ``radiance`` (..., C) to ``target`` (0 when there is no light): bright
    enough to see, with at most ~1 % of the values clipped. The one exposure rule; pictures
    with labelled panels round it to 0.1 stop
    ([`shprobe.probes.figures.exposure_for`][shprobe.probes.figures.exposure_for])."""
    a = np.asarray(radiance, dtype=np.float64)
    if a.size == 0:
        return 0.0
    peak = float(np.percentile(np.max(a, axis=-1), percentile))
    return float(np.log2(target / peak)) if np.isfinite(peak) and peak > 0 else 0.0

