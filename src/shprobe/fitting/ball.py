"""Grey and chrome balls in photographs: the two fits (the camera model and the ball's
pixels are `shprobe.fitting.ball_geometry`'s, importable from here too).

The frame and the camera models are `shprobe.fitting.ball_geometry`'s (its module docstring).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from .ball_geometry import (  # noqa: F401  (importable from here as before)
    BallCamera,
    BallPixels,
    _geometry,
    _rays,
    _reflect,
    ball_pixels,
    parse_ball_camera,
)
from .circle import Circle, _reduce, block_extremes, check_circle, detect_circle
from .document import FitDocument
from .solve import MAX_RADIUS as _MAX_RADIUS
from .solve import FitSettings, LightingFit, check_level, fit_samples

#: Largest ball radius (px) a grey-ball fit works at; bigger balls are block-averaged.
MAX_RADIUS = _MAX_RADIUS  # the one value, from .solve

if TYPE_CHECKING:
    pass

__all__ = ["BallCamera", "BallPixels", "ball_pixels", "fit_chrome_ball", "fit_grey_ball",
           "parse_ball_camera"]


def _image(img: NDArray, path=None) -> NDArray[np.float32]:
    a = np.asarray(img, dtype=np.float32)
    if a.ndim == 2:
        a = np.repeat(a[:, :, None], 3, axis=2)
    if a.ndim != 3 or a.shape[2] < 3 or a.shape[0] < 4 or a.shape[1] < 4:
        raise ShprobeError(f"photo must be an (H, W, 3) image, got shape {a.shape}", path)
    if not np.all(np.isfinite(a[..., :3])):
        raise ShprobeError("photo has NaN or infinite pixels", path)
    return a[..., :3]


@dataclass(repr=False)
class BallFit(FitDocument):
    """A ball photo's fit: ``fit`` ([`LightingFit`][shprobe.fitting.LightingFit], coefficients in
    the camera frame), ``circle``, ``camera``, ``pixels``
    ([`BallPixels`][shprobe.fitting.BallPixels]), and for a chrome ball the blind spot:
    ``blind_angle`` (degrees, half-angle of the cone of directions around −axis that no used pixel
    reflects) and ``blind_solid_angle`` (sr).

    Attributes
    ----------
    fit
        The lighting fit, coefficients in the camera frame.
    circle
        The ball's outline.
    camera
        The camera assumed.
    pixels
        The pixels used.
    kind
        "grey" or "chrome".
    binning
        The block size the photo was averaged by (1: none).
    photo
        The (block-mean) photo fitted.
    blind_angle, blind_solid_angle
        A chrome ball's blind cone: half-angle (degrees) and solid angle (sr).
    info
        Further figures about the fit.
    """

    fit: LightingFit
    circle: Circle
    camera: BallCamera
    pixels: BallPixels
    kind: str
    binning: int = 1
    photo: NDArray[np.float32] | None = None
    blind_angle: float = 0.0
    blind_solid_angle: float = 0.0
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def coeffs(self) -> NDArray[np.float64]:
        return self.fit.coeffs

    def image(self, values: NDArray) -> NDArray[np.float32]:
        """Scatter per-pixel values (P,) or (P, C) back into a full (H, W[, C]) image (0
        off the ball).

        Parameters
        ----------
        values
            (P,) or (P, C) per-pixel values of the fit.

        Returns
        -------
        ndarray of shape (H, W) or (H, W, C), float32
            The values in their pixels, 0 off the ball.
        """
        v = np.asarray(values)
        out = np.zeros((*self.pixels.shape, *v.shape[1:]), dtype=np.float32)
        out[self.pixels.rows, self.pixels.cols] = v
        return out

    def summary(self) -> str:
        c = self.info.get("circle_full", self.circle)
        binned = f", fitted on {self.binning}x{self.binning} blocks" if self.binning > 1 else ""
        s = f"{self.kind} ball {c.text()} ({self.camera}{binned}): {self.fit.summary()}"
        if self.kind == "chrome":
            s += (f"; blind spot {self.blind_angle:.1f} deg around the view axis "
                  f"({self.blind_solid_angle:.3f} sr, "
                  f"{100 * self.blind_solid_angle / (4 * np.pi):.1f} % of the sphere)")
        return s

    def __repr__(self) -> str:
        return f"BallFit({self.kind}, {self.circle!r}, {self.fit!r})"


def _locate(img: NDArray, circle: Circle | None, path) -> Circle:
    if circle is None:
        return detect_circle(img, path)
    return check_circle(circle, img.shape, path)


def fit_grey_ball(image: NDArray, circle: Circle | None = None,
                  camera: BallCamera | None = None, settings: FitSettings | None = None, *,
                  albedo: float = 1.0, inset: float = 1.0, path=None,
                  **changes: Any) -> BallFit:
    """Nine RGB lighting coefficients from a photo of a diffuse (grey) ball (R&H 2001 §2–3).

    Parameters
    ----------
    image
        The photo (H, W, 3), linear.
    circle
        The ball's outline, or None (detected).
    camera
        The camera model (default: orthographic).
    settings
        The fit's [`FitSettings`][shprobe.fitting.FitSettings] (saturation, robust, max_radius, …).
    albedo
        The ball's albedo × exposure, by which the coefficients are divided.
    inset
        Pixels within this many pixels of the outline are left out.
    path
        The file the photo came from, for messages.
    **changes
        Fields of [`FitSettings`][shprobe.fitting.FitSettings] changed from ``settings``
        (``robust=False``).

    Returns
    -------
    BallFit
        The fit, the circle, the camera and the pixels used.

    Notes
    -----
    ``circle`` None detects the ball. Pixels whose centre lies within ``inset`` px of the
    outline (blended with the background) are left out. ``albedo``: the ball's albedo ×
    exposure, by which the coefficients are divided (1: the coefficients carry that scale).
    Only the visible part of the ball constrains the lighting; ``fit.conditioning`` says how
    well each coefficient is determined.

    A ball of radius above ``max_radius`` px (a 4k photo's) is fitted on f×f block means of
    the photo (f the smallest block that brings it under, dividing the image size): the model
    is linear in the pixel values and the normals vary by O(1/r) over a block, so the fit
    loses nothing that matters while the work drops f²-fold. The result (``circle``,
    ``pixels``, the images) is then at that resolution, ``binning`` = f and ``photo`` the
    block-mean image; ``info['circle_full']`` is the circle in the photo's pixels.
    """
    s = settings if settings is not None else FitSettings()
    if changes:
        s = replace(s, **changes)
    saturation = s.saturation
    img = _image(image, path)
    c = _locate(img, circle, path)
    cam = camera or BallCamera()
    f = _binning(c, img.shape, s.max_radius)
    work, cw, inset_w = img, c, inset
    if f > 1:  # block means; a block holding a clipped pixel stays clipped
        work = _reduce(img, f)
        hi, lo = block_extremes(img, f)
        if saturation is not None:
            work[hi >= saturation] = saturation
        work[lo <= 0.0] = 0.0
        cw = Circle(c.cx / f, c.cy / f, c.r / f, c.inliers)
        inset_w = inset / f + 0.75  # blocks straddling the outline blend with the background
    px = ball_pixels(cw, work.shape[:2], cam, inset_w, mirror=False)
    if px.rows.size < 9:
        raise ShprobeError(f"the ball covers only {px.rows.size} pixels", path)
    vals = work[px.rows, px.cols]
    if saturation is not None and np.all(np.any(vals >= saturation, axis=1)):
        raise ShprobeError("every pixel of the ball is saturated (clipped): nothing to fit",
                           path)
    fit = fit_samples(px.normals, vals, replace(s, model="diffuse", black=0.0), albedo=albedo)
    out = BallFit(fit, cw, cam, px, "grey", binning=f, photo=work if f > 1 else None)
    out.info["circle_full"] = c
    return out


def _binning(c: Circle, shape: tuple[int, ...], max_radius: float | None) -> int:
    """Block size for a ball of radius above ``max_radius`` px (one that divides the image)."""
    if not max_radius or c.r <= max_radius:
        return 1
    f = int(np.ceil(c.r / max_radius))
    while f > 1 and (shape[0] % f or shape[1] % f):
        f -= 1
    return f


def fit_chrome_ball(image: NDArray, circle: Circle | None = None,
                    camera: BallCamera | None = None, *, reflectance: float = 1.0,
                    saturation: float | None = None, inset: float = 0.5,
                    path=None) -> BallFit:
    """Nine RGB lighting coefficients from a photo of a mirror (chrome) ball.

    Every ball pixel sees the environment radiance × ``reflectance`` in the mirror direction;
    the coefficients are the least-squares fit of Σ L_lm y_lm(ω) to those samples weighted by
    their solid angles (the projection of R&H eq. 10 where the sphere is covered, a smooth
    fill of the blind spot). The blind spot: directions around −axis (behind the ball) that
    only the outermost rim reflects; pixels within ``inset`` px of the outline are left out,
    and the cone they would have covered is reported. Clipped pixels are kept (the brightest
    lights are what clip) and counted in ``info['clipped']``.

    Parameters
    ----------
    image
        (H, W, 3) linear photo of the mirror ball.
    circle
        The ball's outline in pixels; None detects it.
    camera
        The camera that took the photo (default: orthographic, looking along −Z).
    reflectance
        The mirror's reflectance × exposure.
    saturation
        Pixels with a channel at or above it are reported as clipped (and kept).
    inset
        Pixels within this many pixels of the outline are left out.
    path
        The photo's file, named in errors.

    Returns
    -------
    BallFit
        The nine RGB coefficients and the blind spot's cone.
    """
    img = _image(image, path)
    c = _locate(img, circle, path)
    cam = camera or BallCamera()
    px = ball_pixels(c, img.shape[:2], cam, inset)
    if px.rows.size < 9:
        raise ShprobeError(f"the ball covers only {px.rows.size} pixels", path)
    vals = img[px.rows, px.cols]
    clipped = 0
    check_level(saturation, "saturation")
    if saturation is not None:
        sat = np.any(vals >= saturation, axis=1)
        clipped = int(sat.sum())
        if clipped == sat.size:
            raise ShprobeError("every pixel of the ball is saturated (clipped): nothing to "
                               "fit", path)
    fit = fit_samples(px.reflect, vals, model="mirror", weights=px.solid_angle,
                      albedo=reflectance, robust=False)
    # the cone around −axis that no used pixel reflects into: up to the closest reflection
    blind = float(np.degrees(np.arccos(np.clip(np.max(px.reflect @ -px.axis), -1, 1))))
    out = BallFit(fit, c, cam, px, "chrome", blind_angle=blind,
                  blind_solid_angle=2 * np.pi * (1 - np.cos(np.radians(blind))))
    out.info["clipped"] = clipped
    out.fit.info["clipped_kept"] = clipped
    return out
