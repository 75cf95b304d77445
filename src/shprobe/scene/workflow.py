"""The render workflow in the one shape: `RenderSettings` (``shprobe render``'s
defaults), one entry `render_image` that renders a diffuse object under SH lighting
(R&H 2001 §3.2) and writes the picture, and its `RenderImageResult`."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ShprobeError
from ..progress import Progress, Steps
from .camera import Camera

__all__ = ["RENDER_MODES", "BasisImagesSettings", "RenderImageResult", "RenderSettings",
           "render_image"]

#: Per-pixel shading, or per-vertex shading interpolated (R&H's procedural shader).
RENDER_MODES = ("pixel", "vertex")


@dataclass(frozen=True)
class RenderSettings:
    """Settings of a render (`render_image`); the defaults are ``shprobe render``'s.

    Parameters
    ----------
    mode
        'pixel' or 'vertex' shading.
    size
        Image (width, height) in pixels.
    azimuth
        Orbit angle about +Y, degrees (0: camera on +Z looking along -Z).
    elevation
        Orbit elevation, degrees.
    fov
        Vertical field of view, degrees (perspective).
    ortho
        An orthographic camera.
    albedo
        A constant albedo r,g,b (None: the mesh's own colours, else 1).
    exposure
        PNG tone map in stops (None: automatic, the 99th percentile of the object at white).
    """

    mode: str = "pixel"
    size: tuple[int, int] = (512, 512)
    azimuth: float = 0.0
    elevation: float = 0.0
    fov: float = 40.0
    ortho: bool = False
    albedo: Any = None
    exposure: float | None = None

    def __post_init__(self) -> None:
        if self.mode not in RENDER_MODES:
            raise ShprobeError(f"render mode must be one of {', '.join(RENDER_MODES)}, got "
                               f"{self.mode!r}")
        if self.exposure is not None and not math.isfinite(self.exposure):
            raise ShprobeError(f"exposure must be a finite number, got {self.exposure!r}")

    def camera(self) -> Camera:
        """The camera these settings describe.

        Returns
        -------
        Camera
            Its size, orbit, field of view and projection.
        """
        w, h = self.size
        return Camera(int(w), int(h), projection="orthographic" if self.ortho else "perspective",
                      azimuth=self.azimuth, elevation=self.elevation, fov=self.fov)


@dataclass(frozen=True)
class BasisImagesSettings:
    """Settings of the irradiance basis images (``shprobe basis-images``'s defaults): the
    camera of a render and the degree of the basis.

    Parameters
    ----------
    lmax
        Degree of the basis: one image per (l, m) up to it.
    mode
        'pixel' or 'vertex' shading.
    size
        Image (width, height) in pixels.
    azimuth
        Orbit angle about +Y, degrees.
    elevation
        Orbit elevation, degrees.
    fov
        Vertical field of view, degrees (perspective).
    ortho
        An orthographic camera.
    """

    lmax: int = 2
    mode: str = RenderSettings.mode
    size: tuple[int, int] = RenderSettings.size
    azimuth: float = RenderSettings.azimuth
    elevation: float = RenderSettings.elevation
    fov: float = RenderSettings.fov
    ortho: bool = RenderSettings.ortho

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values.

        Returns
        -------
        dict
            Each field.
        """
        return {f: getattr(self, f) for f in self.__dataclass_fields__}


@dataclass(frozen=True)
class RenderImageResult:
    """What `render_image` wrote: the files, the size, the shading mode, the share of
    pixels on the object and the exposure (stops; ``auto`` when chosen from the image)."""

    paths: tuple[Path, ...]
    width: int
    height: int
    mode: str
    object_fraction: float
    exposure: float
    auto: bool

    def as_dict(self) -> dict[str, Any]:
        """The result as JSON-able values.

        Returns
        -------
        dict
            paths, width, height, mode, object_fraction, exposure, auto.
        """
        return {"paths": [str(p) for p in self.paths], "width": self.width,
                "height": self.height, "mode": self.mode,
                "object_fraction": float(self.object_fraction),
                "exposure": float(self.exposure), "auto": self.auto}


def render_image(mesh: Any, coeffs: ArrayLike, output: str | os.PathLike[str],
                 settings: RenderSettings | None = None, progress: Progress | None = None, *,
                 background: Any = None, linear_copy: str | os.PathLike[str] | None = None,
                 overwrite: bool = False) -> RenderImageResult:
    """Render a diffuse object lit by SH lighting and write it (R&H 2001 §3.2).

    Parameters
    ----------
    mesh
        A trimesh mesh, or None for the analytic unit sphere.
    coeffs
        Lighting L_lm, (K, C) or (K,).
    output
        The picture: .png (tone-mapped) or .exr/.hdr/.pfm (linear).
    settings
        The render's `RenderSettings` (default: its defaults).
    progress
        A [`shprobe.progress.Progress`][shprobe.progress.Progress] reporter (rendering, writing).
    background
        None (black), a colour, or an Env (the probe) seen where the rays miss.
    linear_copy
        Also write the linear radiance here (.exr), with the picture or not at all.
    overwrite
        Replace existing files.

    Returns
    -------
    RenderImageResult
        The files, the size, the mode, the object's share of pixels and the exposure.
    """
    from ..files import transaction
    from ..probes.images import check_image_output
    from ..probes.tonemap import auto_exposure
    from .render import render

    s = settings if settings is not None else RenderSettings()
    check_image_output(output, overwrite)
    if linear_copy is not None:
        check_image_output(linear_copy, overwrite)
    cam = s.camera()
    albedo = None if s.albedo is None else np.asarray(s.albedo, dtype=np.float64)
    with Steps(progress, 2) as step:
        step(f"rendering {cam.width}x{cam.height} ({s.mode} shading)")
        res = render(mesh, coeffs, cam, mode=s.mode, albedo=albedo, background=background)
        step("writing")
        stops = s.exposure
        if stops is None:
            stops = auto_exposure(res.image[res.mask] if res.mask.any() else res.image, 1.0)
        with transaction():  # the image and its linear copy: both or neither
            res.save(output, exposure=stops, overwrite=overwrite)
            if linear_copy is not None:
                res.save(linear_copy, overwrite=overwrite)
    paths = (Path(output),) + (() if linear_copy is None else (Path(linear_copy),))
    return RenderImageResult(paths, cam.width, cam.height, s.mode, float(res.mask.mean()),
                             float(stops), s.exposure is None)
