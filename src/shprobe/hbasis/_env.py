"""Lighting input for the normal-mapping bake/render: a lat-long probe or SH coefficients.

Until ``shprobe.layouts`` / ``shprobe.prefilter`` are on main this module reads a lat-long
image itself (OpenImageIO) with the project convention (world +Y up, row 0 = +Y, pixel centres
u = (i+0.5)/W, v = (j+0.5)/H, u = 0.5 looks along −Z, u = 0.75 along +X):

    d(u, v) = (−sin 2πu · sin πv,  cos πv,  cos 2πu · sin πv),

with exact pixel solid angles (2π/W)(cos θ_top − cos θ_bottom).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..sh import lmax_of, sh_basis


@dataclass
class Lighting:
    """Radiance samples (may be None for pure SH input) and SH lighting coefficients L_lm."""

    dirs: NDArray | None  # (N, 3)
    solid_angles: NDArray | None  # (N,)
    radiance: NDArray | None  # (N, 3)
    sh: NDArray  # (K, 3) radiance coefficients L_lm


def latlong_directions(width: int, height: int) -> tuple[NDArray, NDArray]:
    """Pixel-centre directions (H, W, 3) and solid angles (H, W) of a lat-long map."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    st, ct = np.sin(np.pi * v), np.cos(np.pi * v)
    d = np.stack(np.broadcast_arrays(-np.sin(2 * np.pi * u)[None, :] * st[:, None],
                                     ct[:, None] + 0 * u[None, :],
                                     np.cos(2 * np.pi * u)[None, :] * st[:, None]), axis=-1)
    edges = np.cos(np.pi * np.arange(height + 1) / height)
    sa = (2 * np.pi / width) * (edges[:-1] - edges[1:])
    return d, np.broadcast_to(sa[:, None], (height, width)).copy()


def _read_image(path: Path) -> NDArray:
    try:
        from ..images import read_image  # when the layouts branch has landed
    except ImportError:
        read_image = None
    if read_image is not None:
        return np.asarray(read_image(path), dtype=np.float64)[..., :3]
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise ShprobeError("cannot read image (not a supported HDR/LDR image)", path)
    try:
        px = inp.read_image(format=oiio.FLOAT)
    finally:
        inp.close()
    if px is None or px.ndim != 3 or px.shape[2] < 3:
        raise ShprobeError("cannot read image as RGB", path)
    return np.asarray(px[..., :3], dtype=np.float64)


def load_lighting(path, lmax: int = 16) -> Lighting:
    """Lighting from a lat-long probe image (2:1) or an .npy/.npz of SH radiance coefficients
    (K, 3) (npz: array ``L`` or ``coeffs`` or the first array)."""
    p = Path(path)
    if not p.is_file():
        raise ShprobeError("no such file", p)
    if p.suffix.lower() in (".npy", ".npz"):
        try:
            data = np.load(p)
            if p.suffix.lower() == ".npz":
                key = next((k for k in ("L", "coeffs") if k in data.files), data.files[0])
                data = data[key]
        except (OSError, ValueError, IndexError) as e:
            raise ShprobeError(f"cannot read SH coefficients: {e}", p) from None
        c = np.asarray(data, dtype=np.float64)
        if c.ndim == 1:
            c = np.repeat(c[:, None], 3, axis=1)
        try:
            lmax_of(c.shape[0])
        except ShprobeError as e:
            raise ShprobeError(e.message, p) from None
        if c.ndim != 2 or c.shape[1] != 3:
            raise ShprobeError(f"SH coefficients must be (K, 3), got {c.shape}", p)
        return Lighting(None, None, None, c)
    img = _read_image(p)
    h, w = img.shape[:2]
    if w != 2 * h:
        raise ShprobeError(f"expected a 2:1 lat-long probe, got {w}x{h}", p)
    d, sa = latlong_directions(w, h)
    d, sa, rad = d.reshape(-1, 3), sa.reshape(-1), img.reshape(-1, 3)
    if not np.all(np.isfinite(rad)):
        raise ShprobeError("probe contains non-finite pixels", p)
    sh = (sh_basis(d, lmax) * sa[:, None]).T @ rad
    return Lighting(d, sa, rad, sh)


def brute_force_irradiance(lighting: Lighting, normals: NDArray, chunk: int = 256) -> NDArray:
    """E(n) = Σ_pixels L(ω) max(n·ω, 0) dΩ (R&H eq. 5 by direct summation), normals (N, 3)."""
    if lighting.dirs is None:
        raise ShprobeError("brute-force irradiance needs an image probe, not SH coefficients")
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    ld = lighting.radiance * lighting.solid_angles[:, None]
    out = np.empty((n.shape[0], 3))
    dt = lighting.dirs.T
    for i in range(0, n.shape[0], chunk):
        cos = np.maximum(n[i:i + chunk] @ dt, 0.0)
        out[i:i + chunk] = cos @ ld
    return out.reshape(*np.shape(normals)[:-1], 3)
