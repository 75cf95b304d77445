"""The NumPy decoder of whole Radiance RGBE images: no compiled kernel, so no start-up cost.

The compiled decoder (`shprobe.probes._kernels_rgbe`) is about 5× faster per pixel, but its first
call in a process costs 0.6–0.9 s (numba's import, the scipy.linalg it imports and its typing
set-up) against 0.1–0.15 s for NumPy to decode a whole 2048×1024 probe.
`shprobe.probes.codecs.read_rgbe` takes this path for images up to
``RGBE_NUMPY_MAX_PIXELS`` and the compiled one above (and for whatever this one declines). Both
give (m + 0.5) · 2^(e − 136), bit for bit.

New-style RLE (Radiance's ``fwritecolrs``): each scanline is a header ``2 2 W/256 W%256`` and
four channel planes, each a sequence of packets — a count byte c > 128 then one byte repeated
c − 128 times, or c ≤ 128 then c literal bytes. Packets must be read in order, but the
scanlines need not be: every scanline starts with its header, so the candidate starts are
found by one search, all of them parsed in lockstep (one NumPy step per packet of the longest
scanline), and the true ones are the chain that runs from the first byte. The bytes are then
expanded by one ``np.repeat`` per block of rows (count bytes 0 times, literals once, a run's
byte its length).

Declined (``False``; the compiled decoder reads them, or says what is wrong): old-style repeat
markers, rows of mixed kinds, truncated or corrupt data, and scanlines of more than
``MAX_PACKETS`` packets (noise at its least compressible; lockstep is slow there) or more
packet positions than 64 MB holds.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

__all__ = ["MAX_PACKETS", "RGBE_NUMPY_MAX_PIXELS", "decode_rgbe_numpy", "rgbe_scale",
           "rgbe_to_float"]

#: Largest image decoded here by default: above it the compiled kernel's speed (13–20 ms per
#: Mpx against NumPy's ~60) repays its start-up within the one decode (docs/benchmarks.md).
RGBE_NUMPY_MAX_PIXELS = 1 << 22

#: Most packets in one scanline before the lockstep parse gives way to the compiled decoder
#: (its time is one NumPy step per packet of the longest scanline).
MAX_PACKETS = 2048

#: Most recorded packet positions (4 bytes each: 64 MB) before it gives way, for memory.
_MAX_RECORDED = 1 << 24

#: Pixels expanded per ``np.repeat`` (its temporaries stay small and in cache).
_BLOCK_PIXELS = 1 << 16


@lru_cache(maxsize=1)
def rgbe_scale() -> NDArray[np.float32]:
    """2^(e − 136) for each exponent byte e as float32, 0 for e = 0 (Radiance's colr_color; the
    compiled decoder takes it as its table)."""
    e = np.arange(256)
    t = np.where(e > 0, np.ldexp(1.0, e - (128 + 8)), 0.0).astype(np.float32)
    t.flags.writeable = False
    return t


def rgbe_to_float(rgbe: NDArray[np.uint8], out: NDArray[np.float32] | None = None
                  ) -> NDArray[np.float32]:
    """RGBE bytes (..., 4) → float RGB: (m + 0.5) · 2^(e − 136), as Radiance's colr_color
    (writers truncate, so the half step makes the round trip unbiased); in float32 as the
    compiled decoder, exactly (m + 0.5 has 9 significant bits, the scale is a power of two);
    into ``out`` when given."""
    if out is None:
        out = np.empty((*rgbe.shape[:-1], 3), np.float32)
    np.add(rgbe[..., :3], np.float32(0.5), out=out, dtype=np.float32)
    out *= rgbe_scale()[rgbe[..., 3]][..., None]
    return out


def decode_rgbe_numpy(body: NDArray[np.uint8], out: NDArray[np.float32]) -> bool:
    """Decode the pixel data ``body`` into ``out`` (rows, W, 3) float32 in file order
    (`rgbe_to_float`). False (``out`` partly written) where the data is not flat or
    new-style RLE throughout, is truncated or corrupt, or needs more than
    `MAX_PACKETS` packets in a scanline."""
    h, w = out.shape[:2]
    if body.size >= 4 and 8 <= w < 32768 and body[0] == 2 and body[1] == 2 \
            and body[2] < 128:
        rows = _rle_rows(body, h, w)
        if rows is None:
            return False
        _expand(body, rows, w, out)
        return True
    return _flat(body, h, w, out)


def _flat(body: NDArray[np.uint8], h: int, w: int, out: NDArray[np.float32]) -> bool:
    """Uncompressed pixels; False for repeat markers (r = g = b = 1), a row that reads as
    new-style RLE, or too few bytes."""
    if body.size < 4 * h * w:
        return False
    px = body[:4 * h * w].reshape(h, w, 4)
    if 8 <= w < 32768:  # a row starting 2 2 c (c < 128) is new-style RLE to Radiance
        first = px[:, 0]
        if np.any((first[:, 0] == 2) & (first[:, 1] == 2) & (first[:, 2] < 128)):
            return False
    if np.any((px[..., 0] == 1) & (px[..., 1] == 1) & (px[..., 2] == 1)):
        return False
    rgbe_to_float(px, out)
    return True


def _rle_rows(body: NDArray[np.uint8], h: int, w: int
              ) -> tuple[NDArray[np.int64], NDArray[np.int64]] | None:
    """(start of each scanline and the end of the last, (packets, h) count-byte positions
    padded with a position past the data) of ``h`` new-style RLE scanlines, or None."""
    # h scanlines fill at most h · (4 + 8w) bytes (a packet costs at most 2 bytes a pixel):
    # bytes past that are never read, so trailing data costs neither time nor memory
    n = min(int(body.size), h * (4 + 8 * w))
    cand = _candidates(body[:n], w, 4 * h + 1024)
    if cand is None or cand.size == 0 or cand[0] != 0:
        return None
    # parse from every candidate at once: p = position, x = pixels done in channel ch
    c = cand.size
    pos = cand + 4
    x = np.zeros(c, np.int64)
    ch = np.zeros(c, np.int64)
    live = np.ones(c, bool)
    steps = []
    act = np.arange(c)
    while act.size:
        if len(steps) == MAX_PACKETS or len(steps) * c > _MAX_RECORDED:
            return None
        p = np.minimum(pos[act], n - 1)
        rec = np.full(c, n, np.int32 if n < 1 << 31 else np.int64)
        rec[act] = p
        steps.append(rec)
        v = body[p].astype(np.int64)
        run = v > 128
        cnt = np.where(run, v - 128, v)
        xa = x[act] + cnt
        nxt = p + np.where(run, 2, 1 + v)
        bad = (cnt == 0) | (xa > w) | (pos[act] >= n) | (nxt > n)
        done = xa == w
        pos[act] = nxt
        x[act] = np.where(done, 0, xa)
        ch[act] += done
        live[act[bad]] = False
        act = act[~bad & (ch[act] < 4)]
    # the true scanlines: the chain of live candidates, each ending where the next starts
    at = np.minimum(np.searchsorted(cand, pos), c - 1)
    follows = np.where(live & (cand[at] == pos), at, -1).tolist()
    chain = [0] * h
    k = 0
    for y in range(1, h):
        k = follows[k]
        if k < 0:
            return None
        chain[y] = k
    if not live[k]:
        return None
    starts = np.append(cand[chain], pos[k])
    return starts, np.stack(steps)[:, chain]


def _candidates(body: NDArray[np.uint8], w: int, most: int) -> NDArray[np.int64] | None:
    """Positions of the scanline header ``2 2 W/256 W%256`` in ``body``, searched a MB at a
    time; None past ``most`` of them."""
    hi, lo = w >> 8, w & 255
    found, total = [], 0
    last = body.size - 3
    for a in range(0, max(0, last), 1 << 20):
        b = min(last, a + (1 << 20))
        hit = np.flatnonzero((body[a:b] == 2) & (body[a + 1:b + 1] == 2)
                             & (body[a + 2:b + 2] == hi) & (body[a + 3:b + 3] == lo)) + a
        total += hit.size
        if total > most:
            return None
        found.append(hit)
    return np.concatenate(found) if found else None


def _expand(body: NDArray[np.uint8], rows: tuple[NDArray[np.int64], NDArray[np.int64]],
            w: int, out: NDArray[np.float32]) -> None:
    starts, packets = rows
    h = out.shape[0]
    block = max(1, _BLOCK_PIXELS // w)
    for y0 in range(0, h, block):
        y1 = min(h, y0 + block)
        a, b = int(starts[y0]), int(starts[y1])
        seg = body[a:b]
        reps = np.ones(b - a, np.intp)
        pk = packets[:, y0:y1].ravel()
        pk = pk[pk < b] - a  # drop the padding
        reps[pk] = 0  # count bytes
        runs = pk[seg[pk] > 128]
        reps[runs + 1] = seg[runs].astype(np.intp) - 128
        for k in range(4):  # scanline headers
            reps[starts[y0:y1] - a + k] = 0
        data = np.repeat(seg, reps).reshape(y1 - y0, 4, w)
        rgbe_to_float(data.transpose(0, 2, 1), out[y0:y1])

