"""Niantic SPZ files (nianticlabs/spz, its README's "File Format"): read versions 1–4, write
version 3.

Versions 1–3 are one gzip stream: a 16-byte header (magic "NGSP", version, point count, SH
degree, fractional bits, flags, reserved) then, attribute by attribute, positions (24-bit
fixed point, ``fractionalBits`` fraction bits), alphas (sigmoid·255), colours (f_dc·0.15·255
+ 127.5), scales ((log + 10)·16), rotations (v2: x, y, z as (q+1)·127.5; v3+: "smallest
three", 2 bits for the largest component's index and 3 × 10-bit signed magnitudes scaled
by 1/√2) and SH (coefficient-major, channel inner, as round(128·x) + 128). Version 4 has a
32-byte plaintext header and a table of independently zstd-compressed streams in the same
order (reading it needs the ``zstandard`` package).

SPZ stores its data in an RUB frame (x Right, y Up, z Back); the reference trainer's PLY is
RDF. Reading returns the splats in the PLY's frame and writing expects them there: the
conversion between the two is the 180° turn about x
([`shprobe.splats.transform.frame`][shprobe.splats.frame]), SH included, as the spz library's own
``from``/``to`` coordinate options do.
"""

from __future__ import annotations

import gzip
import os
import struct
import zlib

import numpy as np

from ..errors import ShprobeError
from ..limits import check_memory
from .cloud import READ_BYTES_PER_FLOAT, Splats, floats_per_splat, read_bytes
from .conventions import check_degree
from .transform import apply, frame

MAGIC = 0x5053474E
_SQRT1_2 = np.float32(0.7071067811865476)
_COLOR_SCALE = 0.15


def _sh_dim(degree: int) -> int:
    return (degree + 1) ** 2 - 1


def _inflate(z, raw: bytes, size: int, p: str) -> bytes:
    try:
        return z.decompress(raw, size)
    except zlib.error as e:
        raise ShprobeError(f"SPZ gzip stream is damaged or truncated ({e})", p) from None


def _per_splat(version: int, degree: int) -> int:
    """Packed bytes a splat: position, alpha, colour, scales, rotation, SH."""
    return ((6 if version == 1 else 9) + 1 + 3 + 3 + (4 if version >= 3 else 3)
            + 3 * _sh_dim(degree))


def _zstd_streams(raw: bytes, p: str, n_streams: int, toc: int, size: int) -> list[bytes]:
    """The streams of a version-4 file, refused before inflating when their table claims
    more than the ``size`` bytes the header implies."""
    try:
        import zstandard
    except ImportError:
        raise ShprobeError("SPZ version 4 is zstd-compressed: install the 'zstandard' package "
                           "(pip install zstandard) to read it", p) from None
    out, pos = [], toc + 16 * n_streams
    if len(raw) < pos:
        raise ShprobeError("SPZ table of contents is truncated", p)
    total = sum(struct.unpack_from("<QQ", raw, toc + 16 * i)[1] for i in range(n_streams))
    if total != size:
        raise ShprobeError(f"SPZ streams hold {total} bytes, the header implies {size}", p)
    for i in range(n_streams):
        csize, usize = struct.unpack_from("<QQ", raw, toc + 16 * i)
        if pos + csize > len(raw):
            raise ShprobeError("SPZ stream is truncated", p)
        try:
            data = zstandard.ZstdDecompressor().decompress(raw[pos : pos + csize],
                                                           max_output_size=usize)
        except zstandard.ZstdError as e:
            raise ShprobeError(f"SPZ zstd stream is damaged ({e})", p) from None
        if len(data) != usize:
            raise ShprobeError("SPZ stream is not the size its table says", p)
        out.append(data)
        pos += csize
    return out


def read(path: str | os.PathLike[str]) -> Splats:
    """An SPZ file's splats, in the PLY's (RDF) frame."""
    p = os.fspath(path)
    raw = read_bytes(p)
    if raw[:4] == b"NGSP":  # version 4: plaintext header, zstd streams
        if len(raw) < 32:
            raise ShprobeError("SPZ header is truncated", p)
        _, version, n, degree, fbits, _flags, n_streams, toc = struct.unpack_from(
            "<IIIBBBBI", raw)
        _check_header(p, version, n, degree, fbits)
        if n_streams < 5:
            raise ShprobeError(f"SPZ has {n_streams} streams, expected 6", p)
        body = b"".join(_zstd_streams(raw, p, n_streams, toc, n * _per_splat(version, degree)))
    elif raw[:2] == b"\x1f\x8b":
        # the header is inflated first and checked, so that a small file cannot inflate to
        # gigabytes unasked; the rest is inflated up to the size the header implies
        z = zlib.decompressobj(16 + zlib.MAX_WBITS)
        data = _inflate(z, raw, 16, p)
        if len(data) < 16:
            raise ShprobeError("SPZ header is truncated", p)
        magic, version, n, degree, fbits, _flags, _ = struct.unpack_from("<IIIBBBB", data)
        if magic != MAGIC:
            raise ShprobeError("not an SPZ file (no NGSP magic inside the gzip stream)", p)
        _check_header(p, version, n, degree, fbits)
        size = n * _per_splat(version, degree)
        body = data[16:] + _inflate(z, z.unconsumed_tail, size, p)
        if len(body) == size and _inflate(z, z.unconsumed_tail, 1, p):
            # a count below the data's would shift every attribute after the positions
            raise ShprobeError(f"SPZ holds more data than its header's {n} splats (the count "
                               "is wrong or the file is not SPZ)", p)
    else:
        raise ShprobeError("not an SPZ file (neither gzip nor NGSP)", p)
    return frame_in(_unpack(p, body, version, n, degree, fbits))


#: ``fractionalBits`` read: 24-bit fixed-point positions keep at least one integer bit and
#: one fraction bit (0 or ≥ 24 would round every position to an integer or to zero).
FRACTIONAL_BITS = (1, 23)


def _check_header(p: str, version: int, n: int, degree: int, fbits: int = 12) -> None:
    if version not in (1, 2, 3, 4):
        raise ShprobeError(f"SPZ version {version} is not supported (1–4)", p)
    lo, hi = FRACTIONAL_BITS
    if version >= 2 and not lo <= fbits <= hi:
        raise ShprobeError(f"SPZ fractionalBits {fbits} is outside {lo}–{hi} (24-bit fixed-"
                           "point positions)", p)
    check_degree(degree, "SPZ holds SH degree", p)
    if n == 0:
        raise ShprobeError("SPZ holds no splats", p)
    check_memory(n * floats_per_splat(degree) * READ_BYTES_PER_FLOAT[".spz"],
                 f"reading {n} splats", p)


def _take(body: bytes, pos: int, size: int, p: str) -> tuple[np.ndarray, int]:
    if pos + size > len(body):
        raise ShprobeError(f"SPZ data is truncated ({len(body)} bytes, the header needs more)",
                           p)
    return np.frombuffer(body, dtype=np.uint8, count=size, offset=pos), pos + size


def _unpack(p: str, body: bytes, version: int, n: int, degree: int, fbits: int) -> Splats:
    d = _sh_dim(degree)
    pos = 0
    if version == 1:
        raw, pos = _take(body, pos, n * 6, p)
        positions = raw.view("<f2").reshape(n, 3).astype(np.float32)
    else:
        raw, pos = _take(body, pos, n * 9, p)
        b = raw.reshape(n, 3, 3).astype(np.int32)
        fixed = b[..., 0] | (b[..., 1] << 8) | (b[..., 2] << 16)
        fixed = np.where(fixed & 0x800000, fixed - (1 << 24), fixed)
        positions = (fixed / float(1 << fbits)).astype(np.float32)
    alphas, pos = _take(body, pos, n, p)
    colors, pos = _take(body, pos, n * 3, p)
    scales, pos = _take(body, pos, n * 3, p)
    rbytes = 4 if version >= 3 else 3
    rot, pos = _take(body, pos, n * rbytes, p)
    sh, pos = _take(body, pos, n * d * 3, p)
    # alphas 0 and 255 would be logits ∓∞: held half a step inside (never a non-finite value)
    a = np.clip(alphas.astype(np.float64), 0.5, 254.5) / 255.0
    opacity = np.log(a / (1.0 - a))
    dc = (colors.reshape(n, 3).astype(np.float32) / 255.0 - 0.5) / _COLOR_SCALE
    shc = np.empty((n, d + 1, 3), dtype=np.float32)
    shc[:, 0] = dc
    shc[:, 1:] = (sh.reshape(n, d, 3).astype(np.float32) - 128.0) / 128.0
    return Splats(positions, scales.reshape(n, 3).astype(np.float32) / 16.0 - 10.0,
                  _unpack_rotations(rot, n, version), opacity.astype(np.float32), shc)


def _unpack_rotations(rot: np.ndarray, n: int, version: int) -> np.ndarray:
    xyzw = np.empty((n, 4), dtype=np.float32)
    if version < 3:
        xyz = rot.reshape(n, 3).astype(np.float32) / 127.5 - 1.0
        xyzw[:, :3] = xyz
        xyzw[:, 3] = np.sqrt(np.maximum(0.0, 1.0 - (xyz * xyz).sum(axis=1)))
    else:
        comp = rot.reshape(n, 4).astype(np.uint32)
        comp = comp[:, 0] | (comp[:, 1] << 8) | (comp[:, 2] << 16) | (comp[:, 3] << 24)
        largest = (comp >> 30).astype(np.int64)
        total = np.zeros(n, dtype=np.float32)
        for i in range(3, -1, -1):
            here = largest != i
            mag = (comp & 511).astype(np.float32)
            neg = ((comp >> 9) & 1).astype(bool)
            v = _SQRT1_2 * mag / np.float32(511)
            v = np.where(neg, -v, v)
            xyzw[:, i] = np.where(here, v, 0.0)
            total += np.where(here, v * v, 0.0)
            comp = np.where(here, comp >> 10, comp)
        xyzw[np.arange(n), largest] = np.sqrt(np.maximum(0.0, 1.0 - total))
    return xyzw[:, [3, 0, 1, 2]]  # (w, x, y, z)


def frame_in(s: Splats) -> Splats:
    """SPZ's RUB frame → the PLY's RDF frame (a 180° turn about x)."""
    return apply(s, frame("spz", "ply"))


def _u8(x: np.ndarray) -> np.ndarray:
    return np.clip(np.round(x), 0, 255).astype(np.uint8)


def _pack_rotations(q_wxyz: np.ndarray) -> np.ndarray:
    q = q_wxyz[:, [1, 2, 3, 0]].astype(np.float64)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    n = q.shape[0]
    largest = np.argmax(np.abs(q), axis=1)
    negate = q[np.arange(n), largest] < 0
    comp = largest.astype(np.uint32)
    for i in range(4):
        here = largest != i
        negbit = ((q[:, i] < 0) ^ negate).astype(np.uint32)
        mag = np.floor(511.0 * np.abs(q[:, i]) / float(_SQRT1_2) + 0.5).astype(np.uint32)
        comp = np.where(here, (comp << 10) | (negbit << 9) | np.minimum(mag, 511), comp)
    return comp.astype("<u4").view(np.uint8).reshape(n, 4)


def pack(s: Splats) -> bytes:
    """The uncompressed version-3 payload (header included) of splats in the PLY's frame."""
    s = apply(s, frame("ply", "spz"))
    n, d = s.count, _sh_dim(s.degree)
    big = float(np.abs(s.positions).max())
    fbits = 12
    while fbits > FRACTIONAL_BITS[0] and big * (1 << fbits) >= (1 << 23) - 1:
        fbits -= 1
    if big * (1 << fbits) >= (1 << 23) - 1:
        raise ShprobeError(f"positions up to {big:.3g} do not fit SPZ's 24-bit fixed point")
    fixed = np.round(s.positions.astype(np.float64) * (1 << fbits)).astype(np.int64)
    fixed &= 0xFFFFFF
    pos = np.stack([fixed & 0xFF, (fixed >> 8) & 0xFF, (fixed >> 16) & 0xFF], axis=-1)
    with np.errstate(over="ignore"):  # a logit below −709: e^−x is inf, the alpha 0
        alphas = _u8(255.0 / (1.0 + np.exp(-s.opacity.astype(np.float64))))
    colors = _u8(s.sh[:, 0].astype(np.float64) * (_COLOR_SCALE * 255.0) + 127.5)
    scales = _u8((s.log_scales.astype(np.float64) + 10.0) * 16.0)
    if s.log_scales.shape[1] == 2:  # 2DGS: SPZ has three scales; the normal axis is flat
        scales = np.concatenate([scales, np.zeros((n, 1), np.uint8)], axis=1)
    sh = _u8(np.round(s.sh[:, 1:].astype(np.float64) * 128.0) + 128.0)
    head = struct.pack("<IIIBBBB", MAGIC, 3, n, s.degree, fbits, 0, 0)
    parts = [head, pos.astype(np.uint8).tobytes(), alphas.tobytes(), colors.tobytes(),
             scales.tobytes(), _pack_rotations(s.rotations).tobytes(),
             sh.reshape(n, d * 3).tobytes()]
    return b"".join(parts)


def write(path: str | os.PathLike[str], s: Splats, overwrite: bool = False) -> None:
    """Write an SPZ (version 3, gzip; all SH at 8 bits) through `shprobe.files`."""
    from ..files import atomic_output

    s.check_finite(os.fspath(path))
    s.check_rotations(os.fspath(path))
    try:
        data = gzip.compress(pack(s), compresslevel=6)
    except ShprobeError as e:
        if e.path:
            raise
        raise ShprobeError(e.message, path) from None
    with atomic_output(path, overwrite) as tmp, open(tmp, "wb") as f:
        f.write(data)
