"""numba kernel for [`shprobe.sh.sh_basis`][shprobe.sh.sh_basis] above the unrolled degrees
(imported lazily; compiled once, cached on disk).

Same normalised recurrence as ``shprobe.sh.sh_basis_numpy`` (see the ``shprobe.sh`` module
docstring), run per direction with the result written straight into the output row, shaped
for speed:

- the interior step is P̄_lm = A_lm z P̄_{l−1,m} − AB_lm P̄_{l−2,m} with A = a, AB = a·b
  precomputed, so the loop-carried chain is one fused multiply-add (``fastmath={"contract"}``)
  instead of multiply, subtract, multiply;
- four directions go through the loops together (rows of ≤ ``FOUR_MAX_ROW_BYTES``): four
  independent chains per step sharing each table load and index; for longer rows one
  direction at a time with the columns m run two at a time (m, m+1) through the same l loop;
- an output larger than L2 is computed in blocks into a small buffer, each copied out in one
  sequential pass (four rows written in place at once, column by column, scatter stores
  that the store prefetching does not follow into memory not in the cache) — except a
  *fresh* output (just allocated by ``sh_basis``) whose four rows take ≤ 40 KiB: its pages
  are zeroed by the kernel as the stores reach them, and the copy costs more than the
  scatter there;
- the arithmetic is done in the type of the tables (float32 tables for float32 output up to
  the degree where P̄ could overflow float32, see ``shprobe.sh.basis``);
- an output much larger than the caches is written with streaming (non-temporal) stores:
  rows are computed in blocks into a small buffer that stays in L1/L2, and each block, one
  contiguous span of the output, is copied out in aligned 64-byte non-temporal stores. That
  skips reading every output line into the cache before overwriting it (the read for
  ownership), half the memory traffic of a kernel that writes gigabytes.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

#: Rows of at most this many bytes are computed four directions at a time (four independent
#: recurrence chains sharing each table load); longer rows one at a time, with two columns
#: in flight.
FOUR_MAX_ROW_BYTES = 65536
#: Outputs of at most this many bytes (they stay in L2), and rows over
#: ``FOUR_MAX_ROW_BYTES``, are written in place.
IN_PLACE_MAX_BYTES = 2 << 20
#: Larger outputs are computed in blocks of about this many bytes (at least four rows) into a
#: buffer that stays in L1, each block then copied out in one sequential pass, with plain or
#: streaming stores: four rows written in place at once, column by column, scatter stores
#: over memory not in the cache, which the store prefetchers do not follow (a fresh array's
#: pages, just zeroed by the kernel, included).
BUF_BYTES = 16384
#: A fresh output (``sh_rows(..., fresh=True)``) is written in place when four of its rows
#: take at most this many bytes (float64 to lmax 34, float32 to lmax 49). Its huge pages are
#: zeroed by the kernel at the first store into each. Allocating calls against sphericart's
#: (process CPU, per-round medians, AMD EPYC, 1 MiB L2): float64 in place 0.86–0.92 at lmax
#: 10–34, through the buffer 0.96–1.12; float32 in place 0.67–0.83 at lmax 40–48
#: (docs/benchmarks.md, ``bench/bench_sh.py``). On an Intel box float64 in place was
#: 1.05–1.08× the buffer at lmax 16–24: float32 gains there too, float64 about breaks even.
FRESH_FOUR_MAX_BYTES = 40 << 10


@intrinsic
def _stream64(typingctx, dst, di, src, si):
    """dst[di : di + w] = src[si : si + w], w = 64 bytes / itemsize, as one non-temporal
    64-byte store (1-D C-contiguous arrays of one float type
    &dst[di] 64-byte aligned)."""
    sig = types.void(dst, di, src, si)

    def codegen(context, builder, signature, args):
        lt = context.get_value_type(signature.args[0].dtype)
        vt = ir.VectorType(lt, 64 // context.get_abi_sizeof(lt))
        d = context.make_array(signature.args[0])(context, builder, args[0])
        s = context.make_array(signature.args[2])(context, builder, args[2])
        sp = builder.bitcast(builder.gep(s.data, [args[3]]), vt.as_pointer())
        dp = builder.bitcast(builder.gep(d.data, [args[1]]), vt.as_pointer())
        v = builder.load(sp, align=context.get_abi_sizeof(lt))
        store = builder.store(v, dp, align=64)
        store.set_metadata("nontemporal",
                           builder.module.add_metadata([ir.Constant(ir.IntType(32), 1)]))
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _fence(typingctx):
    """A sequentially consistent fence (orders the streaming stores before later accesses)."""

    def codegen(context, builder, signature, args):
        builder.fence("seq_cst")
        return context.get_dummy_value()

    return types.void(), codegen


@nb.njit(inline="always")
def _stream_copy(dst, d0, src, n, a0):  # pragma: no cover - compiled
    """dst[d0 : d0 + n] = src[:n]; flat index j of dst is 64-byte aligned iff j ≡ a0 (mod w)."""
    w = 64 // dst.itemsize
    j = 0
    while j < n and (d0 + j - a0) % w != 0:
        dst[d0 + j] = src[j]
        j += 1
    while j + w <= n:
        _stream64(dst, d0 + j, src, j)
        j += w
    while j < n:
        dst[d0 + j] = src[j]
        j += 1


@nb.njit(inline="always")
def stream_rows(kern, dirs, out, a0):  # pragma: no cover - compiled
    """out = kern's rows of dirs, computed ``BUF_BYTES`` at a time into a buffer that stays in
    L1 and copied out with streaming stores (``_stream_copy``; flat index j of ``out`` is
    64-byte aligned iff j ≡ a0); ``kern(dirs, out)`` fills rows in place (the generated
    unrolled kernels, ``shprobe.sh._kernels_unrolled``, whose ``*_stream`` variants inline this)."""
    n = dirs.shape[0]
    K = out.shape[1]
    B = max(16, BUF_BYTES // (K * out.itemsize))
    buf = np.empty((min(B, n), K), out.dtype)
    flat_buf = buf.reshape(-1)
    flat = out.reshape(-1)
    for i0 in range(0, n, B):
        cnt = min(B, n - i0)
        kern(dirs[i0:i0 + cnt], buf[:cnt])
        _stream_copy(flat, i0 * K, flat_buf, cnt * K, a0)
    _fence()


@nb.njit(inline="always")
def _column(out, i, m, lo, hi, z, c, s, R, o, p1, p2):  # pragma: no cover - compiled
    """Column m from l = lo to hi − 1, given P̄_{lo−1,m} = p1, P̄_{lo−2,m} = p2; its
    (A, AB) pairs from R[o] on."""
    for l in range(lo, hi):
        k = l * (l + 1)
        p = R[o] * z * p1 - R[o + 1] * p2
        o += 2
        out[i, k + m] = p * c
        out[i, k - m] = p * s
        p2 = p1
        p1 = p


@nb.njit(inline="always")
def _row(out, i, x, y, z, lmax, R, d0, d1):  # pragma: no cover - compiled
    """out[i, :] = y_k(x, y, z) (x, y, z already in the arithmetic type, R's)."""
    T = R.dtype
    r2 = T.type(np.sqrt(2.0))
    one = T.type(1.0)
    zero = T.type(0.0)
    # m = 0: P̄_l0 straight into y_l0
    out[i, 0] = d0[0]
    p1 = d1[1] * z
    out[i, 2] = p1
    _column(out, i, 0, 2, lmax + 1, z, one, one, R, 0, p1, d0[0])  # k ± 0: both p
    # m > 0 in pairs; (c, s) = √2 (x + iy)^m
    c = r2
    s = zero
    m = 1
    o = 2 * (lmax - 1)  # start of column 1 in R
    while m <= lmax:
        c, s = x * c - y * s, x * s + y * c
        k = m * (m + 1)
        out[i, k + m] = d0[m] * c
        out[i, k - m] = d0[m] * s
        if m == lmax:
            break
        a1 = d1[m + 1] * z
        k = (m + 1) * (m + 2)
        out[i, k + m] = a1 * c
        out[i, k - m] = a1 * s
        c2, s2 = x * c - y * s, x * s + y * c
        out[i, k + m + 1] = d0[m + 1] * c2
        out[i, k - m - 1] = d0[m + 1] * s2
        if m + 1 == lmax:
            break
        b1 = d1[m + 2] * z
        k = (m + 2) * (m + 3)
        ob = o + 2 * (lmax - m - 1)  # start of column m + 1
        a2 = a1
        a1 = R[o] * z * a2 - R[o + 1] * d0[m]
        o += 2
        out[i, k + m] = a1 * c
        out[i, k - m] = a1 * s
        out[i, k + m + 1] = b1 * c2
        out[i, k - m - 1] = b1 * s2
        b2 = d0[m + 1]
        mb = m + 1
        for l in range(m + 3, lmax + 1):
            k = l * (l + 1)
            pa = R[o] * z * a1 - R[o + 1] * a2
            pb = R[ob] * z * b1 - R[ob + 1] * b2
            o += 2
            ob += 2
            out[i, k + m] = pa * c
            out[i, k - m] = pa * s
            out[i, k + mb] = pb * c2
            out[i, k - mb] = pb * s2
            a2 = a1
            a1 = pa
            b2 = b1
            b1 = pb
        c = c2
        s = s2
        o = ob  # column m + 1 done: ob is the start of column m + 2
        m += 2


@nb.njit(inline="always")
def _four(dirs, i, out, r, lmax, R, d0, d1):  # pragma: no cover - compiled
    """out[r : r+4, :] = y_k(dirs[i : i+4]): four directions through the same loops, four
    independent recurrence chains per step, one table load for the four."""
    T = R.dtype
    r2 = T.type(np.sqrt(2.0))
    zero = T.type(0.0)
    x0 = T.type(dirs[i, 0])
    y0 = T.type(dirs[i, 1])
    z0 = T.type(dirs[i, 2])
    x1 = T.type(dirs[i + 1, 0])
    y1 = T.type(dirs[i + 1, 1])
    z1 = T.type(dirs[i + 1, 2])
    x2 = T.type(dirs[i + 2, 0])
    y2 = T.type(dirs[i + 2, 1])
    z2 = T.type(dirs[i + 2, 2])
    x3 = T.type(dirs[i + 3, 0])
    y3 = T.type(dirs[i + 3, 1])
    z3 = T.type(dirs[i + 3, 2])
    # m = 0
    q = d0[0]
    out[r, 0] = q
    out[r + 1, 0] = q
    out[r + 2, 0] = q
    out[r + 3, 0] = q
    e = d1[1]
    a0 = e * z0
    a1 = e * z1
    a2 = e * z2
    a3 = e * z3
    out[r, 2] = a0
    out[r + 1, 2] = a1
    out[r + 2, 2] = a2
    out[r + 3, 2] = a3
    b0 = q
    b1 = q
    b2 = q
    b3 = q
    o = 0
    for l in range(2, lmax + 1):
        k = l * (l + 1)
        A = R[o]
        AB = R[o + 1]
        o += 2
        p0 = A * z0 * a0 - AB * b0
        p1 = A * z1 * a1 - AB * b1
        p2 = A * z2 * a2 - AB * b2
        p3 = A * z3 * a3 - AB * b3
        out[r, k] = p0
        out[r + 1, k] = p1
        out[r + 2, k] = p2
        out[r + 3, k] = p3
        b0 = a0
        b1 = a1
        b2 = a2
        b3 = a3
        a0 = p0
        a1 = p1
        a2 = p2
        a3 = p3
    c0 = r2
    c1 = r2
    c2 = r2
    c3 = r2
    s0 = zero
    s1 = zero
    s2 = zero
    s3 = zero
    for m in range(1, lmax + 1):
        c0, s0 = x0 * c0 - y0 * s0, x0 * s0 + y0 * c0
        c1, s1 = x1 * c1 - y1 * s1, x1 * s1 + y1 * c1
        c2, s2 = x2 * c2 - y2 * s2, x2 * s2 + y2 * c2
        c3, s3 = x3 * c3 - y3 * s3, x3 * s3 + y3 * c3
        k = m * (m + 1)
        q = d0[m]
        out[r, k + m] = q * c0
        out[r, k - m] = q * s0
        out[r + 1, k + m] = q * c1
        out[r + 1, k - m] = q * s1
        out[r + 2, k + m] = q * c2
        out[r + 2, k - m] = q * s2
        out[r + 3, k + m] = q * c3
        out[r + 3, k - m] = q * s3
        if m == lmax:
            break
        e = d1[m + 1]
        k = (m + 1) * (m + 2)
        a0 = e * z0
        a1 = e * z1
        a2 = e * z2
        a3 = e * z3
        out[r, k + m] = a0 * c0
        out[r, k - m] = a0 * s0
        out[r + 1, k + m] = a1 * c1
        out[r + 1, k - m] = a1 * s1
        out[r + 2, k + m] = a2 * c2
        out[r + 2, k - m] = a2 * s2
        out[r + 3, k + m] = a3 * c3
        out[r + 3, k - m] = a3 * s3
        b0 = q
        b1 = q
        b2 = q
        b3 = q
        for l in range(m + 2, lmax + 1):
            k = l * (l + 1)
            A = R[o]
            AB = R[o + 1]
            o += 2
            p0 = A * z0 * a0 - AB * b0
            p1 = A * z1 * a1 - AB * b1
            p2 = A * z2 * a2 - AB * b2
            p3 = A * z3 * a3 - AB * b3
            out[r, k + m] = p0 * c0
            out[r, k - m] = p0 * s0
            out[r + 1, k + m] = p1 * c1
            out[r + 1, k - m] = p1 * s1
            out[r + 2, k + m] = p2 * c2
            out[r + 2, k - m] = p2 * s2
            out[r + 3, k + m] = p3 * c3
            out[r + 3, k - m] = p3 * s3
            b0 = a0
            b1 = a1
            b2 = a2
            b3 = a3
            a0 = p0
            a1 = p1
            a2 = p2
            a3 = p3


@nb.njit(inline="always")
def _rows(dirs, i0, cnt, out, r0, lmax, R, d0, d1, four):  # pragma: no cover - compiled
    """out[r0 + j] = y_k(dirs[i0 + j]) for j < cnt, four at a time if ``four``."""
    T = R.dtype
    j = 0
    if four:
        while j + 4 <= cnt:
            _four(dirs, i0 + j, out, r0 + j, lmax, R, d0, d1)
            j += 4
    while j < cnt:
        i = i0 + j
        _row(out, r0 + j, T.type(dirs[i, 0]), T.type(dirs[i, 1]), T.type(dirs[i, 2]), lmax,
             R, d0, d1)
        j += 1


@nb.njit(inline="always")
def _copy(dst, d0, src, n):  # pragma: no cover - compiled
    """dst[d0 : d0 + n] = src[:n] with plain stores (one sequential stream)."""
    dst[d0:d0 + n] = src[:n]


@nb.njit(cache=True, nogil=True, fastmath={"contract"}, error_model="numpy")
def sh_rows(dirs, lmax, R, d0, d1, out, stream_a0, fresh):  # pragma: no cover - compiled
    """out[i, k] = y_k(dirs[i]) for dirs (N, 3), out (N, (lmax+1)²), lmax ≥ 2.

    ``R``: the interior recurrence's (a_lm, a_lm·b_lm) pairs, column by column (m = 0, 1, …;
    l = m+2 … lmax within a column), so that every column reads one sequential stream;
    ``d0[m]`` = P̄_mm, ``d1[l]`` = √(2l+1) P̄_{l−1,l−1} (so P̄_{l,l−1} = d1[l] z). The
    arithmetic is done in R's type. ``stream_a0`` < 0: plain stores; otherwise streaming
    stores, and flat output index j is 64-byte aligned iff j ≡ stream_a0 (mod 64/itemsize).
    ``fresh``: ``out`` was just allocated (no page of it touched yet).

    Rows of ≤ ``FOUR_MAX_ROW_BYTES`` are computed four directions at a time. With plain
    stores, outputs of ≤ ``IN_PLACE_MAX_BYTES``, rows over ``FOUR_MAX_ROW_BYTES`` and fresh
    outputs whose four rows take ≤ ``FRESH_FOUR_MAX_BYTES`` are written in place; otherwise
    rows are computed in blocks into a small buffer and each block, one contiguous span of
    the output, is copied out in one sequential pass: with streaming stores, or plain.
    """
    n = dirs.shape[0]
    K = out.shape[1]
    row_bytes = K * out.itemsize
    four = row_bytes <= FOUR_MAX_ROW_BYTES
    if stream_a0 < 0 and (not four or n * row_bytes <= IN_PLACE_MAX_BYTES
                          or (fresh and 4 * row_bytes <= FRESH_FOUR_MAX_BYTES)):
        _rows(dirs, 0, n, out, 0, lmax, R, d0, d1, four)
        return
    B = max(4, BUF_BYTES // row_bytes // 4 * 4)  # rows per block
    B = min(B, (n + 3) // 4 * 4)
    buf = np.empty((B, K), out.dtype)
    flat_buf = buf.reshape(-1)
    flat = out.reshape(-1)
    for i0 in range(0, n, B):
        cnt = min(B, n - i0)
        _rows(dirs, i0, cnt, buf, 0, lmax, R, d0, d1, four)
        if stream_a0 < 0:
            _copy(flat, i0 * K, flat_buf, cnt * K)
        else:
            _stream_copy(flat, i0 * K, flat_buf, cnt * K, stream_a0)
    if stream_a0 >= 0:
        _fence()
