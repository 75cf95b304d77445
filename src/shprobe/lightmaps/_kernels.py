"""Numba kernel of the lightmap rasteriser (compiled once, cached on disk); the reference is
the per-texel definition in `shprobe.lightmaps.atlas.rasterize`'s docstring, checked
against a brute-force NumPy evaluation in the tests."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def raster(tri, width, height, face, bary, dist, count):  # pragma: no cover - compiled
    """tri (F, 3, 2) texel-space corners (texel (r, c) centre at (c, r)); fills face (H, W),
    bary (H, W, 3), dist (H, W) (0 inside, else the centre's distance to the triangle in
    texels, kept when < 0.75) and count (H, W) (strict inside claims, for overlap)."""
    for f in range(tri.shape[0]):
        x0, y0 = tri[f, 0, 0], tri[f, 0, 1]
        x1, y1 = tri[f, 1, 0], tri[f, 1, 1]
        x2, y2 = tri[f, 2, 0], tri[f, 2, 1]
        den = (y1 - y2) * (x0 - x2) + (x2 - x1) * (y0 - y2)
        if abs(den) < 1e-14:
            continue
        lo_x = max(0, int(np.floor(min(x0, x1, x2) - 0.75)))
        hi_x = min(width - 1, int(np.ceil(max(x0, x1, x2) + 0.75)))
        lo_y = max(0, int(np.floor(min(y0, y1, y2) - 0.75)))
        hi_y = min(height - 1, int(np.ceil(max(y0, y1, y2) + 0.75)))
        for r in range(lo_y, hi_y + 1):
            for c in range(lo_x, hi_x + 1):
                px, py = float(c), float(r)
                b0 = ((y1 - y2) * (px - x2) + (x2 - x1) * (py - y2)) / den
                b1 = ((y2 - y0) * (px - x2) + (x0 - x2) * (py - y2)) / den
                b2 = 1.0 - b0 - b1
                if b0 > 1e-9 and b1 > 1e-9 and b2 > 1e-9:
                    count[r, c] += 1
                d = 0.0
                if b0 < 0.0 or b1 < 0.0 or b2 < 0.0:
                    # clamp onto the triangle: the closest point of the three edges
                    best = 1e30
                    bb0, bb1, bb2 = 0.0, 0.0, 0.0
                    for e in range(3):
                        ax, ay = tri[f, e, 0], tri[f, e, 1]
                        bx, by = tri[f, (e + 1) % 3, 0], tri[f, (e + 1) % 3, 1]
                        ex, ey = bx - ax, by - ay
                        ll = ex * ex + ey * ey
                        t = 0.0 if ll == 0.0 else ((px - ax) * ex + (py - ay) * ey) / ll
                        t = min(1.0, max(0.0, t))
                        qx, qy = ax + t * ex, ay + t * ey
                        dd = (qx - px) ** 2 + (qy - py) ** 2
                        if dd < best:
                            best = dd
                            bb0, bb1, bb2 = 0.0, 0.0, 0.0
                            if e == 0:
                                bb0, bb1 = 1.0 - t, t
                            elif e == 1:
                                bb1, bb2 = 1.0 - t, t
                            else:
                                bb2, bb0 = 1.0 - t, t
                    d = np.sqrt(best)
                    if d >= 0.75:
                        continue
                    b0, b1, b2 = bb0, bb1, bb2
                if d < dist[r, c]:
                    dist[r, c] = d
                    face[r, c] = f
                    bary[r, c, 0] = b0
                    bary[r, c, 1] = b1
                    bary[r, c, 2] = b2


@numba.njit(cache=True, nogil=True)
def hit_sums(texel, uv, weight, factor, image, out):  # pragma: no cover - compiled
    """out[t, k, ch] += factor[m, k] · weight[m, ch % 3] · bilinear(image, uv[m])[ch] for every
    hit m of texel t: `shprobe.lightmaps.encode.hit_sums_numpy`'s sums, one pass and no
    temporaries. image (H, W, C) with clamp-to-edge bilinear taps at texel centres."""
    h, w, nc = image.shape
    nk = factor.shape[1]
    for m in range(texel.shape[0]):
        x = min(max(uv[m, 0] * w - 0.5, 0.0), w - 1.0)
        y = min(max(uv[m, 1] * h - 0.5, 0.0), h - 1.0)
        x0 = min(int(np.floor(x)), max(w - 2, 0))
        y0 = min(int(np.floor(y)), max(h - 2, 0))
        x1, y1 = min(x0 + 1, w - 1), min(y0 + 1, h - 1)
        fx, fy = x - x0, y - y0
        t = texel[m]
        for ch in range(nc):
            v = ((image[y0, x0, ch] * (1 - fx) + image[y0, x1, ch] * fx) * (1 - fy)
                 + (image[y1, x0, ch] * (1 - fx) + image[y1, x1, ch] * fx) * fy)
            v *= weight[m, ch % 3]
            for k in range(nk):
                out[t, k, ch] += factor[m, k] * v


@numba.njit(cache=True, nogil=True, inline="always")
def _y9(x, y, z, o):  # pragma: no cover - compiled
    """Real SH l ≤ 2, shprobe's convention (as shprobe.sh's unrolled kernel)."""
    o[0] = 0.28209479177387814
    p1 = 0.48860251190291987 * z
    o[2] = p1
    o[6] = 1.9364916731037085 * z * p1 - 0.31539156525252
    o[3] = 0.4886025119029199 * x
    o[1] = 0.4886025119029199 * y
    q = 1.0925484305920792 * z
    o[7] = q * x
    o[5] = q * y
    o[8] = 0.5462742152960396 * (x * x - y * y)
    o[4] = 0.5462742152960396 * (x * y + y * x)


@numba.njit(cache=True, nogil=True)
def blocked_sums(dt, dw, below, f, face_normals, sky, wt, direct_sh, direct_e, half,
                 front, back):  # pragma: no cover - compiled
    """The control variate's corrections over a tile's rays (the NumPy reference:
    `shprobe.lightmaps.gather.blocked_sums_numpy`): for every blocked ray (a hit, or
    below the face) −c · y_k(tangent dir) · L_sky(world dir) into direct_sh, −c · cos θ · L_sky
    into direct_e and half[s % 2] (× 2), c = wt[p, s] the ray's weight; front[p, s] marks
    front-face hits, back[p] the share of back-face hits and rays below the face."""
    n, s_count = f.shape
    nc = sky.shape[1]
    yt = np.empty(9)
    yw = np.empty(9)
    lsky = np.empty(nc)
    for p in range(n):
        nback = 0
        for s in range(s_count):
            hit = f[p, s] >= 0
            bf = False
            if hit:
                k = f[p, s]
                d = (dw[p, s, 0] * face_normals[k, 0] + dw[p, s, 1] * face_normals[k, 1]
                     + dw[p, s, 2] * face_normals[k, 2])
                bf = d > 0
            bl = below[p, s]
            front[p, s] = hit and not bf and not bl
            if bf or bl:
                nback += 1
            if not (hit or bl):
                continue
            _y9(dw[p, s, 0], dw[p, s, 1], dw[p, s, 2], yw)
            _y9(dt[p, s, 0], dt[p, s, 1], dt[p, s, 2], yt)
            for ch in range(nc):
                acc = 0.0
                for j in range(9):
                    acc += yw[j] * sky[j, ch]
                lsky[ch] = acc
            cz = dt[p, s, 2]
            c = wt[p, s]
            h = s % 2
            for ch in range(nc):
                lv = lsky[ch]
                for k2 in range(9):
                    direct_sh[p, k2, ch] -= c * yt[k2] * lv
                direct_e[p, ch] -= c * lv * cz
                half[h, p, ch] -= 2.0 * c * lv * cz
        back[p] = nback / s_count


@numba.njit(cache=True, nogil=True)
def hit_sums_sh(texel, uv, weight, dirs, image, out):  # pragma: no cover - compiled
    """`hit_sums` with factor = the 9 real SH (l ≤ 2) of each hit's tangent-frame
    direction, evaluated on the fly (no (M, 9) table)."""
    h, w, nc = image.shape
    y = np.empty(9)
    for m in range(texel.shape[0]):
        x = min(max(uv[m, 0] * w - 0.5, 0.0), w - 1.0)
        yy = min(max(uv[m, 1] * h - 0.5, 0.0), h - 1.0)
        x0 = min(int(np.floor(x)), max(w - 2, 0))
        y0 = min(int(np.floor(yy)), max(h - 2, 0))
        x1, y1 = min(x0 + 1, w - 1), min(y0 + 1, h - 1)
        fx, fy = x - x0, yy - y0
        _y9(np.float64(dirs[m, 0]), np.float64(dirs[m, 1]), np.float64(dirs[m, 2]), y)
        t = texel[m]
        for ch in range(nc):
            v = ((image[y0, x0, ch] * (1 - fx) + image[y0, x1, ch] * fx) * (1 - fy)
                 + (image[y1, x0, ch] * (1 - fx) + image[y1, x1, ch] * fx) * fy)
            v *= weight[m, ch % 3]
            for k in range(9):
                out[t, k, ch] += y[k] * v
