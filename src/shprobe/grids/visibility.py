"""Leak control: visibility-aware weights between a point and the probes of its cell, after
DDGI (Majercik, Guertin, Nowrouzezahrai, McGuire 2019, "Dynamic Diffuse Global Illumination
with Ray-Traced Irradiance Fields", JCGT 8(2), §4 and its listing 1).

Each probe keeps an octahedral map of the mean and mean-square distance to the first surface
it sees (``ProbeGrid.depth``). A point p with normal n is looked up at q = p + b·n (b: the
normal bias, a fraction of the smallest cell side); each of the 8 probes of q's cell gets

- the back-face weight ((1 + n·ω̂)/2)² + 0.2, ω̂ the direction from q to the probe;
- the Chebyshev weight σ²/(σ² + (d − μ)²), cubed, where the probe's distance d to q passes the
  mean μ of its depth map in that direction (1 where d ≤ μ): a probe behind a wall has a
  near surface in q's direction, so d ≫ μ and the weight falls to ~0;
- the crush of weights below 0.2 (w ← w³/0.04), then the trilinear weight and the probe's
  validity (0 for a probe left inside geometry).

The weights are normalised to sum to 1; a point whose every probe is hidden or invalid falls
back on the trilinear weights (of the valid probes, else of all). The lookups run in a numba
kernel (`shprobe.grids._kernels`); `visibility_weights_reference` is the same rule in numpy.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .cells import cell_probes
from .octahedral import octahedral_lookup, pad_maps

__all__ = ["DEFAULT_NORMAL_BIAS", "visibility_weights", "visibility_weights_reference"]

#: Offset of the lookup point along the normal, as a fraction of the smallest cell side (the
#: meta key ``normal_bias`` of a grid overrides it).
DEFAULT_NORMAL_BIAS = 0.1
#: Points per block: bounds the temporaries (8 probes × ~12 doubles per point).
_BLOCK = 65536


def visibility_weights(grid, points: NDArray[np.float64], normals: NDArray[np.float64]
                       ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Flat probe indices (..., 8) and leak-controlled weights (..., 8) summing to 1 for
    points (..., 3) on surfaces facing unit ``normals`` (..., 3) (module doc)."""
    from . import _kernels

    p, n, shape, depth, pos, valid, bias = _inputs(grid, points, normals)
    padded = pad_maps(depth)
    idx = np.empty((len(p), 8), dtype=np.int64)
    w = np.empty((len(p), 8))
    for a in range(0, len(p), _BLOCK):
        s = slice(a, a + _BLOCK)
        q = np.ascontiguousarray(p[s] + bias * n[s])
        idx[s], tri = cell_probes(grid.bounds, grid.resolution, q)
        _kernels.visibility_weights(q, np.ascontiguousarray(n[s]), idx[s], tri, pos, padded,
                                    valid, w[s])
    return idx.reshape(*shape, 8), w.reshape(*shape, 8)


def visibility_weights_reference(grid, points: NDArray[np.float64],
                                 normals: NDArray[np.float64]
                                 ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """`visibility_weights` in numpy, array by array (the reference of the kernel)."""
    p, n, shape, depth, pos, valid, bias = _inputs(grid, points, normals)
    idx = np.empty((len(p), 8), dtype=np.int64)
    w = np.empty((len(p), 8))
    for a in range(0, len(p), _BLOCK):
        s = slice(a, a + _BLOCK)
        idx[s], w[s] = _block(grid, depth, pos, valid, p[s] + bias * n[s], n[s])
    return idx.reshape(*shape, 8), w.reshape(*shape, 8)


def _inputs(grid, points, normals):
    p = np.asarray(points, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)
    shape = p.shape[:-1]
    depth = np.asarray(grid.depth, dtype=np.float64)
    depth = depth.reshape(-1, *depth.shape[3:])
    pos = np.ascontiguousarray(grid.probe_positions().reshape(-1, 3))
    valid = (np.ones(len(pos)) if grid.validity is None
             else np.asarray(grid.validity, dtype=np.float64).reshape(-1))
    bias = float(grid.meta.get("normal_bias", DEFAULT_NORMAL_BIAS)) * float(grid.spacing.min())
    return p.reshape(-1, 3), n.reshape(-1, 3), shape, depth, pos, valid, bias


def _block(grid, depth, pos, valid, q, n):
    idx, tri = cell_probes(grid.bounds, grid.resolution, q)
    to_probe = pos[idx] - q[:, None, :]  # (N, 8, 3)
    d = np.linalg.norm(to_probe, axis=-1)
    near = d < 1e-9
    u = np.where(near[..., None], n[:, None, :], to_probe / np.where(near, 1.0, d)[..., None])
    cosine = np.einsum("nkc,nc->nk", u, n)
    w = ((1.0 + cosine) * 0.5) ** 2 + 0.2
    moments = octahedral_lookup(depth, idx, -u)  # the probe's map in the direction of q
    mean, mean2 = moments[..., 0], moments[..., 1]
    var = np.abs(mean2 - mean * mean)
    gap = np.maximum(d - mean, 0.0)
    cheb = np.where(gap > 0, var / np.maximum(var + gap * gap, 1e-300), 1.0)
    w = np.maximum(w * cheb ** 3, 1e-6)
    w = np.where(w < 0.2, w * w * w / 0.04, w)
    w = w * tri * valid[idx]
    total = w.sum(axis=1, keepdims=True)
    hidden = total[:, 0] <= 0
    if hidden.any():  # every probe hidden or invalid: the trilinear blend of the valid ones
        fb = tri[hidden] * valid[idx[hidden]]
        fb = np.where(fb.sum(axis=1, keepdims=True) > 0, fb, tri[hidden])
        w[hidden], total[hidden] = fb, fb.sum(axis=1, keepdims=True)
    return idx, w / total
