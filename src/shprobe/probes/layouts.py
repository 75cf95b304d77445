"""Image parameterisations of the sphere (lat-long, angular map, mirror ball, cube maps): every
direction convention of shprobe in one module.

World frame: right-handed, **+Y up**. Pixel (column i, row j) has its centre at continuous pixel
coordinates (x, y) = (i + 0.5, j + 0.5); normalised coordinates u = x / W, v = y / H; row 0 is
the top of the image.

Lat-long (equirectangular), image W × H with W = 2H (``latlong``)
    θ = π v (from +Y), ψ = 2π u (azimuth),
    ω = (−sin ψ sin θ,  cos θ,  cos ψ sin θ).
    Row 0 = +Y, u = 0 (and 1) → +Z, u = 0.25 → −X, u = 0.5 → −Z, u = 0.75 → +X (the convention
    of Debevec's lat-long probes and ``shared/probes``). Exact pixel solid angle, the same in a
    row: (2π/W)(cos θ_top − cos θ_bottom). Row and column helpers for separable sums:
    :meth:`LatLong.row_cos_theta`, :meth:`LatLong.row_solid_angle`,
    :meth:`LatLong.column_azimuth`.

Angular map (Debevec light probe; R&H 2001 Fig. 3 caption), square N × N (``angular``)
    Normalised image coordinates a = 2u − 1 (right = +), b = 1 − 2v (up = +), r = √(a²+b²),
    φ = atan2(b, a):  θ = π r (from +Z),  ω = (sin θ cos φ, sin θ sin φ, cos θ).
    Centre = +Z, rim (r = 1) = −Z, image right = +X, image up = +Y; +X lands at half radius on
    the right. Pixels wholly outside the disc are invalid (solid angle 0). Jacobian
    dω = π sin(πr)/r da db; exact pixel solid angles by Gauss quadrature (error < 1e-12), rim
    pixels clipped to the disc, so the total is 4π.

Mirror ball (photo of a chrome sphere by an orthographic camera looking along −Z), square N × N
    (``mirrorball``; never auto-detected). Same a, b, r, φ as the angular map; the ball normal at
    r is n = (r cos φ, r sin φ, √(1−r²)), the view vector v = +Z, and the pixel sees the
    reflected direction ω = 2(n·v)n − v, i.e. θ = 2 arcsin r (from +Z) with the same φ. Centre
    reflects +Z (back towards the camera), the rim −Z; image right = +X, up = +Y. Jacobian
    dω = 4 da db (uniform!), so the exact pixel solid angle is 4 × the area of pixel ∩ disc
    (closed form).

Cube map (``cube``), grid (6, N, N), faces in order +X −X +Y −Y +Z −Z (OpenGL / DirectX cube-map
orientation). Face texel (i, j): s = (i+0.5)/N, t = (j+0.5)/N, sc = 2s−1, tc = 2t−1 (row 0 at
the top), and

    ======  ===========  =================  ============
    face    major axis   image right (sc)   image down (tc)
    ======  ===========  =================  ============
    +X      +X           −Z                 −Y
    −X      −X           +Z                 −Y
    +Y      +Y           +X                 +Z
    −Y      −Y           +X                 −Z
    +Z      +Z           +X                 −Y
    −Z      −Z           −X                 −Y
    ======  ===========  =================  ============

e.g. +X face: ω ∝ (1, −tc, −sc). Exact texel solid angle from the corner terms
A(a, b) = atan2(ab, √(a² + b² + 1)): Ω = A(a0,b0) − A(a0,b1) − A(a1,b0) + A(a1,b1).
Files: horizontal cross 4:3 (row 1: −X +Z +X −Z, +Y above and −Y below +Z), vertical cross
3:4 (+Y, then −X +Z +X, then −Y, then −Z turned by 180°), strips 6:1 and 1:6 in face order.

Auto-detection (:func:`detect_layout`): 2:1 → latlong, square → angular, 4:3 / 3:4 → cube
cross, 6:1 / 1:6 → cube strip; the mirror ball only when asked for.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError

LAYOUT_NAMES = ("latlong", "angular", "mirrorball", "cube")


# ----------------------------------------------------------------------------- base


class Layout:
    """A parameterisation of the sphere by an image grid (see the module docstring).

    Subclasses implement ``pixel_directions``, ``solid_angles``, ``direction_to_pixel``,
    ``sample`` and ``grid_shape``; ``grid`` is (H, W), or (6, N, N) for cube maps.
    """

    name: str = ""

    def grid_shape(self, size: int | tuple[int, int]) -> tuple[int, ...]:
        """Grid for a size argument (see each layout)."""
        raise NotImplementedError

    def check_grid(self, grid_shape: Sequence[int], path: str | os.PathLike[str] | None = None
                   ) -> tuple[int, ...]:
        """Validate a grid shape for this layout (wrong aspect → ShprobeError)."""
        raise NotImplementedError

    def pixel_directions(self, grid_shape: Sequence[int]) -> NDArray[np.float64]:
        """Unit vectors of the pixel centres, ``(*grid, 3)`` (zero vectors where invalid).
        Disc layouts return a cached read-only array: copy before writing."""
        raise NotImplementedError

    def solid_angles(self, grid_shape: Sequence[int]) -> NDArray[np.float64]:
        """Exact solid angle of each pixel, ``(*grid,)``; 0 where invalid; sums to 4π.
        Disc layouts return a cached read-only array: copy before writing."""
        raise NotImplementedError

    def valid_mask(self, grid_shape: Sequence[int]) -> NDArray[np.bool_]:
        """Pixels that see some direction (solid angle > 0)."""
        return self.solid_angles(grid_shape) > 0

    def direction_to_pixel(self, dirs: ArrayLike, grid_shape: Sequence[int]) -> NDArray:
        """Continuous pixel coordinates (x = column, y = row; pixel (i, j) centre at
        (i+0.5, j+0.5)) of directions ``(..., 3)`` → ``(..., 2)``; cube maps: (face, x, y)."""
        raise NotImplementedError

    def sample(self, radiance: ArrayLike, dirs: ArrayLike) -> NDArray[np.float32]:
        """Bilinear lookup of a map ``(*grid, C)`` in directions ``(..., 3)`` → ``(..., C)``."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def _unit(dirs: ArrayLike) -> NDArray[np.float64]:
    """Directions as unit vectors (zero vectors stay zero): :func:`shprobe.sh.rotation.
    unit_vectors`, the one normalisation."""
    from ..sh.rotation import unit_vectors

    return unit_vectors(dirs, "directions", zero="keep")


def _bilinear(img: NDArray, x: NDArray, y: NDArray, wrap_x: bool) -> NDArray[np.float32]:
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


def _grid2(grid_shape: Sequence[int]) -> tuple[int, int]:
    if len(grid_shape) != 2:
        raise ShprobeError(f"expected an (H, W) grid, got {tuple(grid_shape)}")
    h, w = int(grid_shape[0]), int(grid_shape[1])
    if h <= 0 or w <= 0:
        raise ShprobeError("image has zero size")
    return h, w


# ----------------------------------------------------------------------------- lat-long


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
        h, w = _grid2(grid_shape)
        if w != 2 * h:
            raise ShprobeError(f"a lat-long map must be 2:1 (W = 2H), got {w}x{h}", path)
        return h, w

    # separable structure ----------------------------------------------------
    @staticmethod
    def row_theta(h: int) -> NDArray[np.float64]:
        """Polar angle θ (from +Y) of each row centre, ``(H,)``: π (j + 0.5) / H."""
        return np.pi * (np.arange(h) + 0.5) / h

    @staticmethod
    def row_cos_theta(h: int) -> NDArray[np.float64]:
        """cos θ = ω_y of each row centre, ``(H,)``."""
        return np.cos(LatLong.row_theta(h))

    @staticmethod
    def row_sin_theta(h: int) -> NDArray[np.float64]:
        """sin θ of each row centre, ``(H,)``."""
        return np.sin(LatLong.row_theta(h))

    @staticmethod
    def row_solid_angle(h: int, w: int) -> NDArray[np.float64]:
        """Exact solid angle of ONE pixel in each row, ``(H,)``:
        (2π/W)(cos θ_top − cos θ_bottom), θ_top = π j/H. Sums (× W) to 4π."""
        edges = np.cos(np.pi * np.arange(h + 1) / h)
        return (2.0 * np.pi / w) * (edges[:-1] - edges[1:])

    @staticmethod
    def column_azimuth(w: int) -> NDArray[np.float64]:
        """Azimuth ψ = 2π u of each column centre, ``(W,)``; ω = (−sin ψ sin θ, cos θ,
        cos ψ sin θ)."""
        return 2.0 * np.pi * (np.arange(w) + 0.5) / w

    @staticmethod
    def column_xz(w: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(ω_x, ω_z) / sin θ of each column centre: (−sin ψ, cos ψ), each ``(W,)``."""
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
        d = _unit(dirs)
        theta = np.arccos(np.clip(d[..., 1], -1.0, 1.0))
        psi = np.arctan2(-d[..., 0], d[..., 2]) % (2.0 * np.pi)
        return np.stack([psi / (2.0 * np.pi) * w, theta / np.pi * h], axis=-1)

    def sample(self, radiance, dirs):
        img = np.asarray(radiance)
        xy = self.direction_to_pixel(dirs, img.shape[:2])
        return _bilinear(img, xy[..., 0], xy[..., 1], wrap_x=True)


# ----------------------------------------------------------------------------- disc maps


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
        h, w = _grid2(grid_shape)
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
        d = _unit(dirs)
        th = np.arccos(np.clip(d[..., 2], -1.0, 1.0))
        r = self.radius(th)
        phi = np.arctan2(d[..., 1], d[..., 0])
        a, b = r * np.cos(phi), r * np.sin(phi)
        return np.stack([(a + 1.0) * 0.5 * n, (1.0 - b) * 0.5 * n], axis=-1)

    def sample(self, radiance, dirs):
        img = np.asarray(radiance)
        xy = self.direction_to_pixel(dirs, img.shape[:2])
        return _bilinear(img, xy[..., 0], xy[..., 1], wrap_x=False)

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
    and mirrored (numba, :func:`shprobe._layout_kernels.disc_tables`).
    """
    from ._layout_kernels import disc_tables  # numba, imported lazily

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


# ----------------------------------------------------------------------------- cube maps

#: Face order and, per face, how (major axis, image right sc, image down tc) map to xyz:
#: ω ∝ ma·e_major + sc·e_right + tc·e_down (see the module docstring table).
CUBE_FACES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
_CUBE_AXES = np.array([
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
    vstrip 1:6."""
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
                j = int(np.argmax(np.abs(_CUBE_AXES[f, :, k])))
                np.multiply(parts[j], _CUBE_AXES[f, j, k], out=d[f, :, :, k])
        return d

    def solid_angles(self, grid_shape):
        _, n, _ = self.check_grid(grid_shape)
        e = -1.0 + 2.0 * np.arange(n + 1) / n
        a = np.arctan2(e[:, None] * e[None, :], np.sqrt(e[:, None] ** 2 + e[None, :] ** 2 + 1))
        texel = a[1:, 1:] - a[1:, :-1] - a[:-1, 1:] + a[:-1, :-1]
        return np.broadcast_to(texel, (6, n, n)).copy()

    def direction_to_pixel(self, dirs, grid_shape):
        _, n, _ = self.check_grid(grid_shape)
        d = _unit(dirs)
        ad = np.abs(d)
        axis = np.argmax(ad, axis=-1)  # 0, 1, 2
        comp = np.take_along_axis(d, axis[..., None], -1)[..., 0]
        face = 2 * axis + (comp < 0)
        ax = _CUBE_AXES[face]  # (..., 3, 3)
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
        """Cut a cross or strip image (H, W, C) into faces (6, N, N, C)."""
        name = cube_arrangement(img.shape, path)
        (fw, _), pos = CUBE_ARRANGEMENTS[name]
        n = img.shape[1] // fw
        faces = np.empty((6, n, n, img.shape[2]), dtype=np.float32)
        for k, (col, row, rot) in enumerate(pos):
            f = img[row * n:(row + 1) * n, col * n:(col + 1) * n]
            faces[k] = f[::-1, ::-1] if rot else f
        return faces

    def grid_to_image(self, faces: ArrayLike, arrangement: str = "hcross") -> NDArray[np.float32]:
        """Lay faces (6, N, N, C) out as ``arrangement`` (unused areas black)."""
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


# ----------------------------------------------------------------------------- registry


CUBE = Cube()
LAYOUTS: dict[str, Layout] = {
    "latlong": LatLong(), "angular": Angular(), "mirrorball": MirrorBall(), "cube": CUBE}


def get_layout(name: str | Layout) -> Layout:
    """The layout object of a name (or the object itself)."""
    if isinstance(name, Layout):
        return name
    key = str(name).lower().replace("-", "").replace("_", "")
    aliases = {"equirect": "latlong", "equirectangular": "latlong", "latlon": "latlong",
               "lightprobe": "angular", "probe": "angular", "ball": "mirrorball",
               "sphere": "mirrorball", "cubemap": "cube", "cross": "cube", "strip": "cube"}
    key = aliases.get(key, key)
    if key not in LAYOUTS:
        raise ShprobeError(f"unknown layout {name!r}; choose one of {', '.join(LAYOUTS)}")
    return LAYOUTS[key]


def detect_layout(image_shape: Sequence[int], path: str | os.PathLike[str] | None = None) -> str:
    """Layout name from an image shape (H, W[, C]): 2:1 → latlong, square → angular,
    4:3 / 3:4 / 6:1 / 1:6 → cube."""
    h, w = int(image_shape[0]), int(image_shape[1])
    if h <= 0 or w <= 0:
        raise ShprobeError("image has zero size", path)
    if w == 2 * h:
        return "latlong"
    if w == h:
        return "angular"
    if (3 * w == 4 * h) or (4 * w == 3 * h) or (w == 6 * h) or (h == 6 * w):
        return "cube"
    raise ShprobeError(
        f"cannot tell the layout of a {w}x{h} image (2:1 lat-long, square angular map, "
        "4:3 / 3:4 cube cross, 6:1 / 1:6 cube strip); pass --layout", path)


# ----------------------------------------------------------------------------- Env


@dataclass(frozen=True)
class Env:
    """An environment map: linear RGB radiance on the grid of a layout.

    ``radiance`` is ``(*grid, 3)`` float32 with grid (H, W), or (6, N, N) for cube maps.
    """

    radiance: NDArray[np.float32]
    layout: Layout
    path: str | None = None
    _grid: tuple[int, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
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
        """Unit vectors of the pixel centres, ``(*grid, 3)``."""
        return self.layout.pixel_directions(self._grid)

    def rotated(self, rotation: ArrayLike) -> Env:
        """The environment turned by ``rotation`` (anything
        :func:`shprobe.sh.rotation.one_rotation` takes): L'(ω) = L(Rᵀω), resampled
        bilinearly on this grid (the map-space counterpart of rotating its SH coefficients)."""
        from ..sh.rotation import one_rotation

        R = one_rotation(rotation)
        valid = self.layout.valid_mask(self.grid)
        out = np.zeros_like(self.radiance)
        out[valid] = self.layout.sample(self.radiance, self.directions()[valid] @ R)
        return Env(out, self.layout, self.path)

    def solid_angles(self) -> NDArray[np.float64]:
        """Exact per-pixel solid angle ``(*grid,)``, 0 where invalid."""
        return self.layout.solid_angles(self._grid)

    def samples(self) -> tuple[NDArray[np.float64], NDArray[np.float32], NDArray[np.float64]]:
        """Valid pixels only: (dirs (S, 3), radiance (S, 3), dω (S,))."""
        dw = self.solid_angles()
        mask = dw > 0
        return self.directions()[mask], self.radiance[mask], dw[mask]

    def sample(self, dirs: ArrayLike) -> NDArray[np.float32]:
        """Bilinear radiance lookup in directions ``(..., 3)`` → ``(..., 3)``."""
        return self.layout.sample(self.radiance, dirs)

    def __repr__(self) -> str:
        """Short: layout, grid, dtype, path and ∫L dω per channel (not the pixels)."""
        grid = "x".join(map(str, self._grid[::-1] if len(self._grid) == 2 else self._grid))
        rad = self.radiance.reshape(-1, self.radiance.shape[-1])
        total = self.solid_angles().reshape(-1) @ rad.astype(np.float64)
        path = f", path={self.path!r}" if self.path else ""
        return (f"Env({self.layout.name} {grid}, {self.radiance.dtype}{path}, "
                f"∫L dω=({', '.join(f'{v:.4g}' for v in total)}))")


def load_env(path: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
             layout: str | Layout | None = None, clamp: bool = False) -> Env:
    """Read an environment map (see :func:`shprobe.images.read_image`) in a layout.

    ``layout`` None / 'auto' detects it from the shape (:func:`detect_layout`); a requested
    layout whose aspect does not fit is a one-line ShprobeError naming the file. A sequence of
    six paths is a cube map given as six face images, in the order +X −X +Y −Y +Z −Z.

    The whole image is decoded into memory. For probes too big for that, the streaming
    entry points are :func:`shprobe.lighting.projection.project_file` (SH coefficients of a
    lat-long or cube file, read a block of rows at a time: what a lazy ``load_env`` would be
    used for) and :class:`shprobe.probes.images.ImageRows` (your own pass over the rows).
    """
    from .images import read_image

    if not isinstance(path, str | os.PathLike):
        return load_cube_faces(path, clamp=clamp)
    img = read_image(path, clamp=clamp)
    name = None if layout in (None, "auto") else layout
    lay = get_layout(name if name is not None else detect_layout(img.shape, path))
    return env_from_image(img, lay, path=os.fspath(path))


def load_cube_faces(paths: Sequence[str | os.PathLike[str]], clamp: bool = False) -> Env:
    """A cube map from six square face images, in the order +X −X +Y −Y +Z −Z."""
    from .images import read_image

    paths = list(paths)
    if len(paths) != 6:
        raise ShprobeError(f"a cube map needs 6 face images (+X -X +Y -Y +Z -Z), got "
                           f"{len(paths)}")
    faces = []
    for p in paths:
        img = read_image(p, clamp=clamp)
        if img.shape[0] != img.shape[1] or (faces and img.shape != faces[0].shape):
            raise ShprobeError(f"cube faces must be square and all the same size, got "
                               f"{img.shape[1]}x{img.shape[0]}", p)
        faces.append(img)
    return Env(np.stack(faces), CUBE, os.fspath(paths[0]))


def env_from_image(img: ArrayLike, layout: str | Layout,
                   path: str | os.PathLike[str] | None = None) -> Env:
    """Wrap an (H, W, 3) image as an Env in ``layout`` (cube files are cut into faces)."""
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
    or 'vstrip' (1:6). See :func:`shprobe.images.write_image` for formats and ``exposure``.
    """
    from .images import write_image

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


__all__ = [
    "CUBE_ARRANGEMENTS",
    "CUBE_FACES",
    "LAYOUTS",
    "LAYOUT_NAMES",
    "Angular",
    "Cube",
    "Env",
    "LatLong",
    "Layout",
    "MirrorBall",
    "cube_arrangement",
    "detect_layout",
    "env_from_function",
    "env_from_image",
    "get_layout",
    "load_cube_faces",
    "load_env",
    "write_env",
]

