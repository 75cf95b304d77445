"""The cells of a probe grid: the volume ``bounds`` split ``resolution`` ways, one probe at each
cell centre (three.js's ``LightProbeGrid`` convention), and the eight probes around a point
with their trilinear weights — what both the engines' plain lookup
([`shprobe.grids.grid.plain_weights`][shprobe.grids.plain_weights]) and leak control
(`shprobe.grids.visibility`) start from."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["cell_centres", "cell_probes"]


def cell_centres(bounds: ArrayLike, resolution: tuple[int, int, int]) -> NDArray[np.float64]:
    """Centres (NX, NY, NZ, 3) of the cells of ``bounds`` split ``resolution`` ways.

    Parameters
    ----------
    bounds
        (2, 3) minimum and maximum corners.
    resolution
        Cells along x, y and z.

    Returns
    -------
    ndarray of shape (NX, NY, NZ, 3)
        The centres.
    """
    b = np.asarray(bounds, dtype=np.float64)
    axes = [b[0, a] + (np.arange(resolution[a]) + 0.5) * (b[1, a] - b[0, a]) / resolution[a]
            for a in range(3)]
    g = np.meshgrid(*axes, indexing="ij")
    return np.stack(g, axis=-1)


def cell_probes(bounds: ArrayLike, resolution: tuple[int, int, int], q: NDArray
                ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Flat indices (..., 8) of the probes at the corners of the cell of probe centres holding
    each point q (..., 3), clamped to the outer probe centres, and their trilinear weights
    (..., 8)."""
    b = np.asarray(bounds, dtype=np.float64)
    res = np.asarray(resolution, dtype=np.int64)
    spacing = (b[1] - b[0]) / res
    g = (np.asarray(q, dtype=np.float64) - (b[0] + 0.5 * spacing)) / spacing  # probe i at i
    i0 = np.clip(np.floor(g).astype(np.int64), 0, np.maximum(res - 2, 0))
    f = np.clip(g - i0, 0.0, 1.0)
    nx, ny, nz = (int(r) for r in res)
    idx, w = [], []
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                ix = np.minimum(i0[..., 0] + dx, nx - 1)
                iy = np.minimum(i0[..., 1] + dy, ny - 1)
                iz = np.minimum(i0[..., 2] + dz, nz - 1)
                wx = f[..., 0] if dx else 1.0 - f[..., 0]
                wy = f[..., 1] if dy else 1.0 - f[..., 1]
                wz = f[..., 2] if dz else 1.0 - f[..., 2]
                idx.append((ix * ny + iy) * nz + iz)
                w.append(wx * wy * wz)
    return np.stack(idx, axis=-1), np.stack(w, axis=-1)
