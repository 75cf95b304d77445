"""Numba kernels of the gather's per-ray bookkeeping (compiled once, cached on disk); their
references are `shprobe.lightmaps.hits.directions_numpy` and
`shprobe.lightmaps.hits.hit_records_numpy`, checked against them in the tests."""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def directions(rand, kz, kp, a, frames, fn, dt, dw, dw32, below,
               wt):  # pragma: no cover - compiled
    """Stratified directions of the mixture density with uniform share ``a``: dt (n, S, 3)
    tangent-frame, dw world (and dw32 its float32 copy for Embree), below (n, S) where dw
    points under the face with normal fn, wt (n, S) the weights 1/(S p(ω))."""
    n, s = rand.shape[0], rand.shape[1]
    for p in range(n):
        for i in range(s):
            u = (i // kp + rand[p, i, 0]) / kz
            z = u if a >= 1.0 else (math.sqrt(a * a + 4.0 * (1.0 - a) * u) - a) / (2.0 * (1.0 - a))
            wt[p, i] = 1.0 / (s * (a / (2.0 * math.pi) + (1.0 - a) * z / math.pi))
            phi = 2.0 * math.pi * (i % kp + rand[p, i, 1]) / kp
            r = math.sqrt(max(0.0, 1.0 - z * z))
            x, y = r * math.cos(phi), r * math.sin(phi)
            dt[p, i, 0], dt[p, i, 1], dt[p, i, 2] = x, y, z
            d = 0.0
            for j in range(3):
                w = x * frames[p, 0, j] + y * frames[p, 1, j] + z * frames[p, 2, j]
                dw[p, i, j] = w
                dw32[p * s + i, j] = w
                d += w * fn[p, j]
            below[p, i] = d <= 0.0


@numba.njit(cache=True, nogil=True)
def hit_records(f, u, v, front, uv1, uv0, base, tex, texels, tex_info,
                ps, rec):  # pragma: no cover - compiled
    """Fill the front-face hits' texel and ray ps (M, 2) and their lightmap UV and albedo
    rec (M, 5) (row-major over (texel, ray)); the textures are bilinear with REPEAT
    wrapping."""
    n, s = f.shape
    m = 0
    for p in range(n):
        for i in range(s):
            if not front[p, i]:
                continue
            k = f[p, i]
            b1, b2 = np.float64(u[p, i]), np.float64(v[p, i])
            b0 = 1.0 - b1 - b2
            ps[m, 0], ps[m, 1] = p, i
            for j in range(2):
                rec[m, j] = b0 * uv1[k, 0, j] + b1 * uv1[k, 1, j] + b2 * uv1[k, 2, j]
            t = tex[k]
            if t < 0:
                for ch in range(3):
                    rec[m, 2 + ch] = min(1.0, max(0.0, base[k, ch]))
            else:
                off, h, w = tex_info[t, 0], tex_info[t, 1], tex_info[t, 2]
                tu = b0 * uv0[k, 0, 0] + b1 * uv0[k, 1, 0] + b2 * uv0[k, 2, 0]
                tv = b0 * uv0[k, 0, 1] + b1 * uv0[k, 1, 1] + b2 * uv0[k, 2, 1]
                x, y = tu * w - 0.5, tv * h - 0.5
                x0, y0 = math.floor(x), math.floor(y)
                fx, fy = x - x0, y - y0
                xa, ya = int(x0) % w, int(y0) % h
                xb, yb = (xa + 1) % w, (ya + 1) % h
                for ch in range(3):
                    t00 = texels[off + (ya * w + xa) * 3 + ch]
                    t01 = texels[off + (ya * w + xb) * 3 + ch]
                    t10 = texels[off + (yb * w + xa) * 3 + ch]
                    t11 = texels[off + (yb * w + xb) * 3 + ch]
                    val = ((t00 * (1 - fx) + t01 * fx) * (1 - fy)
                           + (t10 * (1 - fx) + t11 * fx) * fy)
                    rec[m, 2 + ch] = min(1.0, max(0.0, base[k, ch] * val))
            m += 1
