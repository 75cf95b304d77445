"""Image I/O: HDR/EXR/PFM/TIFF/PNG/JPEG in, EXR/HDR/PFM/PNG/JPEG/TIFF out.

``read_image`` returns linear RGB ``(H, W, 3) float32`` with row 0 at the top. 8/16-bit images
(PNG, JPEG, integer TIFF) are decoded from sRGB to linear and an
[`LDRWarning`][shprobe.probes.images.LDRWarning] is issued: display-referred pixels are not
radiance. NaN, Inf or negative pixels are an error naming the file, unless ``clamp=True`` (NaN → 0,
−∞/negatives → 0, +∞ → the largest finite value). The formats themselves are in
`shprobe.probes.codecs`, the tone map in `shprobe.probes.tonemap`, streamed reading in
`shprobe.probes.streaming`.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..files import atomic_output, check_output_path
from .codecs import (
    exposure_metadata,
    read_oiio,
    read_pfm,
    read_rgbe,
    rgbe_half_step,
    write_oiio,
    write_pfm,
)
from .tonemap import tonemap

#: Extensions read_image accepts.
READ_EXTENSIONS = (".hdr", ".rgbe", ".pic", ".exr", ".pfm", ".tif", ".tiff", ".png", ".jpg",
                   ".jpeg")
#: Extensions write_image accepts.
WRITE_EXTENSIONS = (".exr", ".hdr", ".pfm", ".png", ".jpg", ".jpeg", ".tif", ".tiff")
_LDR_OUT = (".png", ".jpg", ".jpeg")


class LDRWarning(UserWarning):
    """An 8/16-bit image was read: its pixels are display values, not radiance."""


def read_image(path: str | os.PathLike[str], clamp: bool = False) -> NDArray[np.float32]:
    """Read an image as linear RGB ``(H, W, 3) float32``, row 0 at the top.

    Grey images are repeated to 3 channels; a 4th (alpha) channel and any beyond are dropped
    (colour is read as stored, not multiplied by alpha).
    Raises [`ShprobeError`][shprobe.errors.ShprobeError] naming the file for a missing, empty,
    truncated, corrupt or unknown file, and for NaN/Inf/negative pixels unless ``clamp``.

    Parameters
    ----------
    path
        The image file (.hdr, .exr, .pfm, .tif, .png, .jpg …).
    clamp
        Clamp NaN, infinite and negative pixels to 0 instead of refusing them.

    Returns
    -------
    ndarray of shape (H, W, 3), float32
        Linear RGB, row 0 at the top.
    """
    p = Path(path)
    ext = p.suffix.lower()
    check_readable(p, ext)
    ldr = False
    if ext == ".pfm":
        img = read_pfm(p)
    else:
        if ext in (".hdr", ".rgbe", ".pic"):
            try:  # shprobe's decoder first: one compiled pass, the (m + 0.5) step built in
                return read_rgbe(p)  # finite and ≥ 0 by construction: nothing to check
            except ShprobeError as own:
                try:  # what it refuses (other FORMATs) OpenImageIO may still read
                    img = rgbe_half_step(read_oiio(p)[0])
                except ShprobeError:
                    raise own from None
        else:
            img, ldr = read_oiio(p)
    img = to_rgb(img, p)
    if ldr:
        warnings.warn(f"{p}: 8/16-bit image decoded from sRGB to linear — display values are "
                      "not radiance", LDRWarning, stacklevel=2)
    return check_pixels(img, p, clamp)


def check_readable(p: Path, ext: str) -> None:
    """One line for an unknown extension, a missing file, a folder or an empty file.

    Parameters
    ----------
    p
        The file.
    ext
        Its extension.
    """
    if ext not in READ_EXTENSIONS:
        raise ShprobeError(
            f"unknown image extension {ext or '(none)'!r}; expected one of "
            + " ".join(READ_EXTENSIONS), p)
    if not p.exists():
        raise ShprobeError("no such file", p)
    if p.is_dir():
        raise ShprobeError("is a directory, not an image", p)
    if p.stat().st_size == 0:
        raise ShprobeError("file is empty", p)




def to_rgb(img: NDArray[np.float32], p: Path) -> NDArray[np.float32]:
    if img.ndim != 3 or img.shape[0] == 0 or img.shape[1] == 0:
        raise ShprobeError("image has zero size", p)
    c = img.shape[2]
    if c in (1, 2):  # grey (+ alpha)
        img = np.repeat(img[:, :, :1], 3, axis=2)
    elif c >= 3:
        img = img[:, :, :3]
    return np.ascontiguousarray(img, dtype=np.float32)


def check_pixels(img: NDArray[np.float32], path: str | os.PathLike[str] | None = None,
                 clamp: bool = False, whole: bool = True) -> NDArray[np.float32]:
    """Refuse NaN, Inf or negative pixels (``ShprobeError`` with counts) unless ``clamp``;
    a ``whole`` image (not a block of one) without any finite pixel is refused even then.

    Parameters
    ----------
    img
        The image.
    path
        Its file, named in the error.
    clamp
        Clamp bad pixels to 0 instead of refusing them.
    whole
        The image is whole (not a streamed block of one).

    Returns
    -------
    ndarray
        The image (clamped when asked).
    """
    if img.size == 0:
        return img
    lo, hi = img.min(), img.max()  # fast path: two reductions, no temporaries
    if lo >= 0 and np.isfinite(hi):
        return img
    bad_nan = np.isnan(img)
    bad_inf = np.isinf(img)
    bad_neg = img < 0
    n_nan, n_inf, n_neg = int(bad_nan.sum()), int(bad_inf.sum()), int((bad_neg & ~bad_inf).sum())
    if n_nan + n_inf + n_neg == 0:
        return img
    if not clamp:
        parts = [f"{n} {what}" for n, what in ((n_nan, "NaN"), (n_inf, "infinite"),
                                               (n_neg, "negative")) if n]
        raise ShprobeError(
            "image has " + ", ".join(parts) + " pixel values (use clamp / --clamp to zero them)",
            path)
    finite = img[np.isfinite(img)]
    if finite.size == 0 and whole:  # clamping would leave a black image: nothing to light
        raise ShprobeError(f"image has no finite pixel value ({n_nan} NaN, {n_inf} infinite): "
                           "clamp would leave it black", path)
    big = float(finite.max()) if finite.size else 0.0
    out = np.nan_to_num(img, nan=0.0, posinf=max(big, 0.0), neginf=0.0)
    return np.maximum(out, 0.0).astype(np.float32)



def check_image_output(path: str | os.PathLike[str], overwrite: bool = False) -> Path:
    """Refuse, before any work, an output [`write_image`][shprobe.probes.images.write_image] cannot
    write or may not replace: an unknown extension, an existing file (unless ``overwrite``), a
    missing folder.

    Parameters
    ----------
    path
        The output file.
    overwrite
        An existing file may be replaced.

    Returns
    -------
    Path
        The path, checked.
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in WRITE_EXTENSIONS:
        raise ShprobeError(
            f"cannot write extension {ext or '(none)'!r}; expected one of "
            + " ".join(WRITE_EXTENSIONS), p)
    return check_output_path(p, overwrite)


def write_image(path: str | os.PathLike[str], rgb: ArrayLike, overwrite: bool = False,
                exposure: float = 0.0, half: bool = False) -> Path:
    """Write linear RGB ``(H, W, 3)`` (or ``(H, W)`` grey) atomically.

    ``.exr`` (float, or half with ``half=True``), ``.hdr`` (RGBE), ``.pfm`` and ``.tif`` are
    linear and ignore ``exposure``; ``.png`` and ``.jpg`` are tone-mapped with
    `tonemap` (exposure in stops). The picture carries its
    exposure and colour space in its metadata (PNG text chunks, EXR/TIFF/JPEG attributes:
    `exposure_metadata`: the stops applied, 0 for linear files;
    ``oiio:ColorSpace`` sRGB or linear Rec. 709), so a reader such as ``shprobe fit`` can
    undo it (`read_exposure`). An existing file is replaced only
    with ``overwrite=True``. NaN or Inf values are refused; ``.hdr`` (RGBE, unsigned) stores
    negative values as 0.

    Parameters
    ----------
    path
        The output file; its suffix picks the format.
    rgb
        (H, W, 3) linear RGB or (H, W) grey.
    overwrite
        Replace an existing file.
    exposure
        Stops applied before tone mapping (PNG / JPEG only).
    half
        Write half floats (EXR).

    Returns
    -------
    Path
        The file written.
    """
    p = check_image_output(path, overwrite)
    ext = p.suffix.lower()
    a = np.asarray(rgb, dtype=np.float32)
    if a.ndim == 2:
        a = np.repeat(a[:, :, None], 3, axis=2)
    if a.ndim != 3 or a.shape[2] not in (1, 3, 4) or a.shape[0] == 0 or a.shape[1] == 0:
        raise ShprobeError(f"image to write must be (H, W, 3), got {a.shape}", p)
    if a.shape[2] == 1:
        a = np.repeat(a, 3, axis=2)
    a = np.ascontiguousarray(a[:, :, :3])
    bad = int(np.count_nonzero(~np.isfinite(a)))
    if bad:
        raise ShprobeError(f"refusing to write an image with {bad} NaN or Inf values", p)
    if ext == ".hdr":
        a = np.maximum(a, 0.0)  # RGBE has no sign
    with atomic_output(p, overwrite) as tmp:
        if ext == ".pfm":
            write_pfm(tmp, a)
        elif ext in _LDR_OUT:
            write_oiio(tmp, tonemap(a, exposure), "uint8", exposure_metadata(exposure, "sRGB"))
        else:
            fmt = "half" if (half and ext == ".exr") else "float"
            write_oiio(tmp, a, fmt, exposure_metadata(0.0, "lin_rec709"))
    return p

