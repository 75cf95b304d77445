"""The cube-map layout: six faces (OpenGL / DirectX orientation), exact texel solid angles, and
the file arrangements (crosses and strips). Conventions: `shprobe.probes.layouts`."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...errors import ShprobeError
from .base import Layout, unit

#: Face order and, per face, how (major axis, image right sc, image down tc) map to xyz:
#: ω ∝ ma·e_major + sc·e_right + tc·e_down (see the module docstring table).
CUBE_FACES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
CUBE_AXES = np.array([
    # major         right (sc)      down (tc)
    [[1, 0, 0], [0, 0, -1], [0, -1, 0]],   # +X
    [[-1, 0, 0], [0, 0, 1], [0, -1, 0]],   # -X
    [[0, 1, 0], [1, 0, 0], [0, 0, 1]],     # +Y
    [[0, -1, 0], [1, 0, 0], [0, 0, -1]],   # -Y
    [[0, 0, 1], [1, 0, 0], [0, -1, 0]],    # +Z
    [[0, 0, -1], [-1, 0, 0], [0, -1, 0]],  # -Z
], dtype=np.float64)

#: Face positions (column, row) in units of the face size, and whether the face is turned 180°.
CUBE_ARRANGEMENTS: dict[str, tuple[tuple[int, int], tuple[tuple[int, int, bool], ...]]] = {
    # name: ((width, height) in faces, per face (col, row, rotated))
    "hcross": ((4, 3), ((2, 1, False), (0, 1, False), (1, 0, False), (1, 2, False),
                        (1, 1, False), (3, 1, False))),
    "vcross": ((3, 4), ((2, 1, False), (0, 1, False), (1, 0, False), (1, 2, False),
                        (1, 1, False), (1, 3, True))),
    "hstrip": ((6, 1), tuple((k, 0, False) for k in range(6))),
    "vstrip": ((1, 6), tuple((0, k, False) for k in range(6))),
}


def cube_arrangement(image_shape: Sequence[int], path=None) -> str:
    """Which cube arrangement an (H, W) image is: hcross 4:3, vcross 3:4, hstrip 6:1,
    vstrip 1:6.

    Parameters
    ----------
    image_shape
        (H, W[, C]).
    path
        The file, named in the error.

    Returns
    -------
    str
        'hcross', 'vcross', 'hstrip' or 'vstrip'.
    """
    h, w = int(image_shape[0]), int(image_shape[1])
    if h <= 0 or w <= 0:
        raise ShprobeError("image has zero size", path)
    for name, ((fw, fh), _) in CUBE_ARRANGEMENTS.items():
        if w * fh == h * fw and w % fw == 0:
            return name
    raise ShprobeError(
        f"a cube map must be a 4:3 or 3:4 cross or a 6:1 or 1:6 strip, got {w}x{h}", path)


class Cube(Layout):
    """Cube map, grid (6, N, N), faces +X −X +Y −Y +Z −Z (OpenGL / DirectX orientation)."""

    name = "cube"

    def grid_shape(self, size):
        n = int(size[0]) if isinstance(size, tuple | list) else int(size)
        return self.check_grid((6, n, n))

    def check_grid(self, grid_shape, path=None):
        g = tuple(int(v) for v in grid_shape)
        if len(g) != 3 or g[0] != 6 or g[1] != g[2]:
            raise ShprobeError(f"a cube map grid must be (6, N, N), got {g}", path)
        if g[1] <= 0:
            raise ShprobeError("image has zero size", path)
        return g

    @staticmethod
    def _face_coords(n: int) -> NDArray[np.float64]:
        return -1.0 + 2.0 * (np.arange(n) + 0.5) / n

    def pixel_directions(self, grid_shape):
        _, n, _ = self.check_grid(grid_shape)
        c = self._face_coords(n)
        # ω = (e_major + sc e_right + tc e_down) / √(1 + sc² + tc²): the norm is the same on
        # every face, and each axis is a signed unit vector, so each component is ±u, ±s or ±t
        u = 1.0 / np.sqrt(1.0 + c[None, :] ** 2 + c[:, None] ** 2)  # (row tc, column sc)
        parts = (u, c[None, :] * u, c[:, None] * u)
        d = np.empty((6, n, n, 3))
        for f in range(6):
            for k in range(3):
                j = int(np.argmax(np.abs(CUBE_AXES[f, :, k])))
                np.multiply(parts[j], CUBE_AXES[f, j, k], out=d[f, :, :, k])
        return d

    def solid_angles(self, grid_shape):
        _, n, _ = self.check_grid(grid_shape)
        e = -1.0 + 2.0 * np.arange(n + 1) / n
        a = np.arctan2(e[:, None] * e[None, :], np.sqrt(e[:, None] ** 2 + e[None, :] ** 2 + 1))
        texel = a[1:, 1:] - a[1:, :-1] - a[:-1, 1:] + a[:-1, :-1]
        return np.broadcast_to(texel, (6, n, n)).copy()

    def direction_to_pixel(self, dirs, grid_shape):
        _, n, _ = self.check_grid(grid_shape)
        d = unit(dirs)
        ad = np.abs(d)
        axis = np.argmax(ad, axis=-1)  # 0, 1, 2
        comp = np.take_along_axis(d, axis[..., None], -1)[..., 0]
        face = 2 * axis + (comp < 0)
        ax = CUBE_AXES[face]  # (..., 3, 3)
        ma = np.einsum("...c,...c->...", d, ax[..., 0, :])
        sc = np.einsum("...c,...c->...", d, ax[..., 1, :]) / ma
        tc = np.einsum("...c,...c->...", d, ax[..., 2, :]) / ma
        return np.stack([face.astype(np.float64), (sc + 1) * 0.5 * n, (tc + 1) * 0.5 * n], -1)

    def sample(self, radiance, dirs):
        img = np.asarray(radiance)
        n = img.shape[1]
        fxy = self.direction_to_pixel(dirs, img.shape[:3])
        f = fxy[..., 0].astype(np.int64)
        fx = np.clip(fxy[..., 1] - 0.5, 0.0, n - 1.0)
        fy = np.clip(fxy[..., 2] - 0.5, 0.0, n - 1.0)
        x0 = np.floor(fx).astype(np.int64)
        y0 = np.floor(fy).astype(np.int64)
        x1, y1 = np.minimum(x0 + 1, n - 1), np.minimum(y0 + 1, n - 1)
        tx, ty = (fx - x0)[..., None], (fy - y0)[..., None]
        top = img[f, y0, x0] * (1 - tx) + img[f, y0, x1] * tx
        bot = img[f, y1, x0] * (1 - tx) + img[f, y1, x1] * tx
        return (top * (1 - ty) + bot * ty).astype(np.float32)

    # files ------------------------------------------------------------------
    def image_to_grid(self, img: NDArray[np.float32], path=None) -> NDArray[np.float32]:
        """Cut a cross or strip image (H, W, C) into faces (6, N, N, C).

        Parameters
        ----------
        img
            (H, W, C) cross or strip.
        path
            The file, named in errors.

        Returns
        -------
        ndarray of shape (6, N, N, C)
            The faces.
        """
        name = cube_arrangement(img.shape, path)
        (fw, _), pos = CUBE_ARRANGEMENTS[name]
        n = img.shape[1] // fw
        faces = np.empty((6, n, n, img.shape[2]), dtype=np.float32)
        for k, (col, row, rot) in enumerate(pos):
            f = img[row * n:(row + 1) * n, col * n:(col + 1) * n]
            faces[k] = f[::-1, ::-1] if rot else f
        return faces

    def grid_to_image(self, faces: ArrayLike, arrangement: str = "hcross") -> NDArray[np.float32]:
        """Lay faces (6, N, N, C) out as ``arrangement`` (unused areas black).

        Parameters
        ----------
        faces
            (6, N, N, C) faces.
        arrangement
            'hcross', 'vcross', 'hstrip' or 'vstrip'.

        Returns
        -------
        ndarray
            The laid-out image.
        """
        faces = np.asarray(faces, dtype=np.float32)
        if arrangement not in CUBE_ARRANGEMENTS:
            raise ShprobeError(f"unknown cube arrangement {arrangement!r}; choose one of "
                               + ", ".join(CUBE_ARRANGEMENTS))
        (fw, fh), pos = CUBE_ARRANGEMENTS[arrangement]
        n = faces.shape[1]
        img = np.zeros((fh * n, fw * n, faces.shape[-1]), dtype=np.float32)
        for k, (col, row, rot) in enumerate(pos):
            img[row * n:(row + 1) * n, col * n:(col + 1) * n] = (
                faces[k][::-1, ::-1] if rot else faces[k])
        return img
