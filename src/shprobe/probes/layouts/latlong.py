"""The lat-long (equirectangular) layout: exact per-row solid angles, separable row and column
helpers (conventions: `shprobe.probes.layouts`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ...errors import ShprobeError
from .base import Layout, bilinear, grid2, unit


class LatLong(Layout):
    """Equirectangular map, W = 2H, row 0 = +Y, u = 0.5 → −Z, u = 0.75 → +X.

    ``grid_shape(size)``: ``size`` = H (W = 2H) or (W, H).
    """

    name = "latlong"

    def grid_shape(self, size: int | tuple[int, int]) -> tuple[int, int]:
        if isinstance(size, tuple | list):
            w, h = int(size[0]), int(size[1])
        else:
            h = int(size)
            w = 2 * h
        return self.check_grid((h, w))

    def check_grid(self, grid_shape, path=None):
        h, w = grid2(grid_shape)
        if w != 2 * h:
            raise ShprobeError(f"a lat-long map must be 2:1 (W = 2H), got {w}x{h}", path)
        return h, w

    # separable structure ----------------------------------------------------
    @staticmethod
    def row_theta(h: int) -> NDArray[np.float64]:
        """Polar angle θ (from +Y) of each row centre, ``(H,)``: π (j + 0.5) / H.

        Parameters
        ----------
        h
            Rows.

        Returns
        -------
        ndarray of shape (H,)
            θ of each row centre.
        """
        return np.pi * (np.arange(h) + 0.5) / h

    @staticmethod
    def row_cos_theta(h: int) -> NDArray[np.float64]:
        """cos θ = ω_y of each row centre, ``(H,)``.

        Parameters
        ----------
        h
            Rows.

        Returns
        -------
        ndarray of shape (H,)
            cos θ of each row centre.
        """
        return np.cos(LatLong.row_theta(h))

    @staticmethod
    def row_sin_theta(h: int) -> NDArray[np.float64]:
        """sin θ of each row centre, ``(H,)``.

        Parameters
        ----------
        h
            Rows.

        Returns
        -------
        ndarray of shape (H,)
            sin θ of each row centre.
        """
        return np.sin(LatLong.row_theta(h))

    @staticmethod
    def row_solid_angle(h: int, w: int) -> NDArray[np.float64]:
        """Exact solid angle of ONE pixel in each row, ``(H,)``:
        (2π/W)(cos θ_top − cos θ_bottom), θ_top = π j/H. Sums (× W) to 4π.

        Parameters
        ----------
        h, w
            Rows and columns.

        Returns
        -------
        ndarray of shape (H,)
            One pixel's solid angle in each row.
        """
        edges = np.cos(np.pi * np.arange(h + 1) / h)
        return (2.0 * np.pi / w) * (edges[:-1] - edges[1:])

    @staticmethod
    def column_azimuth(w: int) -> NDArray[np.float64]:
        """Azimuth ψ = 2π u of each column centre, ``(W,)``; ω = (−sin ψ sin θ, cos θ,
        cos ψ sin θ).

        Parameters
        ----------
        w
            Columns.

        Returns
        -------
        ndarray of shape (W,)
            ψ of each column centre.
        """
        return 2.0 * np.pi * (np.arange(w) + 0.5) / w

    @staticmethod
    def column_xz(w: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(ω_x, ω_z) / sin θ of each column centre: (−sin ψ, cos ψ), each ``(W,)``.

        Parameters
        ----------
        w
            Columns.

        Returns
        -------
        tuple of ndarray, each (W,)
            −sin ψ and cos ψ.
        """
        psi = LatLong.column_azimuth(w)
        return -np.sin(psi), np.cos(psi)

    # Layout API ---------------------------------------------------------------
    def pixel_directions(self, grid_shape):
        h, w = self.check_grid(grid_shape)
        ct, st = self.row_cos_theta(h), self.row_sin_theta(h)
        cx, cz = self.column_xz(w)
        out = np.empty((h, w, 3))
        out[..., 0] = st[:, None] * cx[None, :]
        out[..., 1] = ct[:, None]
        out[..., 2] = st[:, None] * cz[None, :]
        return out

    def solid_angles(self, grid_shape):
        h, w = self.check_grid(grid_shape)
        return np.repeat(self.row_solid_angle(h, w)[:, None], w, axis=1)

    def direction_to_pixel(self, dirs, grid_shape):
        h, w = self.check_grid(grid_shape)
        d = unit(dirs)
        theta = np.arccos(np.clip(d[..., 1], -1.0, 1.0))
        psi = np.arctan2(-d[..., 0], d[..., 2]) % (2.0 * np.pi)
        return np.stack([psi / (2.0 * np.pi) * w, theta / np.pi * h], axis=-1)

    def sample(self, radiance, dirs):
        img = np.asarray(radiance)
        xy = self.direction_to_pixel(dirs, img.shape[:2])
        return bilinear(img, xy[..., 0], xy[..., 1], wrap_x=True)
