"""A ball's outline in a photograph: parsing ``CX,CY,R`` and automatic detection.

Pixel coordinates throughout: x right, y down, from the image's top-left corner, pixel
(column i, row j) centred at (i + 0.5, j + 0.5) (docs/conventions.md).

Detection (numpy / scipy only): the background colour is the median of the image border; a
pixel belongs to the foreground when its colour differs from it by more than 2 % of the
image's largest differences (and more than 6 border noise deviations); the largest connected
foreground component, holes filled, is the ball candidate. A circle is fitted algebraically
(Kåsa) to its outline on a reduced image, then refined at full resolution on edge points
(midpoints between neighbouring pixels on either side of the threshold, in an annulus around
the first circle) by geometric least squares with Tukey weights, so a shadow or a stand
touching the ball is outvoted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError

__all__ = ["Circle", "check_circle", "detect_circle", "parse_circle"]

#: Smallest ball radius (pixels) detection accepts.
MIN_RADIUS = 8.0
#: Largest image side the coarse detection works on.
COARSE_SIDE = 768
#: Foreground: colour distance from the background above this fraction of the image's
#: 99.5th-percentile distance (and above 6 noise deviations of the border).
THRESHOLD = 0.02


@dataclass(frozen=True)
class Circle:
    """A circle in pixel coordinates (x right, y down, top-left corner 0, pixel centres at
    +0.5). ``inliers``: fraction of the outline points the fit agrees with (1 for a given
    circle).

    Parameters
    ----------
    cx, cy
        The centre, pixels (x right, y down, pixel centres at +0.5).
    r
        The radius, pixels.
    inliers
        The fraction of outline points the fit agrees with (1 for a given circle).
    """

    cx: float
    cy: float
    r: float
    inliers: float = 1.0

    def __repr__(self) -> str:
        return f"Circle(cx={self.cx:.2f}, cy={self.cy:.2f}, r={self.r:.2f})"

    def text(self) -> str:
        return f"{self.cx:.3f},{self.cy:.3f},{self.r:.3f}"


def parse_circle(text: str) -> Circle:
    """``"CX,CY,R"`` → [`Circle`][shprobe.fitting.Circle]; one-line error otherwise.

    Parameters
    ----------
    text
        "CX,CY,R" in pixels.

    Returns
    -------
    Circle
        The circle.
    """
    try:
        vals = [float(t) for t in text.replace(" ", "").split(",")]
    except ValueError:
        vals = []
    if len(vals) != 3 or not all(np.isfinite(vals)):
        raise ShprobeError(f"cannot parse circle {text!r}: expected CX,CY,R in pixels")
    if vals[2] <= 0:
        raise ShprobeError(f"circle radius must be positive, got {vals[2]}")
    return Circle(*vals)


def check_circle(circle: Circle, shape: tuple[int, ...], path=None) -> Circle:
    """Refuse a circle that leaves the image or is too small to fit.

    Parameters
    ----------
    circle
        The circle.
    shape
        The image's shape.
    path
        The image file, named in the error.

    Returns
    -------
    Circle
        The same circle, checked.
    """
    h, w = shape[:2]
    c = circle
    if c.r < 2.0:
        raise ShprobeError(f"ball radius {c.r:.2f} px is too small to fit", path)
    if c.cx - c.r < 0 or c.cy - c.r < 0 or c.cx + c.r > w or c.cy + c.r > h:
        raise ShprobeError(f"the ball ({c.text()}) touches or crosses the image border "
                           f"({w}x{h}); the photo must show the whole ball", path)
    return c


def _reduce(img: NDArray, f: int) -> NDArray[np.float32]:
    """f×f block means (the image cropped to whole blocks), summed over the f² strided views
    (much faster than a reduction over a 5-D reshape)."""
    a = np.asarray(img, np.float32)
    if f == 1:
        return a
    h, w = (a.shape[0] // f) * f, (a.shape[1] // f) * f
    out = np.zeros((h // f, w // f, *a.shape[2:]), np.float32)
    for i in range(f):
        for j in range(f):
            out += a[i:h:f, j:w:f]
    out *= np.float32(1.0 / (f * f))
    return out


def block_extremes(img: NDArray, f: int) -> tuple[NDArray, NDArray]:
    """Per f×f block, the largest and the smallest channel value of any pixel (elementwise
    over the strided views and the channels; reductions over a length-3 axis are slow)."""
    a = np.asarray(img, np.float32)
    h, w = (a.shape[0] // f) * f, (a.shape[1] // f) * f
    hi = lo = None
    for i in range(f):
        for j in range(f):
            v = a[i:h:f, j:w:f]
            for c in range(a.shape[2]):
                x = v[..., c]
                hi = x.copy() if hi is None else np.maximum(hi, x, out=hi)
                lo = x.copy() if lo is None else np.minimum(lo, x, out=lo)
    return hi, lo


def _kasa(x: NDArray, y: NDArray) -> tuple[float, float, float]:
    A = np.stack([x, y, np.ones_like(x)], axis=1)
    b = x * x + y * y
    sol = np.linalg.lstsq(A, b, rcond=None)[0]
    cx, cy = sol[0] / 2, sol[1] / 2
    return float(cx), float(cy), float(np.sqrt(max(sol[2] + cx * cx + cy * cy, 0.0)))


def _geometric(x: NDArray, y: NDArray, c0: tuple[float, float, float], iters: int = 20
               ) -> tuple[float, float, float, NDArray]:
    """Gauss–Newton on the distances to the circle with Tukey weights; (cx, cy, r, weights)."""
    cx, cy, r = c0
    w = np.ones_like(x)
    for _ in range(iters):
        dx, dy = x - cx, y - cy
        rho = np.maximum(np.hypot(dx, dy), 1e-12)
        res = rho - r
        s = max(1.4826 * np.median(np.abs(res[w > 0])) if np.any(w > 0) else 1.0, 0.25)
        t = np.clip(res / (4.685 * s), -1.0, 1.0)
        w = (1 - t * t) ** 2
        J = np.stack([-dx / rho, -dy / rho, -np.ones_like(x)], axis=1)
        Jw = J * w[:, None]
        try:
            step = np.linalg.solve(Jw.T @ J, -(Jw.T @ res))
        except np.linalg.LinAlgError:
            break
        cx, cy, r = cx + step[0], cy + step[1], r + step[2]
        if np.abs(step).max() < 1e-6:
            break
    return float(cx), float(cy), float(r), w


def _foreground_distance(img: NDArray, bg: NDArray) -> NDArray[np.float32]:
    """max over channels of |pixel − background| (elementwise over the channels)."""
    a = np.asarray(img, np.float32)
    out = np.abs(a[..., 0] - np.float32(bg[0]))
    for c in range(1, a.shape[-1]):
        np.maximum(out, np.abs(a[..., c] - np.float32(bg[c])), out=out)
    return out


def _edge_points(dist: NDArray, thr: float, x0: float = 0.0, y0: float = 0.0
                 ) -> tuple[NDArray, NDArray]:
    """Midpoints between horizontally and vertically neighbouring pixels on either side of
    the threshold (pixel centres at +0.5, offset by (x0, y0)): unbiased for a hard edge, and
    within ±0.5 px (averaging out over the outline) for a blended one. Interpolating the
    crossing instead would shift the outline with the shading next to it."""
    xs, ys = [], []
    fg = dist > thr
    for axis in (0, 1):
        fa = fg[:-1] if axis == 0 else fg[:, :-1]
        fb = fg[1:] if axis == 0 else fg[:, 1:]
        jj, ii = np.nonzero(fa != fb)
        t = 0.5
        if axis == 0:
            xs.append(ii + 0.5)
            ys.append(jj + 0.5 + t)
        else:
            xs.append(ii + 0.5 + t)
            ys.append(jj + 0.5)
    return np.concatenate(xs) + x0, np.concatenate(ys) + y0


def detect_circle(image: NDArray, path=None) -> Circle:
    """Find one ball (a disc differing from the background) in ``image`` (H, W, C) linear.

    Raises a one-line [`ShprobeError`][shprobe.errors.ShprobeError] when no ball stands out, when
    the outline is not a circle, or when the ball touches the image border.

    Parameters
    ----------
    image
        (H, W, C) linear image.
    path
        The image file, named in the error.

    Returns
    -------
    Circle
        The ball's outline.
    """
    from scipy import ndimage

    img = np.asarray(image)
    if img.ndim == 2:
        img = img[:, :, None]
    H, W = img.shape[:2]
    f = max(1, int(np.ceil(max(H, W) / COARSE_SIDE)))
    small = _reduce(img, f)
    h, w = small.shape[:2]
    if min(h, w) < 8:
        raise ShprobeError(f"image {W}x{H} is too small to find a ball in", path)
    b = max(1, min(h, w) // 50)
    border = np.concatenate([small[:b].reshape(-1, small.shape[2]),
                             small[-b:].reshape(-1, small.shape[2]),
                             small[:, :b].reshape(-1, small.shape[2]),
                             small[:, -b:].reshape(-1, small.shape[2])])
    bg = np.median(border, axis=0)
    dist = _foreground_distance(small, bg)
    noise = 1.4826 * np.median(np.abs(_foreground_distance(border, bg)))
    top = float(np.percentile(dist, 99.5))
    if not top > max(6.0 * noise, 1e-6 * max(float(np.abs(bg).max()), 1e-30), 0.0):
        raise ShprobeError("no ball found: nothing in the image stands out from the "
                           "background (pass --circle CX,CY,R)", path)
    thr = max(THRESHOLD * top, 6.0 * noise)
    lab, n = ndimage.label(dist > thr)
    if n == 0:
        raise ShprobeError("no ball found: nothing stands out from the background "
                           "(pass --circle CX,CY,R)", path)
    sizes = np.bincount(lab.ravel())[1:]
    k = int(np.argmax(sizes)) + 1
    comp = ndimage.binary_fill_holes(lab == k)
    area = float(comp.sum()) * f * f
    if np.sqrt(area / np.pi) < MIN_RADIUS:
        raise ShprobeError(f"no ball found: the largest object covers {int(area)} pixels "
                           f"(pass --circle CX,CY,R)", path)
    # coarse circle from the component's outline
    cdist = np.where(comp, np.maximum(dist, thr * 1.0001), np.minimum(dist, thr))
    ex, ey = _edge_points(cdist, thr)
    if ex.size < 12:
        raise ShprobeError("no ball found: the object's outline is too small", path)
    c0 = _kasa(ex * f, ey * f)
    cx, cy, r, wts = _geometric(ex * f, ey * f, c0)
    # refine at full resolution in an annulus around the coarse circle
    m = 2.0 * f + 2.0
    x0, x1 = int(max(np.floor(cx - r - m), 0)), int(min(np.ceil(cx + r + m), W))
    y0, y1 = int(max(np.floor(cy - r - m), 0)), int(min(np.ceil(cy + r + m), H))
    if f > 1:
        crop = _foreground_distance(img[y0:y1, x0:x1], bg)
        yy = (np.arange(y0, y1, dtype=np.float32) + np.float32(0.5 - cy))[:, None]
        xx = (np.arange(x0, x1, dtype=np.float32) + np.float32(0.5 - cx))[None, :]
        rho = np.sqrt(yy * yy + xx * xx)
        ring = np.abs(rho - r) <= m
        # keep the structure of the crop: outside the ring, force the coarse decision
        crop = np.where(ring, crop, np.where(rho < r, np.maximum(crop, thr * 1.0001),
                                             np.minimum(crop, thr)))
        ex, ey = _edge_points(crop, thr, x0, y0)
        cx, cy, r, wts = _geometric(ex, ey, (cx, cy, r))
    inl = float(np.mean(wts > 0.5))
    touches = bool(comp[0].any() or comp[-1].any() or comp[:, 0].any() or comp[:, -1].any())
    outside = cx - r < 0 or cy - r < 0 or cx + r > W or cy + r > H
    if touches and (outside or inl < 0.6):
        raise ShprobeError("the ball touches the image border; the photo must show the whole "
                           "ball", path)
    if inl < 0.6 or not r > MIN_RADIUS:
        raise ShprobeError(f"no ball found: the largest object's outline is not a circle "
                           f"(only {100 * inl:.0f} % of it fits one; pass --circle CX,CY,R)",
                           path)
    return check_circle(Circle(cx, cy, r, inl), img.shape, path)
