"""How a grid is baked: [`GridSettings`][shprobe.grids.GridSettings], checked in one place before
any work."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..limits import Limits

__all__ = ["MAX_RESOLUTION", "GridSettings"]

#: The most probes along one axis (a grid of 512³ probes would be 134 million probes).
MAX_RESOLUTION = 512


@dataclass(frozen=True)
class GridSettings:
    """The bake of a probe grid; the defaults are ``shprobe grid bake``'s.

    Parameters
    ----------
    resolution
        Probes along X, Y, Z.
    bounds
        (2, 3) min and max corners of the volume (None: the scene's bounding box).
    lmax
        1 or 2.
    bounces
        Diffuse interreflection bounces (0: the environment as the probe sees it past the
        scene, surfaces black).
    samples
        Ray directions per probe (spherical Fibonacci): the accuracy option.
    depth_resolution
        Texels a side of each probe's octahedral depth map (leak control).
    depth_samples
        Rays a side per depth texel.
    normal_bias
        The lookup offset along the normal, a fraction of the smallest cell side.
    inside_fraction
        A probe whose rays hit back faces more often than this is inside geometry: moved
        within its cell to free space, else marked invalid and filled from its neighbours.
    seed
        The random turn of the direction set (and of the gather's rays).
    gather
        Rays per surface a probe ray meets, gathering that surface's irradiance from the
        surface itself (0: read it from the grid of the bounce before, DDGI's recursion,
        which lights the foot of a wall as the nearest probe sees it; docs/grids.md gives
        both).
    limits
        The memory limit the bake is refused over (`shprobe.limits.Limits`).
    """

    resolution: tuple[int, int, int]
    bounds: Any = None
    lmax: int = 2
    bounces: int = 2
    samples: int = 4096
    depth_resolution: int = 16
    depth_samples: int = 2
    normal_bias: float = 0.1
    inside_fraction: float = 0.25
    seed: int = 0
    gather: int = 2
    limits: Limits = field(default_factory=Limits, compare=False)

    def __post_init__(self) -> None:
        res = tuple(self.resolution) if not isinstance(self.resolution, str) else ()
        if len(res) != 3 or not all(_is_int(r) for r in res):
            raise ShprobeError(f"grid resolution must be three integers NX,NY,NZ, got "
                               f"{self.resolution!r}")
        if not all(1 <= int(r) <= MAX_RESOLUTION for r in res):
            raise ShprobeError(f"grid resolution {','.join(str(int(r)) for r in res)}: each "
                               f"axis needs 1 to {MAX_RESOLUTION} probes")
        object.__setattr__(self, "resolution", tuple(int(r) for r in res))
        if self.bounds is not None:
            object.__setattr__(self, "bounds", check_bounds(self.bounds))
        for name, lo, hi in (("lmax", 1, 2), ("bounces", 0, 16), ("samples", 64, 1 << 20),
                             ("depth_resolution", 4, 64), ("depth_samples", 1, 8),
                             ("seed", 0, 2**32 - 1), ("gather", 0, 256)):
            v = getattr(self, name)
            if not _is_int(v) or not lo <= int(v) <= hi:
                raise ShprobeError(f"grid {name} must be an integer in {lo}..{hi}, got {v!r}")
            object.__setattr__(self, name, int(v))
        for name, lo, hi in (("normal_bias", 0.0, 0.5), ("inside_fraction", 0.0, 1.0)):
            v = getattr(self, name)
            if not isinstance(v, int | float) or not math.isfinite(v) or not lo <= v <= hi:
                raise ShprobeError(f"grid {name} must be a number in [{lo}, {hi}], got {v!r}")

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values.

        Returns
        -------
        dict
            Each field (bounds as two corners or None).
        """
        d = {f: getattr(self, f) for f in self.__dataclass_fields__ if f != "limits"}
        d["resolution"] = list(self.resolution)
        d["bounds"] = None if self.bounds is None else np.asarray(self.bounds).tolist()
        d["limits"] = self.limits.as_dict()
        return d

    @property
    def n_probes(self) -> int:
        nx, ny, nz = self.resolution
        return nx * ny * nz

    @property
    def depth_rays(self) -> int:
        """Rays per probe for its depth map."""
        return (self.depth_resolution * self.depth_samples) ** 2


def check_bounds(bounds: Any) -> NDArray[np.float64]:
    """(2, 3) finite min/max corners with max > min on every axis, within
    ±`MAX_COORDINATE`, or one line.

    Parameters
    ----------
    bounds : array_like
        Six numbers X0, Y0, Z0, X1, Y1, Z1 (or a (2, 3) array).

    Returns
    -------
    numpy.ndarray
        The (2, 3) float64 corners.
    """
    try:
        b = np.asarray(bounds, dtype=np.float64).reshape(2, 3)
    except (TypeError, ValueError):
        raise ShprobeError(f"grid bounds must be six numbers X0,Y0,Z0,X1,Y1,Z1, got "
                           f"{bounds!r}") from None
    if not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
        raise ShprobeError("grid bounds must be finite, X0,Y0,Z0 (min corner) then X1,Y1,Z1 "
                           "(max corner), max > min on every axis")
    if np.abs(b).max() > MAX_COORDINATE:
        raise ShprobeError(f"grid bounds reach {np.abs(b).max():.3g}: a grid lies within "
                           f"±{MAX_COORDINATE:g} (its depth maps hold squared distances as "
                           "float32); rescale the scene")
    return b


#: Largest magnitude of a grid's bounds, probe positions and depths: the depth maps hold
#: squared distances as float32 (3.4e38), and the viewer draws in float32.
MAX_COORDINATE = 1e15


def _is_int(v: Any) -> bool:
    return isinstance(v, int | np.integer) and not isinstance(v, bool)
