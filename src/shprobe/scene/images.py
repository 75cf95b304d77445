"""What is done with rendered images: relit from basis images (R&H §3.3), coloured as R&H
Fig. 4 (positive green, negative blue), written to a file (tone-mapped PNG or linear HDR)."""

from __future__ import annotations

import os

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError

__all__ = ["basis_visual", "relight", "save_image"]


def relight(basis: ArrayLike, coeffs: ArrayLike) -> NDArray[np.float32]:
    """Σ_k L_kc · basis_k: an image (H, W, C) from basis images (H, W, K) and lighting
    (K, C).

    Parameters
    ----------
    basis
        (H, W, K) basis images.
    coeffs
        (K, C) lighting coefficients.

    Returns
    -------
    ndarray of shape (H, W, C), float32
        The relit image.
    """
    b = np.asarray(basis, dtype=np.float32)
    c = np.asarray(coeffs, dtype=np.float32)
    if c.ndim == 1:
        c = c[:, None]
    if b.shape[-1] != c.shape[0]:
        raise ShprobeError(f"{b.shape[-1]} basis images but {c.shape[0]} coefficients")
    return b @ c


def basis_visual(values: ArrayLike, scale: float | None = None) -> NDArray[np.float32]:
    """R&H Fig. 4 colouring of a signed image (H, W): positive green, negative blue, linear,
    divided by ``scale`` (default: its own max |value|).

    Parameters
    ----------
    values
        (H, W) signed image.
    scale
        The value shown at full intensity (default: its max |value|).

    Returns
    -------
    ndarray of shape (H, W, 3), float32
        Positive green, negative blue.
    """
    v = np.asarray(values, dtype=np.float32)
    s = float(np.abs(v).max()) if scale is None else float(scale)
    v = v / (s if s > 0 else 1.0)
    return np.stack([np.zeros_like(v), np.maximum(v, 0), np.maximum(-v, 0)], -1)


def save_image(path: str | os.PathLike[str], image: ArrayLike, exposure: float = 0.0,
               overwrite: bool = False) -> None:
    """Write a render with [`shprobe.probes.images.write_image`][shprobe.probes.images.write_image]:
    ``.png`` tone-mapped by `tonemap` (× 2^exposure, clamp, sRGB, 8 bits),
    ``.exr``/``.hdr``/``.pfm`` linear. Radiance is never negative: where a truncated SH irradiance
    dips below zero (per-vertex shading interpolates it unclamped) the file holds 0, so that
    shprobe's readers (``fit``) accept what ``render`` writes.

    Parameters
    ----------
    path
        The output file; its suffix picks the format.
    image
        (H, W, C) linear radiance.
    exposure
        Stops applied before tone mapping (PNG only).
    overwrite
        Replace an existing file.
    """
    from ..probes.images import write_image

    write_image(path, np.maximum(np.asarray(image, dtype=np.float32), 0.0),
                overwrite=overwrite, exposure=exposure)
