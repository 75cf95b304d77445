"""Lighting input for the normal-mapping bake/render: an environment map (any layout of
``shprobe.layouts.load_env``: lat-long, angular, cube) or SH radiance coefficients.

L_lm = Σ_pixels L(ω) y_lm(ω) dω over the exact pixel solid angles (R&H eq. 10 as a sum).
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


def load_lighting(path, lmax: int = 16) -> Lighting:
    """Lighting from an environment map (layout detected by ``shprobe.layouts.load_env``) or an
    .npy/.npz of SH radiance coefficients (K, 3) (npz: array ``L`` or ``coeffs`` or the first
    array)."""
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
    from ..probes.layouts import load_env

    d, rad, sa = load_env(p).samples()
    rad = np.asarray(rad, dtype=np.float64)
    if not np.all(np.isfinite(rad)):
        raise ShprobeError("environment map contains non-finite pixels", p)
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
