"""An environment map as data: [`Env`][shprobe.probes.env.Env] (linear RGB radiance on the grid of a
layout), built from an image or a function, read from and written to image files."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from .images import read_image, write_image
from .layouts import CUBE, Layout, detect_layout, get_layout


@dataclass(frozen=True)
class Env:
    """An environment map: linear RGB radiance on the grid of a layout.

    ``radiance`` is ``(*grid, 3)`` float32 with grid (H, W), or (6, N, N) for cube maps.

    Parameters
    ----------
    radiance
        ``(*grid, 3)`` float32 linear radiance.
    layout
        The layout (directions and exact solid angles of the grid).
    path
        The file it was read from, named in errors.
    """

    radiance: NDArray[np.float32]
    layout: Layout
    path: str | None = None
    _grid: tuple[int, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        kind = getattr(self.radiance, "dtype", np.asarray(self.radiance).dtype).kind
        if kind not in "fiub":  # object, string or complex: no radiance (not NaN)
            raise ShprobeError(f"radiance must be real numbers, got an array of "
                               f"{np.asarray(self.radiance).dtype}", self.path)
        rad = np.asarray(self.radiance, dtype=np.float32)
        if rad.ndim < 3 or rad.shape[-1] != 3:
            raise ShprobeError(f"radiance must be (*grid, 3), got {rad.shape}", self.path)
        lay = get_layout(self.layout)
        grid = lay.check_grid(rad.shape[:-1], self.path)
        object.__setattr__(self, "radiance", rad)
        object.__setattr__(self, "layout", lay)
        object.__setattr__(self, "_grid", tuple(grid))

    @property
    def grid(self) -> tuple[int, ...]:
        """Grid shape: (H, W) or (6, N, N)."""
        return self._grid

    def directions(self) -> NDArray[np.float64]:
        """Unit vectors of the pixel centres, ``(*grid, 3)``.

        Returns
        -------
        ndarray of shape (*grid, 3)
            The pixel centres' directions.
        """
        return self.layout.pixel_directions(self._grid)

    def rotated(self, rotation: ArrayLike) -> Env:
        """The environment turned by ``rotation`` (anything
        [`shprobe.sh.rotation.one_rotation`][shprobe.sh.rotation.one_rotation] takes): L'(ω) =
        L(Rᵀω), resampled bilinearly on this grid (the map-space counterpart of rotating its SH
        coefficients).

        Parameters
        ----------
        rotation
            A matrix, a (w, x, y, z) quaternion or a scipy ``Rotation``.

        Returns
        -------
        Env
            The turned environment on the same grid.
        """
        from ..sh.rotation import one_rotation

        R = one_rotation(rotation)
        valid = self.layout.valid_mask(self.grid)
        out = np.zeros_like(self.radiance)
        out[valid] = self.layout.sample(self.radiance, self.directions()[valid] @ R)
        return Env(out, self.layout, self.path)

    def solid_angles(self) -> NDArray[np.float64]:
        """Exact per-pixel solid angle ``(*grid,)``, 0 where invalid.

        Returns
        -------
        ndarray of shape (*grid,)
            The pixels' solid angles.
        """
        return self.layout.solid_angles(self._grid)

    def samples(self) -> tuple[NDArray[np.float64], NDArray[np.float32], NDArray[np.float64]]:
        """Valid pixels only: (dirs (S, 3), radiance (S, 3), dω (S,)).

        Returns
        -------
        tuple
            dirs (S, 3), radiance (S, 3), dω (S,) of the valid pixels.
        """
        dw = self.solid_angles()
        mask = dw > 0
        return self.directions()[mask], self.radiance[mask], dw[mask]

    def sample(self, dirs: ArrayLike) -> NDArray[np.float32]:
        """Bilinear radiance lookup in directions ``(..., 3)`` → ``(..., 3)``.

        Parameters
        ----------
        dirs
            (..., 3) directions.

        Returns
        -------
        ndarray of shape (..., 3), float32
            The radiance there.
        """
        return self.layout.sample(self.radiance, dirs)

    def __repr__(self) -> str:
        """Short: layout, grid, dtype, path and ∫L dω per channel (not the pixels).

        Returns
        -------
        str
            The summary.
        """
        grid = "x".join(map(str, self._grid[::-1] if len(self._grid) == 2 else self._grid))
        rad = self.radiance.reshape(-1, self.radiance.shape[-1])
        total = self.solid_angles().reshape(-1) @ rad.astype(np.float64)
        path = f", path={self.path!r}" if self.path else ""
        return (f"Env({self.layout.name} {grid}, {self.radiance.dtype}{path}, "
                f"∫L dω=({', '.join(f'{v:.4g}' for v in total)}))")


def load_env(path: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
             layout: str | Layout | None = None, clamp: bool = False) -> Env:
    """Read an environment map (see
    [`shprobe.probes.images.read_image`][shprobe.probes.images.read_image]) in a layout.

    ``layout`` None / 'auto' detects it from the shape
    ([`detect_layout`][shprobe.probes.layouts.detect_layout]); a requested layout whose aspect does
    not fit is a one-line ShprobeError naming the file. A sequence of six paths is a cube map given
    as six face images, in the order +X −X +Y −Y +Z −Z.

    The whole image is decoded into memory. For probes too big for that, the streaming
    entry points are `shprobe.lighting.projection.project_file` (SH coefficients of a
    lat-long or cube file, read a block of rows at a time: what a lazy ``load_env`` would be
    used for) and `shprobe.probes.streaming.ImageRows` (your own pass over the rows).

    Parameters
    ----------
    path
        An image file, or six face files (+X −X +Y −Y +Z −Z) of a cube map.
    layout
        The layout's name or object; None or 'auto' detects it from the image's shape.
    clamp
        Clamp NaN, infinite and negative pixels to 0 instead of refusing them.

    Returns
    -------
    Env
        The radiance with its layout (directions and exact solid angles).
    """
    if isinstance(path, list | tuple):
        return load_cube_faces(path, clamp=clamp)
    _check_path(path)
    img = read_image(path, clamp=clamp)
    name = None if layout in (None, "auto") else layout
    lay = get_layout(name if name is not None else detect_layout(img.shape, path))
    return env_from_image(img, lay, path=os.fspath(path))


def _check_path(path: object) -> None:
    """A file path (str or os.PathLike), or one line saying what was given instead."""
    if not isinstance(path, str | os.PathLike):
        raise ShprobeError("an environment map is a file path (or six face paths), got "
                           f"{type(path).__name__} {str(path)[:60]!r}")


def load_cube_faces(paths: Sequence[str | os.PathLike[str]], clamp: bool = False) -> Env:
    """A cube map from six square face images, in the order +X −X +Y −Y +Z −Z.

    Parameters
    ----------
    paths
        Six square face images, +X −X +Y −Y +Z −Z.
    clamp
        Clamp NaN, infinite and negative pixels to 0 instead of refusing them.

    Returns
    -------
    Env
        The cube map.
    """
    paths = list(paths)
    if len(paths) != 6:
        raise ShprobeError(f"a cube map needs 6 face images (+X -X +Y -Y +Z -Z), got "
                           f"{len(paths)}")
    faces = []
    for p in paths:
        _check_path(p)
        img = read_image(p, clamp=clamp)
        if img.shape[0] != img.shape[1] or (faces and img.shape != faces[0].shape):
            raise ShprobeError(f"cube faces must be square and all the same size, got "
                               f"{img.shape[1]}x{img.shape[0]}", p)
        faces.append(img)
    return Env(np.stack(faces), CUBE, os.fspath(paths[0]))


def env_from_image(img: ArrayLike, layout: str | Layout,
                   path: str | os.PathLike[str] | None = None) -> Env:
    """Wrap an (H, W, 3) image as an Env in ``layout`` (cube files are cut into faces).

    Parameters
    ----------
    img
        (H, W, 3) linear image.
    layout
        The layout's name or object.
    path
        The file it came from, named in errors.

    Returns
    -------
    Env
        The image as an environment map.
    """
    lay = get_layout(layout)
    a = np.asarray(img, dtype=np.float32)
    p = None if path is None else os.fspath(path)
    to_grid = getattr(lay, "image_to_grid", None)
    if to_grid is not None:
        a = to_grid(a, p)
    return Env(a, lay, p)


def env_from_function(fn: Callable[[NDArray[np.float64]], ArrayLike], layout: str | Layout,
                      size: int | tuple[int, int]) -> Env:
    """A synthetic Env: ``fn(dirs (..., 3)) -> (..., 3)`` evaluated at the pixel centres.

    ``size``: lat-long H or (W, H); angular / mirror ball N; cube face size N. Invalid pixels
    (outside the disc) are 0.

    Parameters
    ----------
    fn
        Maps (..., 3) directions to (..., 3) radiance.
    layout
        The layout's name or object.
    size
        Lat-long H or (W, H); angular / mirror ball N; cube face N.

    Returns
    -------
    Env
        ``fn`` at the pixel centres (0 outside a disc layout's circle).
    """
    lay = get_layout(layout)
    grid = lay.grid_shape(size)
    dirs = lay.pixel_directions(grid)
    valid = lay.valid_mask(grid)
    rad = np.zeros((*grid, 3), dtype=np.float32)
    vals = np.asarray(fn(dirs[valid]), dtype=np.float64)
    rad[valid] = np.broadcast_to(vals, (int(valid.sum()), 3))
    return Env(rad, lay)


def write_env(path: str | os.PathLike[str], env_or_radiance: Env | ArrayLike,
              layout: str | Layout | None = None, overwrite: bool = False,
              exposure: float = 0.0, arrangement: str = "hcross") -> Path:
    """Write an Env (or a radiance grid in ``layout``) as an image file.

    Cube maps are written as ``arrangement``: 'hcross' (4:3), 'vcross' (3:4), 'hstrip' (6:1)
    or 'vstrip' (1:6). See [`shprobe.probes.images.write_image`][shprobe.probes.images.write_image]
    for formats and ``exposure``.

    Parameters
    ----------
    path
        The output file; its suffix picks the format.
    env_or_radiance
        An Env, or a radiance grid in ``layout``.
    layout
        The grid's layout (for a bare radiance grid).
    overwrite
        Replace an existing file.
    exposure
        Stops applied before tone mapping (PNG / JPEG only).
    arrangement
        A cube map's arrangement: 'hcross', 'vcross', 'hstrip' or 'vstrip'.

    Returns
    -------
    Path
        The file written.
    """
    if isinstance(path, Env) or not isinstance(path, str | os.PathLike):
        raise ShprobeError("write_env(path, env): the first argument is the file to write, "
                           f"got {type(path).__name__}"
                           + (" (arguments swapped?)" if isinstance(env_or_radiance,
                                                                    str | os.PathLike) else ""))
    if isinstance(env_or_radiance, Env):
        rad, lay = env_or_radiance.radiance, env_or_radiance.layout
    else:
        if layout is None:
            raise ShprobeError("write_env needs a layout for a bare radiance array", path)
        rad, lay = np.asarray(env_or_radiance, dtype=np.float32), get_layout(layout)
        lay.check_grid(rad.shape[:-1], path)
    to_image = getattr(lay, "grid_to_image", None)
    img = to_image(rad, arrangement) if to_image is not None else rad
    return write_image(path, img, overwrite=overwrite, exposure=exposure)


__all__ = ["Env", "env_from_function", "env_from_image", "load_cube_faces", "load_env", "write_env"]
