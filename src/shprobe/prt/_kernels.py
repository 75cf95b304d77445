"""Numba kernels of the PRT bake (compiled once, cached on disk; ``nogil`` so that the bake's
worker threads run them in parallel). Imported lazily by
[`shprobe.prt.baking.bake`][shprobe.prt.bake]."""

from __future__ import annotations

import numba


@numba.njit(cache=True, nogil=True)
def hemisphere_rays(p, n, dirs, sid, o, d, cw, vid, did):  # pragma: no cover - compiled
    """Fill the rays (o, d) from every vertex p[v] along every direction dirs[sid[v], j] of its
    own direction set (dirs: (S, N, 3), one rotated copy per set) in its upper hemisphere
    (n[v]·d > 0), with their cosines cw and (vertex, direction) indices; returns the number of
    rays."""
    m = 0
    for v in range(p.shape[0]):
        s = sid[v]
        for j in range(dirs.shape[1]):
            c = n[v, 0] * dirs[s, j, 0] + n[v, 1] * dirs[s, j, 1] + n[v, 2] * dirs[s, j, 2]
            if c > 0:
                for a in range(3):
                    o[m, a] = p[v, a]
                    d[m, a] = dirs[s, j, a]
                cw[m] = c
                vid[m] = v
                did[m] = j
                m += 1
    return m


@numba.njit(cache=True, nogil=True)
def add_visible(free, vid, did, cw, yw, out):  # pragma: no cover - compiled
    """out[vertex] += cos · y(ω)·dω over the rays that reach the environment (free)."""
    for r in range(free.shape[0]):
        if free[r]:
            v, j, c = vid[r], did[r], cw[r]
            for k in range(yw.shape[1]):
                out[v, k] += c * yw[j, k]
