"""A ball in a photograph: the camera model, and the normals, reflected directions and solid
angles of the ball's pixels (the fits are `shprobe.fitting.ball`'s).

Frame: the camera's. It looks along −Z with +Y up and +X to the right of the image (the
renderer's camera at azimuth 0, elevation 0, and the mirror-ball layout's frame), so the
coefficients are world coefficients when the world's +Y is the photo's up and the camera
looks along −Z.

Camera models (``BallCamera``): ``orthographic`` — every pixel looks along −Z, the ball's
normal at image offset (a, b) (in ball radii, b up) is (a, b, √(1 − a² − b²)); ``perspective``
with the vertical field of view of the whole image — the ball's centre lies on the ray
through the circle's centre and its angular radius is the mean angle from that ray to the
rays through the four extreme points of the circle (exact for a ball at the image centre,
whose outline is then a circle; off-centre the true outline is an ellipse).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..scene.camera import MIN_FOV
from .circle import Circle, check_circle

__all__ = ["BallCamera", "BallPixels", "ball_pixels", "parse_ball_camera"]


@dataclass(frozen=True)
class BallCamera:
    """``projection`` "orthographic" or "perspective"; ``fov``: vertical field of view of the
    whole image in degrees (perspective only).

    Parameters
    ----------
    projection
        "orthographic" or "perspective".
    fov
        The whole image's vertical field of view, degrees (perspective only).
    """

    projection: str = "orthographic"
    fov: float | None = None

    def __post_init__(self) -> None:
        if self.projection not in ("orthographic", "perspective"):
            raise ShprobeError(f"camera must be orthographic or perspective:FOV, got "
                               f"{self.projection!r}")
        if self.projection == "perspective" and not (
                self.fov is not None and MIN_FOV <= self.fov < 180.0):
            raise ShprobeError(f"perspective field of view must be in [{MIN_FOV:g}, 180) "
                               f"degrees, got {self.fov} (orthographic is the limit of a "
                               "narrow one)")

    def __str__(self) -> str:
        return self.projection if self.projection == "orthographic" else \
            f"perspective:{self.fov:g}"


def parse_ball_camera(text: str) -> BallCamera:
    """``orthographic`` | ``perspective:FOV`` (vertical, degrees) →
    [`BallCamera`][shprobe.fitting.BallCamera].

    Parameters
    ----------
    text
        "orthographic" or "perspective:FOV" (vertical, degrees).

    Returns
    -------
    BallCamera
        The camera.
    """
    t = text.strip().lower()
    if t in ("orthographic", "ortho"):
        return BallCamera("orthographic")
    if t.startswith("perspective"):
        _, _, fov = t.partition(":")
        try:
            value = float(fov)
        except ValueError:
            pass
        else:
            return BallCamera("perspective", value)
    raise ShprobeError(f"cannot parse camera {text!r}: expected orthographic or "
                       "perspective:FOV (vertical field of view in degrees)")


@dataclass(repr=False)
class BallPixels:
    """The pixels of the ball: ``rows``, ``cols`` (P,) indices; ``normals`` (P, 3) unit;
    ``view`` (P, 3) unit direction from the ball towards the camera; ``reflect`` (P, 3) the
    mirror direction 2(n·v)n − v; ``solid_angle`` (P,) dω of the reflected directions over
    the pixel (|∂ω/∂x × ∂ω/∂y|, central differences); ``axis``: unit direction from the ball
    towards the camera at its centre (the blind spot lies around −axis).

    Attributes
    ----------
    rows, cols
        (P,) pixel indices.
    normals
        (P, 3) unit normals.
    view
        (P, 3) unit directions from the ball towards the camera.
    reflect
        (P, 3) mirror directions 2(n·v)n − v.
    solid_angle
        (P,) dω of the reflected directions over each pixel.
    axis
        The unit direction from the ball's centre towards the camera.
    shape
        The image's (H, W).
    """

    rows: NDArray[np.intp]
    cols: NDArray[np.intp]
    normals: NDArray[np.float64]
    view: NDArray[np.float64]
    reflect: NDArray[np.float64]
    solid_angle: NDArray[np.float64]
    axis: NDArray[np.float64]
    shape: tuple[int, int]

    def __repr__(self) -> str:
        return f"BallPixels({self.rows.size} pixels of {self.shape[1]}x{self.shape[0]})"


def _rays(camera: BallCamera, x: NDArray, y: NDArray, shape: tuple[int, int]) -> NDArray:
    H, W = shape
    f = (H / 2.0) / np.tan(np.radians(camera.fov) / 2.0)
    d = np.stack([(x - W / 2.0) / f, -(y - H / 2.0) / f, -np.ones_like(x)], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _geometry(circle: Circle, camera: BallCamera, x: NDArray, y: NDArray,
              shape: tuple[int, int]) -> tuple[NDArray, NDArray, NDArray]:
    """(inside (P,), normals (P, 3), view (P, 3)) at continuous pixel positions."""
    if camera.projection == "orthographic":
        a = (x - circle.cx) / circle.r
        b = -(y - circle.cy) / circle.r
        q = 1.0 - a * a - b * b
        inside = q > 0
        n = np.stack([a, b, np.sqrt(np.maximum(q, 0.0))], axis=-1)
        v = np.broadcast_to(np.array([0.0, 0.0, 1.0]), n.shape)
        return inside, n, v
    c = _rays(camera, np.array([circle.cx]), np.array([circle.cy]), shape)[0]
    ex = np.array([circle.cx + circle.r, circle.cx - circle.r, circle.cx, circle.cx])
    ey = np.array([circle.cy, circle.cy, circle.cy + circle.r, circle.cy - circle.r])
    alpha = float(np.mean(np.arccos(np.clip(_rays(camera, ex, ey, shape) @ c, -1, 1))))
    R = np.sin(alpha)  # ball of radius sin α at unit distance along c
    d = _rays(camera, x, y, shape)
    dc = d @ c
    disc = dc * dc - 1.0 + R * R
    inside = disc > 0
    t = dc - np.sqrt(np.maximum(disc, 0.0))
    n = (t[..., None] * d - c) / R
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return inside, n, -d


def _reflect(n: NDArray, v: NDArray) -> NDArray:
    return 2.0 * np.sum(n * v, axis=-1, keepdims=True) * n - v


def ball_pixels(circle: Circle, shape: tuple[int, int], camera: BallCamera | None = None,
                inset: float = 0.0, mirror: bool = True) -> BallPixels:
    """Pixels whose centre lies on the ball more than ``inset`` pixels inside its outline.
    ``mirror`` False skips the reflected directions' solid angles (zeros; a grey ball needs
    only the normals).

    Parameters
    ----------
    circle
        The ball's outline.
    shape
        The image's (H, W).
    camera
        The camera (default: orthographic).
    inset
        Pixels within this many pixels of the outline are left out.
    mirror
        Compute the reflected directions' solid angles (a chrome ball).

    Returns
    -------
    BallPixels
        The pixels, their normals and, for a mirror, reflected directions and solid angles.
    """
    camera = camera or BallCamera()
    H, W = shape[:2]
    circle = check_circle(circle, shape)
    if not (np.isfinite(inset) and inset >= 0):
        raise ShprobeError(f"rim inset must be a non-negative number of pixels, got {inset}")
    if inset >= circle.r:
        raise ShprobeError(f"rim inset {inset} px leaves nothing of a ball of radius "
                           f"{circle.r:.1f} px")
    x0, x1 = int(np.floor(circle.cx - circle.r)), int(np.ceil(circle.cx + circle.r))
    y0, y1 = int(np.floor(circle.cy - circle.r)), int(np.ceil(circle.cy + circle.r))
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
    shrunk = Circle(circle.cx, circle.cy, circle.r - inset)
    if camera.projection == "orthographic":  # inside test without building the normals
        dy2 = (np.arange(y0, y1) + 0.5 - circle.cy) ** 2
        dx2 = (np.arange(x0, x1) + 0.5 - circle.cx) ** 2
        jj, ii = np.nonzero(dy2[:, None] + dx2[None, :] < shrunk.r ** 2)
        jj, ii = jj + y0, ii + x0
        x, y = ii + 0.5, jj + 0.5
    else:
        jj, ii = np.mgrid[y0:y1, x0:x1]
        jj, ii = jj.ravel(), ii.ravel()
        x, y = ii + 0.5, jj + 0.5
        inside, _, _ = _geometry(shrunk, camera, x, y, (H, W))
        x, y, jj, ii = x[inside], y[inside], jj[inside], ii[inside]
    _, n, v = _geometry(circle, camera, x, y, (H, W))
    refl = _reflect(n, v)
    # solid angle of the reflected directions over the pixel: central differences
    dw = np.zeros(x.size)
    h = 0.25
    pts = []
    for dx, dy in ((h, 0.0), (-h, 0.0), (0.0, h), (0.0, -h)) if mirror else ():
        _, nn, vv = _geometry(circle, camera, x + dx, y + dy, (H, W))
        pts.append(_reflect(nn, vv))
    if mirror:
        wx = (pts[0] - pts[1]) / (2 * h)
        wy = (pts[2] - pts[3]) / (2 * h)
        dw = np.linalg.norm(np.cross(wx, wy), axis=-1)
    _, _, vc = _geometry(circle, camera, np.array([circle.cx]), np.array([circle.cy]),
                          (H, W))
    return BallPixels(jj, ii, n, v, refl, dw, vc[0].copy(), (H, W))
