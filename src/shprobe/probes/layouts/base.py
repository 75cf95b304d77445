"""The layout interface every image parameterisation of the sphere implements, and the helpers
they share (unit vectors, bilinear lookup, 2-D grids). Conventions: the package docstring."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...errors import ShprobeError


class Layout:
    """A parameterisation of the sphere by an image grid (see the module docstring).

    Subclasses implement ``pixel_directions``, ``solid_angles``, ``direction_to_pixel``,
    ``sample`` and ``grid_shape``; ``grid`` is (H, W), or (6, N, N) for cube maps.
    """

    name: str = ""

    def grid_shape(self, size: int | tuple[int, int]) -> tuple[int, ...]:
        """Grid for a size argument (see each layout).

        Parameters
        ----------
        size
            The layout's size argument.

        Returns
        -------
        tuple of int
            The grid's shape.
        """
        raise NotImplementedError

    def check_grid(self, grid_shape: Sequence[int], path: str | os.PathLike[str] | None = None
                   ) -> tuple[int, ...]:
        """Validate a grid shape for this layout (wrong aspect → ShprobeError).

        Parameters
        ----------
        grid_shape
            A grid shape.
        path
            The file, named in the error.

        Returns
        -------
        tuple of int
            The shape, checked.
        """
        raise NotImplementedError

    def pixel_directions(self, grid_shape: Sequence[int]) -> NDArray[np.float64]:
        """Unit vectors of the pixel centres, ``(*grid, 3)`` (zero vectors where invalid).
        Disc layouts return a cached read-only array: copy before writing.

        Parameters
        ----------
        grid_shape
            The grid's shape.

        Returns
        -------
        ndarray of shape (*grid, 3)
            The pixel centres' directions.
        """
        raise NotImplementedError

    def solid_angles(self, grid_shape: Sequence[int]) -> NDArray[np.float64]:
        """Exact solid angle of each pixel, ``(*grid,)``; 0 where invalid; sums to 4π.
        Disc layouts return a cached read-only array: copy before writing.

        Parameters
        ----------
        grid_shape
            The grid's shape.

        Returns
        -------
        ndarray of shape (*grid,)
            Each pixel's solid angle.
        """
        raise NotImplementedError

    def valid_mask(self, grid_shape: Sequence[int]) -> NDArray[np.bool_]:
        """Pixels that see some direction (solid angle > 0).

        Parameters
        ----------
        grid_shape
            The grid's shape.

        Returns
        -------
        ndarray of bool, shape (*grid,)
            The pixels that see a direction.
        """
        return self.solid_angles(grid_shape) > 0

    def direction_to_pixel(self, dirs: ArrayLike, grid_shape: Sequence[int]) -> NDArray:
        """Continuous pixel coordinates (x = column, y = row; pixel (i, j) centre at
        (i+0.5, j+0.5)) of directions ``(..., 3)`` → ``(..., 2)``; cube maps: (face, x, y).

        Parameters
        ----------
        dirs
            (..., 3) directions.
        grid_shape
            The grid's shape.

        Returns
        -------
        ndarray of shape (..., 2) or (..., 3)
            Continuous pixel coordinates (cube maps: face, x, y).
        """
        raise NotImplementedError

    def sample(self, radiance: ArrayLike, dirs: ArrayLike) -> NDArray[np.float32]:
        """Bilinear lookup of a map ``(*grid, C)`` in directions ``(..., 3)`` → ``(..., C)``.

        Parameters
        ----------
        radiance
            (*grid, C) map.
        dirs
            (..., 3) directions.

        Returns
        -------
        ndarray of shape (..., C), float32
            The bilinear lookups.
        """
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def unit(dirs: ArrayLike) -> NDArray[np.float64]:
    """Directions as unit vectors (zero vectors stay zero): `shprobe.sh.rotation.unit_vectors`, the
    one normalisation."""
    from ...sh.rotation import unit_vectors

    return unit_vectors(dirs, "directions", zero="keep")


def bilinear(img: NDArray, x: NDArray, y: NDArray, wrap_x: bool) -> NDArray[np.float32]:
    """Bilinear lookup at continuous pixel coords (centres at +0.5); y clamped, x wrapped or
    clamped. ``img`` is (H, W, C); float32 out (float64 for a float64 image)."""
    h, w = img.shape[:2]
    fx = x - 0.5
    fy = np.clip(y - 0.5, 0.0, h - 1.0)
    y0 = np.floor(fy).astype(np.int64)
    y1 = np.minimum(y0 + 1, h - 1)
    ty = (fy - y0)[..., None]
    if wrap_x:
        x0f = np.floor(fx)
        tx = (fx - x0f)[..., None]
        x0 = x0f.astype(np.int64) % w
        x1 = (x0 + 1) % w
    else:
        fx = np.clip(fx, 0.0, w - 1.0)
        x0 = np.floor(fx).astype(np.int64)
        x1 = np.minimum(x0 + 1, w - 1)
        tx = (fx - x0)[..., None]
    top = img[y0, x0] * (1 - tx) + img[y0, x1] * tx
    bot = img[y1, x0] * (1 - tx) + img[y1, x1] * tx
    return (top * (1 - ty) + bot * ty).astype(np.promote_types(img.dtype, np.float32))


def grid2(grid_shape: Sequence[int]) -> tuple[int, int]:
    if len(grid_shape) != 2:
        raise ShprobeError(f"expected an (H, W) grid, got {tuple(grid_shape)}")
    h, w = int(grid_shape[0]), int(grid_shape[1])
    if h <= 0 or w <= 0:
        raise ShprobeError("image has zero size")
    return h, w
