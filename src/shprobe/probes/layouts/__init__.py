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
    [`LatLong.row_cos_theta`][shprobe.probes.layouts.LatLong.row_cos_theta],
    [`LatLong.row_solid_angle`][shprobe.probes.layouts.LatLong.row_solid_angle],
    [`LatLong.column_azimuth`][shprobe.probes.layouts.LatLong.column_azimuth].

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

Auto-detection ([`detect_layout`][shprobe.probes.layouts.detect_layout]): 2:1 → latlong, square →
angular, 4:3 / 3:4 → cube cross, 6:1 / 1:6 → cube strip; the mirror ball only when asked for.

The modules: `shprobe.probes.layouts.base` (the ``Layout`` interface),
`shprobe.probes.layouts.latlong`, `shprobe.probes.layouts.disc` (angular map, mirror ball),
`shprobe.probes.layouts.cube`; this module holds the registry
([`get_layout`][shprobe.probes.layouts.get_layout],
[`detect_layout`][shprobe.probes.layouts.detect_layout]). Images in a layout are
[`shprobe.probes.env.Env`][shprobe.probes.env.Env].
"""

from __future__ import annotations

import os
from collections.abc import Sequence

from ...errors import ShprobeError
from .base import Layout
from .cube import CUBE_ARRANGEMENTS, CUBE_AXES, CUBE_FACES, Cube, cube_arrangement
from .disc import Angular, MirrorBall
from .latlong import LatLong

LAYOUT_NAMES = ("latlong", "angular", "mirrorball", "cube")

CUBE = Cube()
LAYOUTS: dict[str, Layout] = {
    "latlong": LatLong(), "angular": Angular(), "mirrorball": MirrorBall(), "cube": CUBE}


def get_layout(name: str | Layout) -> Layout:
    """The layout object of a name (or the object itself).

    Parameters
    ----------
    name
        A layout's name ('latlong', 'angular', 'mirrorball', 'cube') or a Layout.

    Returns
    -------
    Layout
        The layout object.
    """
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
    4:3 / 3:4 / 6:1 / 1:6 → cube.

    Parameters
    ----------
    image_shape
        (H, W[, C]).
    path
        The file, named in the error when no layout fits.

    Returns
    -------
    str
        The layout's name.
    """
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


__all__ = [
    "CUBE",
    "CUBE_ARRANGEMENTS",
    "CUBE_AXES",
    "CUBE_FACES",
    "LAYOUTS",
    "LAYOUT_NAMES",
    "Angular",
    "Cube",
    "LatLong",
    "Layout",
    "MirrorBall",
    "cube_arrangement",
    "detect_layout",
    "get_layout",
]
