"""Numba kernels of grid lookups (compiled once, cached on disk): the leak-controlled weights
of `shprobe.grids.visibility`, point by point, and the blend of probe coefficients. Imported
lazily."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True, inline="always")
def _moments(padded, probe, dx, dy, dz, n):  # pragma: no cover - compiled
    """Bilinear mean and mean-square distance of a probe's bordered octahedral depth map
    (`shprobe.grids.octahedral.octahedral_lookup`, +Y the pole) in direction d."""
    s = abs(dx) + abs(dy) + abs(dz)
    px, pz = dx / s, dz / s
    if dy < 0:
        sx = 1.0 if px >= 0 else -1.0
        sz = 1.0 if pz >= 0 else -1.0
        px, pz = (1.0 - abs(pz)) * sx, (1.0 - abs(px)) * sz
    tu = (0.5 * (px + 1.0)) * n + 0.5
    tv = (0.5 * (pz + 1.0)) * n + 0.5
    u0 = min(max(int(np.floor(tu)), 0), n)
    v0 = min(max(int(np.floor(tv)), 0), n)
    fu = min(max(tu - u0, 0.0), 1.0)
    fv = min(max(tv - v0, 0.0), 1.0)
    a, b = (1 - fu) * (1 - fv), fu * (1 - fv)
    c, d = (1 - fu) * fv, fu * fv
    m0 = (a * padded[probe, v0, u0, 0] + b * padded[probe, v0, u0 + 1, 0]
          + c * padded[probe, v0 + 1, u0, 0] + d * padded[probe, v0 + 1, u0 + 1, 0])
    m1 = (a * padded[probe, v0, u0, 1] + b * padded[probe, v0, u0 + 1, 1]
          + c * padded[probe, v0 + 1, u0, 1] + d * padded[probe, v0 + 1, u0 + 1, 1])
    return m0, m1


@numba.njit(cache=True, nogil=True, parallel=True)
def visibility_weights(q, nrm, idx, tri, pos, padded, valid, out):  # pragma: no cover
    """Leak-controlled weights out (N, 8) of the probes idx (N, 8) of each lookup point q
    (N, 3) with unit normal nrm (N, 3), from their trilinear weights tri (N, 8), probe
    positions pos (P, 3), bordered depth maps padded (P, n+2, n+2, 2) and validity (P,):
    the rule of `shprobe.grids.visibility`."""
    n = padded.shape[1] - 2
    for i in numba.prange(q.shape[0]):
        total = 0.0
        for k in range(8):
            p = idx[i, k]
            tx, ty, tz = pos[p, 0] - q[i, 0], pos[p, 1] - q[i, 1], pos[p, 2] - q[i, 2]
            d = np.sqrt(tx * tx + ty * ty + tz * tz)
            if d < 1e-9:
                ux, uy, uz = nrm[i, 0], nrm[i, 1], nrm[i, 2]
            else:
                ux, uy, uz = tx / d, ty / d, tz / d
            c = ux * nrm[i, 0] + uy * nrm[i, 1] + uz * nrm[i, 2]
            w = ((1.0 + c) * 0.5) ** 2 + 0.2
            mean, mean2 = _moments(padded, p, -ux, -uy, -uz, n)
            gap = d - mean
            if gap > 0:
                var = abs(mean2 - mean * mean)
                den = var + gap * gap
                cheb = var / den if den > 0 else 0.0
                w *= cheb * cheb * cheb
            w = max(w, 1e-6)
            if w < 0.2:
                w = w * w * w / 0.04
            w *= tri[i, k] * valid[p]
            out[i, k] = w
            total += w
        if total > 0:
            for k in range(8):
                out[i, k] /= total
        else:  # every probe hidden or invalid: trilinear over the valid ones, else all
            for k in range(8):
                out[i, k] = tri[i, k] * valid[idx[i, k]]
                total += out[i, k]
            if total <= 0:
                for k in range(8):
                    out[i, k] = tri[i, k]
                    total += tri[i, k]
            for k in range(8):
                out[i, k] /= total


@numba.njit(cache=True, nogil=True, parallel=True)
def blend(idx, w, coeffs, out):  # pragma: no cover - compiled
    """out[i] = Σ_k w[i, k] · coeffs[idx[i, k]] for coeffs (P, K, C), out (N, K, C)."""
    for i in numba.prange(idx.shape[0]):
        for k in range(idx.shape[1]):
            p, wk = idx[i, k], w[i, k]
            if wk == 0.0:
                continue
            for a in range(coeffs.shape[1]):
                for c in range(coeffs.shape[2]):
                    out[i, a, c] += wk * coeffs[p, a, c]
