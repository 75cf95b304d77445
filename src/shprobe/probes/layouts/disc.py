"""The disc layouts: the angular map (Debevec light probe) and the mirror ball, with exact pixel
solid angles (Gauss quadrature; the mirror ball in closed form). Conventions:
`shprobe.probes.layouts`."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ...errors import ShprobeError
from .base import Layout, bilinear, grid2, unit


def _gauss(n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gauss–Legendre nodes and weights on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


class _Disc(Layout):
    """Square N × N image of a disc: a = 2u − 1, b = 1 − 2v, r = √(a²+b²), φ = atan2(b, a);
    direction ω = (sin θ cos φ, sin θ sin φ, cos θ) with θ = theta(r); dω = jac(r) da db."""

    def grid_shape(self, size):
        n = int(size[0]) if isinstance(size, tuple | list) else int(size)
        return self.check_grid((n, n))

    def check_grid(self, grid_shape, path=None):
        h, w = grid2(grid_shape)
        if h != w:
            raise ShprobeError(f"{self.label} must be square, got {w}x{h}", path)
        return h, w

    label = "a disc map"

    #: radial map of the numba table kernel (0: angular, 1: mirror ball)
    kind = -1

    # the radial map, vectorised over r in [0, 1]
    def theta(self, r: NDArray[np.float64]) -> NDArray[np.float64]:
        raise NotImplementedError

    def radius(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        raise NotImplementedError

    def pixel_directions(self, grid_shape):
        n, _ = self.check_grid(grid_shape)
        return _disc_tables(self, n)[1]

    def solid_angles(self, grid_shape):
        n, _ = self.check_grid(grid_shape)
        return _disc_tables(self, n)[0]

    def direction_to_pixel(self, dirs, grid_shape):
        n, _ = self.check_grid(grid_shape)
        d = unit(dirs)
        th = np.arccos(np.clip(d[..., 2], -1.0, 1.0))
        r = self.radius(th)
        phi = np.arctan2(d[..., 1], d[..., 0])
        a, b = r * np.cos(phi), r * np.sin(phi)
        return np.stack([(a + 1.0) * 0.5 * n, (1.0 - b) * 0.5 * n], axis=-1)

    def sample(self, radiance, dirs):
        img = np.asarray(radiance)
        xy = self.direction_to_pixel(dirs, img.shape[:2])
        return bilinear(img, xy[..., 0], xy[..., 1], wrap_x=False)

    def _exact_solid_angles(self, n: int) -> NDArray[np.float64] | None:
        """Closed-form pixel solid angles (N, N), where the radial map has them."""
        return None


@lru_cache(maxsize=8)
def _disc_tables(layout: _Disc, n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(solid angles (N, N), directions (N, N, 3)) of a disc layout, read-only, cached.

    Solid angles are ∫∫ jac(r) da db over each pixel ∩ disc, jac = dω / (da db): closed form
    where the layout has one, else tensor Gauss–Legendre inside the disc (order 8 → 3 as N
    grows) and, for pixels cut by the rim, a quadrature clipped to the disc. Directions are
    the pixel centres', except rim pixels whose centre lies outside the disc, which look along
    their mean direction. Pixels outside the disc: 0 and (0, 0, 0). One quadrant is computed
    and mirrored (numba, `shprobe.probes.layouts._kernels.disc_tables`).
    """
    from ._kernels import disc_tables  # numba, imported lazily

    q = 8 if n <= 16 else 6 if n <= 64 else 4 if n <= 512 else 3
    exact = layout._exact_solid_angles(n)
    omega, dirs = disc_tables(layout.kind, n, np.zeros((0, 0)) if exact is None else exact,
                              *_gauss(q), *_gauss(16), *_gauss(6))
    omega.flags.writeable = False
    dirs.flags.writeable = False
    return omega, dirs


class Angular(_Disc):
    """Angular map (Debevec light probe, R&H Fig. 3): θ = π r, centre +Z, rim −Z."""

    name = "angular"
    label = "an angular map"
    kind = 0  # jac: dω = sin θ dθ dφ = π sin(πr)/r · r dr dφ

    def theta(self, r):
        return np.pi * r

    def radius(self, theta):
        return theta / np.pi


class MirrorBall(_Disc):
    """Chrome-ball photo (orthographic, looking along −Z): θ = 2 arcsin r, dω = 4 da db."""

    name = "mirrorball"
    label = "a mirror-ball image"

    def theta(self, r):
        return 2.0 * np.arcsin(np.clip(r, 0.0, 1.0))

    def radius(self, theta):
        return np.sin(0.5 * theta)

    kind = 1  # jac = 4

    def _exact_solid_angles(self, n):
        # 4 × area(pixel ∩ unit disc), by inclusion–exclusion of quarter-plane areas
        edges = -1.0 + 2.0 * np.arange(n + 1) / n
        s = _disc_corner_area(edges[None, :], edges[::-1][:, None])  # S(a_i, b_j), b top→bottom
        area = s[1:, 1:] - s[1:, :-1] - s[:-1, 1:] + s[:-1, :-1]
        return 4.0 * np.abs(area)


def _disc_corner_area(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """Signed area of the rectangle [0, x] × [0, y] ∩ unit disc (closed form)."""
    ax = np.minimum(np.abs(x), 1.0)
    ay = np.minimum(np.abs(y), 1.0)
    ax, ay = np.broadcast_arrays(ax, ay)

    def prim(t):  # ∫_0^t √(1 − s²) ds
        return 0.5 * (t * np.sqrt(np.clip(1.0 - t * t, 0.0, None)) + np.arcsin(t))

    xc = np.sqrt(np.clip(1.0 - ay * ay, 0.0, None))  # where the circle is at height ay
    out = np.where(ax * ax + ay * ay <= 1.0, ax * ay,
                   ay * np.minimum(xc, ax) + prim(ax) - prim(np.minimum(xc, ax)))
    return np.sign(x) * np.sign(y) * out
