"""Cameras orbiting an object (R&H 2001 §3.2 renders): pinhole or orthographic, primary rays.

Camera frame: world +Y up. At azimuth 0 and elevation 0 the camera sits on the +Z side of the
object looking along −Z (the direction at the centre u = 0.5 of a lat-long map); positive
azimuth turns the camera position from +Z towards +X about +Y, positive elevation lifts it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..limits import check_memory

__all__ = ["PROJECTIONS", "Camera"]

PROJECTIONS = ("perspective", "orthographic")


#: Narrowest field of view, degrees: narrower, the focal length 1/tan(fov/2) overflows the
#: ray arithmetic long before the picture changes.
MIN_FOV = 1e-3
#: Largest camera distance: ray origins are 32-bit floats in the caster's frame.
MAX_DISTANCE = 1e30

@dataclass(frozen=True)
class Camera:
    """A pinhole (perspective) or orthographic camera orbiting the object.

    Angles in degrees. ``fov`` is the vertical field of view of the perspective camera.
    ``distance`` (from the target) and ``target`` default to a fit of the object's bounding
    sphere with ``margin`` (1.0 = the sphere just touches the nearer image edge). For the
    orthographic camera ``distance`` only places the ray origins; ``ortho_height`` (the
    world-space height of the view) defaults to the fit.

    Parameters
    ----------
    width, height
        The image's size, pixels.
    projection
        "perspective" or "orthographic".
    azimuth, elevation
        The orbit's angles, degrees.
    fov
        The perspective camera's vertical field of view, degrees.
    distance
        From the target (default: fitted to the object).
    target
        The point looked at (default: the object's centre).
    margin
        The fit's margin (1.0: the bounding sphere touches the nearer image edge).
    ortho_height
        The orthographic view's world-space height (default: fitted).
    """

    width: int = 512
    height: int = 512
    projection: str = "perspective"
    azimuth: float = 0.0
    elevation: float = 0.0
    fov: float = 40.0
    distance: float | None = None
    target: tuple[float, float, float] | None = None
    margin: float = 1.1
    ortho_height: float | None = None

    def __post_init__(self) -> None:
        if self.projection not in PROJECTIONS:
            raise ShprobeError(f"projection must be one of {PROJECTIONS}, got {self.projection!r}")
        if int(self.width) <= 0 or int(self.height) <= 0:
            raise ShprobeError(f"image size must be positive, got {self.width}x{self.height}")
        if not MIN_FOV <= float(self.fov) < 180.0:
            raise ShprobeError(f"field of view must be in [{MIN_FOV:g}, 180) degrees, got "
                               f"{self.fov} (an orthographic camera is the limit of a narrow "
                               "one)")
        if self.distance is not None and not 0.0 < abs(float(self.distance)) <= MAX_DISTANCE:
            raise ShprobeError(f"camera distance must be non-zero and at most {MAX_DISTANCE:g} "
                               f"(rays are traced in 32-bit floats), got {self.distance}")
        if not self.margin > 0.0:
            raise ShprobeError(f"margin must be positive, got {self.margin}")
        for name in ("azimuth", "elevation", "fov", "margin", "distance", "ortho_height"):
            v = getattr(self, name)
            if v is not None and not np.isfinite(float(v)):
                raise ShprobeError(f"camera {name} must be a finite number, got {v}")
        if self.target is not None and not np.all(np.isfinite(np.asarray(self.target, float))):
            raise ShprobeError(f"camera target must be finite, got {self.target}")

    @property
    def aspect(self) -> float:
        return self.width / self.height

    def basis(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(forward, right, up) unit vectors of the camera in world space.

        Returns
        -------
        tuple of ndarray
            forward, right and up, each (3,).
        """
        az, el = np.radians(self.azimuth), np.radians(self.elevation)
        back = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
        fwd = -back
        right = np.cross(fwd, [0.0, 1.0, 0.0])
        if np.linalg.norm(right) < 1e-9:  # looking straight up/down: keep +X to the right
            right = np.array([np.cos(az), 0.0, -np.sin(az)])
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        return fwd, right, up / np.linalg.norm(up)

    def framing(self, center: ArrayLike, radius: float) -> tuple[NDArray, float, float]:
        """(target, distance, half height of the view at the target) for a bounding sphere.

        Parameters
        ----------
        center, radius
            The bounding sphere.

        Returns
        -------
        tuple
            (target, distance, half height of the view at the target).
        """
        c = np.asarray(self.target if self.target is not None else center, dtype=np.float64)
        r = float(radius) * self.margin
        t = np.tan(np.radians(self.fov) / 2.0)
        half_angle = min(np.arctan(t), np.arctan(t * self.aspect))
        if self.distance is not None:
            d = float(self.distance)
        elif self.projection == "perspective":
            d = r / np.sin(half_angle)
        else:
            d = 2.0 * r + 1e-6
        if self.ortho_height is not None:
            hh = self.ortho_height / 2.0
        else:
            hh = r * max(1.0, 1.0 / self.aspect)
        return c, d, hh

    def rays(self, center: ArrayLike, radius: float) -> tuple[NDArray, NDArray]:
        """Primary rays through pixel centres, (H·W, 3) origins and unit directions, row-major
        with row 0 at the top of the image.

        Parameters
        ----------
        center, radius
            The bounding sphere framed.

        Returns
        -------
        tuple of ndarray
            Origins and unit directions, each (H·W, 3), row 0 at the top.
        """
        w, h = int(self.width), int(self.height)
        # rays, hits, normals, shading and the image: about 256 bytes a pixel, planned first
        check_memory(256.0 * w * h, f"rendering {w}x{h} pixels")
        c, d, hh = self.framing(center, radius)
        fwd, right, up = self.basis()
        sx = (np.arange(w) + 0.5) / w * 2.0 - 1.0
        sy = 1.0 - (np.arange(h) + 0.5) / h * 2.0
        eye = c - d * fwd
        if self.projection == "perspective":
            t = np.tan(np.radians(self.fov) / 2.0)
            px = sx * t * self.aspect
            py = sy * t
            dirs = fwd + px[None, :, None] * right + py[:, None, None] * up
            dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
            origins = np.broadcast_to(eye, dirs.shape)
        else:
            px = sx * hh * self.aspect
            py = sy * hh
            origins = eye + px[None, :, None] * right + py[:, None, None] * up
            dirs = np.broadcast_to(fwd, origins.shape)
        return (np.ascontiguousarray(origins.reshape(-1, 3)),
                np.ascontiguousarray(dirs.reshape(-1, 3)))
