"""How a lightmap is baked: one frozen settings type,
[`LightmapSettings`][shprobe.lightmaps.LightmapSettings]."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ShprobeError
from .format import check_encoding

__all__ = ["MAX_SIZE", "LightmapSettings", "parse_sun"]

#: the largest lightmap side (texels); 65536 and above cannot be indexed by 16-bit tools
MAX_SIZE = 16384


def _positive_int(name: str, v: Any, low: int, high: int | None = None) -> int:
    if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < low or (
            high is not None and v > high):
        top = f" and <= {high}" if high is not None else ""
        raise ShprobeError(f"lightmap {name} must be an integer >= {low}{top}, got {v!r}")
    return int(v)


@dataclass(frozen=True)
class LightmapSettings:
    """Settings of [`shprobe.lightmaps.bake_lightmap`][shprobe.lightmaps.bake_lightmap].

    Parameters
    ----------
    basis : str
        The encoding written to the .glb: "h6", "h4", "sh9", "sh4", "hl2" or "plain" (all six
        are computed; this one is saved). A "plain" bake samples its rays mostly
        cosine-weighted, which suits it and leaves the other five noisier
        (`shprobe.lightmaps.hits`).
    albedo : float or tuple of 3 floats, optional
        Diffuse albedo of every surface for the bounces, replacing the materials' base colour
        (factor × texture) when given.
    texels_per_unit : float, optional
        Lightmap density in texels per scene unit (the atlas size follows); else ``size``.
    size : int
        The lightmap's side in texels when ``texels_per_unit`` is None (default 256).
    bounces : int
        Diffuse bounces inside the scene (0: sky and sun only).
    samples : int
        Hemisphere rays per texel, stratified over a kz × kφ grid of every count (a prime
        count is stratified in φ only; counts with near-square factors, 64 or 128, are best).
    denoise : bool
        Run Intel Open Image Denoise (RTLightmap filter) on the coefficient maps.
    sun : tuple, optional
        ((dx, dy, dz), (r, g, b)): direction TOWARDS the sun (world frame) and its irradiance
        on a surface facing it.
    seed : int
        Seed of the sample pattern (a bake is a pure function of its inputs and settings).
    padding : int
        Texels between xatlas charts.
    transfer : bool
        Also store, per texel, the matrix from the sky's SH (lmax 2) to the coefficients.
    max_texels : int
        Refuse atlases with more covered texels than this.
    """

    basis: str = "h6"
    albedo: float | tuple[float, float, float] | None = None
    texels_per_unit: float | None = None
    size: int = 256
    bounces: int = 1
    samples: int = 64
    denoise: bool = False
    sun: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    seed: int = 0
    padding: int = 2
    transfer: bool = False
    max_texels: int = 4_000_000

    def __post_init__(self) -> None:
        object.__setattr__(self, "basis", check_encoding(self.basis))
        if self.texels_per_unit is not None:
            t = self.texels_per_unit
            if not (isinstance(t, int | float) and math.isfinite(t) and t > 0):
                raise ShprobeError(f"--texels-per-unit must be a finite number > 0, got {t!r}")
        if isinstance(self.size, bool) or not isinstance(self.size, int | np.integer) or not (
                4 <= self.size <= MAX_SIZE):
            raise ShprobeError(f"lightmap --size must be an integer from 4 to {MAX_SIZE}, "
                               f"got {self.size!r}")
        _positive_int("bounces", self.bounces, 0, 16)
        _positive_int("samples", self.samples, 1, 1 << 16)
        _positive_int("padding", self.padding, 1, 64)
        _positive_int("max_texels", self.max_texels, 1)
        if self.albedo is not None:
            a = np.broadcast_to(np.asarray(self.albedo, dtype=float), 3)
            if not (np.isfinite(a).all() and (a >= 0).all() and (a <= 1).all()):
                raise ShprobeError(f"--albedo must be in [0, 1] (one value or three), "
                                   f"got {self.albedo!r}")
        if self.sun is not None:
            d, c = (np.asarray(x, dtype=float) for x in self.sun)
            if d.shape != (3,) or c.shape != (3,) or not (np.isfinite(d).all()
                                                          and np.isfinite(c).all()):
                raise ShprobeError("--sun must be a direction and an RGB irradiance, 6 numbers")
            if np.linalg.norm(d) == 0 or (c < 0).any():
                raise ShprobeError("--sun needs a nonzero direction and a non-negative colour")

    @property
    def albedo_rgb(self) -> np.ndarray | None:
        """The albedo override as (3,), or None."""
        if self.albedo is None:
            return None
        return np.broadcast_to(np.asarray(self.albedo, dtype=float), 3).copy()

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values.

        Returns
        -------
        dict
            Field name → value.
        """
        from dataclasses import asdict

        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}


def parse_sun(text: str) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """'dx,dy,dz,r,g,b' (or 'dx,dy,dz,e' for white) → the ``sun`` setting.

    Parameters
    ----------
    text : str
        Six (or four) comma-separated numbers.

    Returns
    -------
    tuple
        ((dx, dy, dz), (r, g, b)).
    """
    try:
        v = [float(x) for x in str(text).replace(" ", "").split(",")]
    except ValueError:
        v = []
    if len(v) == 4:
        v = v[:3] + [v[3]] * 3
    if len(v) != 6 or not all(math.isfinite(x) for x in v):
        raise ShprobeError(f"--sun takes DX,DY,DZ,R,G,B (six numbers), got {text!r}")
    return (v[0], v[1], v[2]), (v[3], v[4], v[5])
