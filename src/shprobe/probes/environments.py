"""Procedural environments (the built-in default data of ``shprobe demo``).

[`procedural_env`][shprobe.probes.environments.procedural_env] is a deterministic lat-long map
(world +Y up): a sky gradient, a small bright sun, a dim ground and three coloured "windows" on the
horizon — enough structure to give every l ≤ 2 coefficient a visible value.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from .env import Env
from .layouts import LatLong

#: Unit direction of the sun of :func:`procedural_env`.
SUN_DIRECTION = np.array([0.45, 0.6, -0.66]) / np.linalg.norm([0.45, 0.6, -0.66])
#: Angular radius of the sun (radians) and its radiance (RGB).
SUN_RADIUS = np.radians(4.0)
SUN_RADIANCE = np.array([60.0, 52.0, 40.0])

# (azimuth ψ centre°, half width°, elevation low°, high°, RGB radiance)
_WINDOWS = (
    (100.0, 12.0, 4.0, 30.0, (6.0, 0.6, 0.4)),
    (200.0, 10.0, 6.0, 26.0, (0.4, 4.0, 0.8)),
    (300.0, 14.0, 2.0, 22.0, (0.5, 1.2, 6.0)),
)


def procedural_radiance(dirs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Radiance (..., 3) of the procedural environment in unit directions (..., 3).

    Parameters
    ----------
    dirs
        (..., 3) unit directions.

    Returns
    -------
    ndarray of shape (..., 3)
        The procedural sky's radiance.
    """
    d = np.asarray(dirs, dtype=np.float64)
    y = d[..., 1:2]
    up = np.clip(y, 0.0, 1.0)
    horizon = np.array([0.85, 0.9, 1.0])
    zenith = np.array([0.2, 0.4, 0.95])
    sky = horizon + (zenith - horizon) * np.sqrt(up)
    ground = np.array([0.22, 0.18, 0.13]) * (0.6 + 0.4 * np.clip(-y, 0.0, 1.0))
    out = np.where(y >= 0.0, sky, ground)
    # sun: a disc with a one-degree soft edge
    ang = np.arccos(np.clip(d @ SUN_DIRECTION, -1.0, 1.0))[..., None]
    edge = np.clip((SUN_RADIUS - ang) / np.radians(1.0) + 0.5, 0.0, 1.0)
    out = out + edge * SUN_RADIANCE
    # windows in azimuth ψ (lat-long convention: ω = (−sin ψ sin θ, cos θ, cos ψ sin θ))
    psi = np.degrees(np.arctan2(-d[..., 0], d[..., 2])) % 360.0
    elev = np.degrees(np.arcsin(np.clip(d[..., 1], -1.0, 1.0)))
    for centre, half, lo, hi, rgb in _WINDOWS:
        dpsi = np.abs((psi - centre + 180.0) % 360.0 - 180.0)
        inside = (dpsi <= half) & (elev >= lo) & (elev <= hi)
        out = np.where(inside[..., None], np.asarray(rgb), out)
    return out


def procedural_env(width: int = 256, height: int = 128) -> Env:
    """The procedural environment as a lat-long Env of ``width`` × ``height`` (W = 2H),
    each pixel the mean of 2×2 sub-samples.

    Parameters
    ----------
    width, height
        The lat-long size (W = 2H).

    Returns
    -------
    Env
        The procedural sky as a lat-long map.
    """
    if width != 2 * height or height < 2:
        raise ShprobeError(f"procedural_env needs W = 2H ≥ 4, got {width}x{height}")
    lay = LatLong()
    sub = lay.pixel_directions((2 * height, 2 * width))
    rad = procedural_radiance(sub).reshape(height, 2, width, 2, 3).mean(axis=(1, 3))
    return Env(rad.astype(np.float32), lay, "<procedural>")


__all__ = ["SUN_DIRECTION", "procedural_env", "procedural_radiance"]
