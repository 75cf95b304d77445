"""numba kernels of the Radiance RGBE decoder and of the half step added to OpenImageIO's decode
(imported lazily: numba is slow to import).

One pass per scanline: the RLE (flat, old-style repeat markers, new-style per-channel runs)
is decoded into a one-row byte buffer, which is turned into float RGB at once,
(m + 0.5) · 2^(e − 136) as Radiance's colr_color, no (H, W, 4) byte image in between.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def _decode_row(buf, pos, row):  # pragma: no cover - compiled
    """Decode one scanline from ``buf[pos:]`` into ``row`` (W, 4) uint8.

    Returns (status, position after the row): status 0 when the row is done, 1 when ``buf``
    ends inside it (more data, or truncated), 2 for corrupt data. Old-style repeat markers
    refer only to the current row, so decoding can stop and resume at any row boundary.
    """
    w = row.shape[0]
    n = buf.shape[0]
    if pos + 4 > n:
        return 1, pos
    if 8 <= w < 32768 and buf[pos] == 2 and buf[pos + 1] == 2 and buf[pos + 2] < 128:
        # new-style RLE: four channel planes
        if buf[pos + 2] * 256 + buf[pos + 3] != w:
            return 2, pos
        pos += 4
        for c in range(4):
            x = 0
            while x < w:
                if pos >= n:
                    return 1, pos
                cnt = int(buf[pos])
                pos += 1
                if cnt > 128:
                    cnt -= 128
                    if x + cnt > w:
                        return 2, pos
                    if pos >= n:
                        return 1, pos
                    v = buf[pos]
                    pos += 1
                    for k in range(cnt):
                        row[x + k, c] = v
                else:
                    if cnt == 0 or x + cnt > w:
                        return 2, pos
                    if pos + cnt > n:
                        return 1, pos
                    for k in range(cnt):
                        row[x + k, c] = buf[pos + k]
                    pos += cnt
                x += cnt
    else:
        # flat pixels, with old-style repeat markers (1, 1, 1, n)
        x = 0
        shift = 0
        while x < w:
            if pos + 4 > n:
                return 1, pos
            r, g, b, e = buf[pos], buf[pos + 1], buf[pos + 2], buf[pos + 3]
            pos += 4
            if r == 1 and g == 1 and b == 1:
                if x == 0:
                    return 2, pos
                cnt = int(e) << shift
                if x + cnt > w:
                    return 2, pos
                for k in range(cnt):
                    for c in range(4):
                        row[x + k, c] = row[x - 1, c]
                x += cnt
                shift += 8
            else:
                row[x, 0] = r
                row[x, 1] = g
                row[x, 2] = b
                row[x, 3] = e
                x += 1
                shift = 0
    return 0, pos


@numba.njit(cache=True)
def decode_rgbe(buf, pos, out, scale):  # pragma: no cover - compiled
    """Decode scanlines from ``buf[pos:]`` (uint8) into ``out`` (rows, n2, 3) float32;
    ``scale[e]`` = 2^(e − 136) as float32 (0 for e = 0).

    Returns (status, rows decoded, position after the last whole row): status 0 when every
    row of ``out`` is done, 1 when ``buf`` ends inside a row (more data, or truncated), 2 for
    corrupt data.
    """
    h, w = out.shape[0], out.shape[1]
    row = np.zeros((w, 4), dtype=np.uint8)
    half = np.float32(0.5)
    for y in range(h):
        status, end = _decode_row(buf, pos, row)
        if status != 0:
            return status, y, pos
        pos = end
        for x in range(w):
            f = scale[row[x, 3]]
            if f == 0:
                out[y, x, 0] = 0
                out[y, x, 1] = 0
                out[y, x, 2] = 0
            else:
                for c in range(3):
                    out[y, x, c] = (np.float32(row[x, c]) + half) * f
    return 0, h, pos


@numba.njit(cache=True, fastmath=True)
def rgbe_row_sums(buf, pos, sums, weights, scale):  # pragma: no cover - compiled
    """Decode scanlines from ``buf[pos:]`` and reduce each at once, while it is in cache:
    ``sums[y, m, c]`` = Σ_x ``weights[m, x]`` · L(y, x, c), L = (m + 0.5) · 2^(e − 136) as
    `decode_rgbe` makes it (float32, exact), products and sums in float32 as a float32
    matrix product makes them (any order: fastmath, SIMD lanes). ``sums`` (rows, M, 3)
    float64, ``weights`` (M, W) float32.

    Returns (status, rows done, position after the last whole row) as `decode_rgbe`.
    """
    h, nm, w = sums.shape[0], weights.shape[0], weights.shape[1]
    row = np.zeros((w, 4), dtype=np.uint8)
    lin = np.empty((3, w), dtype=np.float32)
    half = np.float32(0.5)
    for y in range(h):
        status, end = _decode_row(buf, pos, row)
        if status != 0:
            return status, y, pos
        pos = end
        for c in range(3):
            lc = lin[c]
            for x in range(w):
                lc[x] = (np.float32(row[x, c]) + half) * scale[row[x, 3]]
        for m in range(nm):
            wm = weights[m]
            for c in range(3):
                lc = lin[c]
                s = np.float32(0.0)
                for x in range(w):
                    s += wm[x] * lc[x]
                sums[y, m, c] = s
    return 0, h, pos


@numba.njit(cache=True)
def half_step(px, bits, table):  # pragma: no cover - compiled
    """OpenImageIO's m · 2^k plus Radiance's half step 0.5 · 2^k, k from the largest channel's
    float32 exponent (``table[E]`` = 2^(E − 135)), in place."""
    for i in range(px.shape[0]):
        best = 0
        for c in range(1, px.shape[1]):
            if px[i, c] > px[i, best]:
                best = c
        v = px[i, best]
        if v > 0:
            e = (bits[i, best] >> 23) & 0xFF
            if e > 0:
                step = table[e]
            else:  # subnormal float32
                step = np.float32(math.ldexp(0.5, math.frexp(v)[1] - 8))
            for c in range(px.shape[1]):
                px[i, c] += step
