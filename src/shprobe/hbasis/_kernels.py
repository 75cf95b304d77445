"""numba kernels of the H-basis (imported lazily: importing this module imports numba).

* ``h_rows`` — H¹..Hⁿ (Habel & Wimmer 2010 eq. 8–13) for rows of unit normals.
* ``t_h_c1``, ``t_h_c1_stream``, ``t_h_c3``, ``t_h_any`` — SH (l ≤ 2) → H4/H6 with T_h
  (H&W §4.1; closed form in docs/hbasis.md), touching only its 10 nonzeros, for one channel
  (plain or streaming stores), RGB and any channel count.
  Each row's 9 inputs are loaded before the first store (the output may not alias the input,
  and loading first lets LLVM keep them in registers), and the result is written straight
  into the caller's array: the kernels are memory-bound, moving exactly the bytes they must.

The constants are module globals, which numba folds in at compile time (``cache=True``).

Streaming, non-temporal stores: for an output much
larger than the caches that is written once, they skip reading each output line into the
cache before overwriting it (the read-for-ownership), a third of these memory-bound kernels'
traffic. Only the one-channel float64 kernel streams (``t_h_c1_stream``): its stores are
sequential 8-byte ones, which fill whole lines in the write-combining buffers; the RGB
kernel's interleaved stores and 4-byte float32 stores gained nothing (or lost) when streamed.
[`shprobe.hbasis.basis.sh_to_h`][shprobe.hbasis.sh_to_h] uses it above ``STREAM_MIN_BYTES``; a fence
at the end orders the stores for other threads.
"""

from __future__ import annotations

import math

import numba
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from ..sh._kernels import _fence  # the one fence for streaming stores

C1 = 1.0 / math.sqrt(2.0 * math.pi)  # H¹
C3 = math.sqrt(3.0 / (2.0 * math.pi))  # H², H³, H⁴
C5 = math.sqrt(15.0 / (2.0 * math.pi))  # H⁵; H⁶ uses C5 / 2
C6 = 0.5 * C5

# T_h's nonzeros (docs/hbasis.md §2): 1/√2, √6/4, √2/4, √30/8, −3√10/16
A = 1.0 / math.sqrt(2.0)
B = math.sqrt(6.0) / 4.0
E = math.sqrt(2.0) / 4.0
F = math.sqrt(30.0) / 8.0
G = -3.0 * math.sqrt(10.0) / 16.0


@numba.njit(cache=True)
def h_rows(d, out):  # pragma: no cover - compiled
    """out[i] = (H¹..Hⁿ)(d[i]) for d (N, 3), out (N, n), n = 4 or 6."""
    six = out.shape[1] == 6
    for i in range(d.shape[0]):
        x = d[i, 0]
        y = d[i, 1]
        z = d[i, 2]
        out[i, 0] = C1
        out[i, 1] = -C3 * y
        out[i, 2] = C3 * (2.0 * z - 1.0)
        out[i, 3] = -C3 * x
        if six:
            out[i, 4] = C5 * x * y
            out[i, 5] = C6 * (x * x - y * y)


@intrinsic
def _stream_store(typingctx, arr, idx, val):
    """arr[idx] = val with LLVM's !nontemporal hint (arr: 1-D C-contiguous float array)."""
    sig = types.void(arr, idx, val)

    def codegen(context, builder, signature, args):
        ary = context.make_array(signature.args[0])(context, builder, args[0])
        v = context.cast(builder, args[2], signature.args[2], signature.args[0].dtype)
        store = builder.store(v, builder.gep(ary.data, [args[1]]))
        store.set_metadata("nontemporal",
                           builder.module.add_metadata([ir.Constant(ir.IntType(32), 1)]))
        return context.get_dummy_value()

    return sig, codegen


@numba.njit(cache=True, inline="always")
def _h_of(s0, s1, s2, s3, s5, s6, s7):  # pragma: no cover - compiled
    """The first four H coefficients from the SH ones (T_h's nonzeros; H⁵ = A s4, H⁶ = A s8)."""
    return A * s0 + B * s2, G * s5 - A * s1, E * s2 + F * s6, G * s7 - A * s3


@numba.njit(cache=True)
def t_h_c1(s, out):  # pragma: no cover - compiled
    """One channel: s (N, 9) SH coefficients → out (N, n) H coefficients, n = 4 or 6."""
    six = out.shape[1] == 6
    for i in range(s.shape[0]):
        s0 = s[i, 0]
        s1 = s[i, 1]
        s2 = s[i, 2]
        s3 = s[i, 3]
        s4 = s[i, 4]
        s5 = s[i, 5]
        s6 = s[i, 6]
        s7 = s[i, 7]
        s8 = s[i, 8]
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = _h_of(s0, s1, s2, s3, s5, s6, s7)
        if six:
            out[i, 4] = A * s4
            out[i, 5] = A * s8


@numba.njit(cache=True)
def t_h_c1_stream(s, out):  # pragma: no cover - compiled
    """`t_h_c1` for a float64 output far larger than the caches: s (N·9,) → out (N·n,)
    flat, written in address order with streaming stores, then a fence."""
    rows = s.shape[0] // 9
    n = out.shape[0] // rows if rows else 6
    for i in range(rows):
        b = 9 * i
        h0, h1, h2, h3 = _h_of(s[b], s[b + 1], s[b + 2], s[b + 3], s[b + 5], s[b + 6],
                               s[b + 7])
        o = n * i
        _stream_store(out, o, h0)
        _stream_store(out, o + 1, h1)
        _stream_store(out, o + 2, h2)
        _stream_store(out, o + 3, h3)
        if n == 6:
            _stream_store(out, o + 4, A * s[b + 4])
            _stream_store(out, o + 5, A * s[b + 8])
    _fence()


@numba.njit(cache=True)
def t_h_c3(s, out):  # pragma: no cover - compiled
    """RGB: s (N, 27) = (N, 9, 3) flattened → out (N, 3n) = (N, n, 3) flattened."""
    six = out.shape[1] == 18
    for i in range(s.shape[0]):
        for c in range(3):
            s0 = s[i, c]
            s1 = s[i, 3 + c]
            s2 = s[i, 6 + c]
            s3 = s[i, 9 + c]
            s4 = s[i, 12 + c]
            s5 = s[i, 15 + c]
            s6 = s[i, 18 + c]
            s7 = s[i, 21 + c]
            s8 = s[i, 24 + c]
            h = _h_of(s0, s1, s2, s3, s5, s6, s7)
            out[i, c] = h[0]
            out[i, 3 + c] = h[1]
            out[i, 6 + c] = h[2]
            out[i, 9 + c] = h[3]
            if six:
                out[i, 12 + c] = A * s4
                out[i, 15 + c] = A * s8


@numba.njit(cache=True)
def t_h_any(s, out):  # pragma: no cover - compiled
    """Any channel count: s (N, 9, C) → out (N, n, C)."""
    six = out.shape[1] == 6
    for i in range(s.shape[0]):
        for c in range(s.shape[2]):
            s0 = s[i, 0, c]
            s1 = s[i, 1, c]
            s2 = s[i, 2, c]
            s3 = s[i, 3, c]
            s4 = s[i, 4, c]
            s5 = s[i, 5, c]
            s6 = s[i, 6, c]
            s7 = s[i, 7, c]
            s8 = s[i, 8, c]
            h = _h_of(s0, s1, s2, s3, s5, s6, s7)
            out[i, 0, c] = h[0]
            out[i, 1, c] = h[1]
            out[i, 2, c] = h[2]
            out[i, 3, c] = h[3]
            if six:
                out[i, 4, c] = A * s4
                out[i, 5, c] = A * s8
