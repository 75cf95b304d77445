"""Octahedral maps of the sphere (Cigolle et al. 2014, "A Survey of Efficient Representations
for Independent Unit Vectors", §3.6), with +Y as the pole: the per-probe depth maps of the
grid's leak control (Majercik et al. 2019, DDGI §4) and their bilinear lookup across the
map's folded edges."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["octahedral_decode", "octahedral_encode", "octahedral_lookup", "pad_maps",
           "texel_directions"]


def _sign(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.where(a >= 0.0, 1.0, -1.0)


def octahedral_encode(dirs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit directions (..., 3) → map coordinates (..., 2) in [0, 1]² (u from x, v from z;
    the upper hemisphere y ≥ 0 fills the inner diamond, the lower one the folded corners)."""
    d = np.asarray(dirs, dtype=np.float64)
    s = np.abs(d).sum(axis=-1, keepdims=True)
    p = d[..., [0, 2]] / np.where(s > 0, s, 1.0)
    low = d[..., 1] < 0
    folded = (1.0 - np.abs(p[..., ::-1])) * _sign(p)
    p = np.where(low[..., None], folded, p)
    return 0.5 * (p + 1.0)


def octahedral_decode(uv: NDArray[np.float64]) -> NDArray[np.float64]:
    """Map coordinates (..., 2) in [0, 1]² → unit directions (..., 3)."""
    p = 2.0 * np.asarray(uv, dtype=np.float64) - 1.0
    y = 1.0 - np.abs(p).sum(axis=-1)
    low = y < 0
    xz = np.where(low[..., None], (1.0 - np.abs(p[..., ::-1])) * _sign(p), p)
    d = np.stack([xz[..., 0], y, xz[..., 1]], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def texel_directions(n: int, sub: int) -> NDArray[np.float64]:
    """Directions (n, n, sub², 3) through a sub × sub lattice inside each texel of an n × n
    map (rows along v, columns along u)."""
    t = (np.arange(n)[:, None] + (np.arange(sub)[None, :] + 0.5) / sub) / n  # (n, sub)
    v = t[:, None, :, None] * np.ones((1, n, 1, sub))
    u = t[None, :, None, :] * np.ones((n, 1, sub, 1))
    uv = np.stack([u, v], axis=-1).reshape(n, n, sub * sub, 2)
    return octahedral_decode(uv)


def pad_maps(maps: NDArray) -> NDArray:
    """Maps (..., n, n, C) with a one-texel border copied across the folded edges (the rule
    of DDGI's probe textures): a border texel holds the texel mirrored along its edge, a
    corner the diagonally opposite corner."""
    n = maps.shape[-2]
    out = np.empty((*maps.shape[:-3], n + 2, n + 2, maps.shape[-1]), dtype=maps.dtype)
    out[..., 1:-1, 1:-1, :] = maps
    out[..., 0, 1:-1, :] = maps[..., 0, ::-1, :]
    out[..., -1, 1:-1, :] = maps[..., -1, ::-1, :]
    out[..., 1:-1, 0, :] = maps[..., ::-1, 0, :]
    out[..., 1:-1, -1, :] = maps[..., ::-1, -1, :]
    out[..., 0, 0, :] = maps[..., -1, -1, :]
    out[..., 0, -1, :] = maps[..., -1, 0, :]
    out[..., -1, 0, :] = maps[..., 0, -1, :]
    out[..., -1, -1, :] = maps[..., 0, 0, :]
    return out


def octahedral_lookup(maps: NDArray, which: NDArray[np.int64],
                      dirs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Bilinear lookup of maps (M, n, n, C) — map ``which`` (...,) in direction ``dirs``
    (..., 3) — → (..., C), filtering across the folded edges as a GPU does on a bordered
    octahedral texture."""
    n = maps.shape[1]
    padded = pad_maps(np.asarray(maps, dtype=np.float64))
    t = octahedral_encode(dirs) * n + 0.5  # padded texel coordinate, texel i centred at i + 1
    i0 = np.clip(np.floor(t).astype(np.int64), 0, n)
    f = np.clip(t - i0, 0.0, 1.0)
    u0, v0 = i0[..., 0], i0[..., 1]
    fu, fv = f[..., 0:1], f[..., 1:2]
    return ((1 - fu) * (1 - fv) * padded[which, v0, u0] + fu * (1 - fv) * padded[which, v0, u0 + 1]
            + (1 - fu) * fv * padded[which, v0 + 1, u0] + fu * fv * padded[which, v0 + 1, u0 + 1])
