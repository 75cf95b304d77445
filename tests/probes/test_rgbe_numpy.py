"""The NumPy RGBE decoder (shprobe.probes.rgbe_numpy) against the exact Radiance formula
(m + 0.5)·2^(e − 136) of bytes encoded here by an independent new-style RLE writer (random
packet splits, runs and literals), and against the compiled decoder bit for bit; and what it
must decline (old-style markers, mixed rows, truncated or corrupt data, too many packets),
which read_rgbe then hands to the compiled decoder."""

from __future__ import annotations

import io
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shprobe.errors import ShprobeError
from shprobe.lighting.source import resolve_lighting
from shprobe.probes import rgbe_numpy
from shprobe.probes.codecs import read_rgbe, rgbe_rows
from shprobe.probes.rgbe_numpy import MAX_PACKETS, decode_rgbe_numpy

HEAD = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n"


def expected(rgbe: np.ndarray) -> np.ndarray:
    r = rgbe.astype(np.float64)
    f = np.where(r[..., 3:] > 0, 2.0 ** (r[..., 3:] - 136), 0.0)
    return ((r[..., :3] + 0.5) * f).astype(np.float32)


def encode_channel(ch: np.ndarray, rng: np.random.Generator) -> bytes:
    """One channel plane as runs (where bytes repeat, split at random) and literal packets of
    random lengths ≤ 128."""
    out, x, w = bytearray(), 0, len(ch)
    while x < w:
        same = 1
        while x + same < w and ch[x + same] == ch[x] and same < 127:
            same += 1
        if same > 1 and rng.random() < 0.8:
            n = int(rng.integers(1, same + 1))
            out += bytes([128 + n, ch[x]])
        else:
            n = int(rng.integers(1, min(128, w - x) + 1))
            out += bytes([n, *ch[x:x + n]])
        x += n
    return bytes(out)


def encode(rgbe: np.ndarray, rng: np.random.Generator) -> bytes:
    h, w = rgbe.shape[:2]
    body = bytearray()
    for y in range(h):
        body += bytes([2, 2, w >> 8, w & 255])
        for c in range(4):
            body += encode_channel(rgbe[y, :, c], rng)
    return bytes(body)


def image(h: int, w: int, rng: np.random.Generator, runs: float = 0.5) -> np.ndarray:
    """RGBE bytes with stretches of repeated values (runs) and noise."""
    px = rng.integers(0, 256, (h, w, 4), dtype=np.uint8)
    px[..., 3] = rng.integers(100, 160, (h, w))
    hold = rng.random((h, w)) < runs  # a pixel repeating its left neighbour
    for x in range(1, w):
        px[hold[:, x], x] = px[hold[:, x], x - 1]
    px[rng.random((h, w)) < 0.05, 3] = 0  # black pixels: e = 0
    return px


def both(body: bytes, h: int, w: int) -> tuple[bool, np.ndarray, np.ndarray]:
    buf = np.frombuffer(body, np.uint8)
    out = np.full((h, w, 3), np.nan, np.float32)
    ok = decode_rgbe_numpy(buf, out)
    ref = np.full((h, w, 3), np.nan, np.float32)
    status = rgbe_rows(buf, 0, ref)[0]
    return ok, out, ref if status == 0 else None


@settings(max_examples=60, deadline=None)
@given(h=st.integers(1, 6), w=st.integers(8, 300), runs=st.floats(0, 1),
       seed=st.integers(0, 2**32 - 1))
def test_new_style_rle_exact(h, w, runs, seed):
    rng = np.random.default_rng(seed)
    px = image(h, w, rng, runs)
    ok, out, ref = both(encode(px, rng), h, w)
    assert ok
    np.testing.assert_array_equal(out, expected(px))
    np.testing.assert_array_equal(out, ref)


def test_scanline_headers_inside_the_data():
    """Literal bytes that spell a scanline header (2 2 W/256 W%256) are candidates the
    lockstep parse must reject: only the chain from the first byte counts."""
    rng = np.random.default_rng(1)
    h, w = 5, 300
    px = image(h, w, rng, 0.0)
    for y in range(h):  # the header's bytes in every channel, twice per row
        for c in range(4):
            px[y, 10:14, c] = px[y, 200:204, c] = [2, 2, w >> 8, w & 255]
    body = encode(px, rng)
    buf = np.frombuffer(body, np.uint8)
    hits = np.flatnonzero((buf[:-3] == 2) & (buf[1:-2] == 2) & (buf[2:-1] == 1)
                          & (buf[3:] == 44))
    assert len(hits) > 2 * h  # the file has the false starts
    ok, out, ref = both(body, h, w)
    assert ok
    np.testing.assert_array_equal(out, expected(px))
    np.testing.assert_array_equal(out, ref)


@pytest.mark.parametrize("w", [1, 5, 7, 40000])
def test_flat_files(w):
    """Widths outside 8…32767 are always flat pixels (as Radiance writes them)."""
    rng = np.random.default_rng(w)
    px = image(2, w, rng)
    px[..., 0] = np.maximum(px[..., 0], 2)  # no repeat markers (1 1 1 n)
    ok, out, ref = both(px.tobytes(), 2, w)
    assert ok
    np.testing.assert_array_equal(out, expected(px))
    np.testing.assert_array_equal(out, ref)


def test_declined_old_style_markers_and_mixed_rows():
    rng = np.random.default_rng(2)
    # flat with an old-style repeat marker: the compiled decoder's
    flat = bytes([128, 64, 32, 129, 1, 1, 1, 3, *([10, 20, 30, 128] * 4)])
    ok, _, ref = both(flat, 2, 4)
    assert not ok and ref is not None
    # a new-style row, then a flat one
    w = 16
    px = image(2, w, rng)
    px[..., 0] = np.maximum(px[..., 0], 3)
    body = encode(px[:1], rng) + px[1].tobytes()
    ok, _, ref = both(body, 2, w)
    assert not ok
    np.testing.assert_array_equal(ref, expected(px))
    # a flat row whose first pixel reads as a new-style header
    px[0, 0, :3] = [2, 2, 0]
    ok, _, _ = both(px.tobytes(), 2, w)
    assert not ok


def test_declined_truncated_and_corrupt():
    rng = np.random.default_rng(3)
    h, w = 4, 64
    body = encode(image(h, w, rng), rng)
    for cut in (len(body) - 1, len(body) // 2, 5):
        ok, _, ref = both(body[:cut], h, w)
        assert not ok and ref is None
    bad = bytearray(encode(np.full((1, w, 4), 7, np.uint8), rng))
    bad[4] = 0  # a packet of length 0
    assert not both(bytes(bad), 1, w)[0]
    over = bytes([2, 2, 0, w, 128 + 65, 9]) + bytes([128 + w, 9]) * 3  # a run past the plane
    ok, _, ref = both(over, 1, w)
    assert not ok and ref is None


def test_declined_past_max_packets():
    """Literal packets of one byte: 4·W packets a scanline, past MAX_PACKETS — the compiled
    decoder's; read_rgbe gives the exact pixels either way."""
    w = MAX_PACKETS // 2
    rng = np.random.default_rng(4)
    px = image(2, w, rng, 0.0)
    body = b"".join(bytes([2, 2, w >> 8, w & 255]) + b"".join(
        bytes([1, v]) for c in range(4) for v in px[y, :, c]) for y in range(2))
    ok, _, ref = both(body, 2, w)
    assert not ok
    np.testing.assert_array_equal(ref, expected(px))


def test_read_rgbe_both_paths(tmp_path, monkeypatch, grace_path, ennis_path):
    """read_rgbe below and above RGBE_NUMPY_MAX_PIXELS: the same pixels, for the test data's
    probes (OpenImageIO's encoder) and a file of this module's; a bad file is one line."""
    rng = np.random.default_rng(6)
    px = image(33, 257, rng)
    ours = tmp_path / "ours.hdr"
    ours.write_bytes(HEAD + b"-Y 33 +X 257\n" + encode(px, rng))
    files = [ours, grace_path, ennis_path]
    fast = [read_rgbe(f) for f in files]
    np.testing.assert_array_equal(fast[0], expected(px))
    monkeypatch.setattr(rgbe_numpy, "RGBE_NUMPY_MAX_PIXELS", 0)
    for f, a in zip(files, fast, strict=True):
        np.testing.assert_array_equal(read_rgbe(f), a)
    monkeypatch.undo()
    (tmp_path / "cut.hdr").write_bytes(ours.read_bytes()[:-100])
    with pytest.raises(ShprobeError, match="truncated or corrupt") as e:
        read_rgbe(tmp_path / "cut.hdr")
    assert "cut.hdr" in str(e.value)


def test_trailing_bytes_and_header_floods():
    """Bytes after the last scanline are never searched (trailing data costs nothing and is
    ignored, as by the compiled decoder); a body that is all scanline headers (W = 514 is
    ``2 2 2 2``) is declined at the candidate search."""
    rng = np.random.default_rng(7)
    h, w = 3, 40
    px = image(h, w, rng)
    ok, out, ref = both(encode(px, rng) + bytes([2, 2, 0, w]) * 100_000, h, w)
    assert ok
    np.testing.assert_array_equal(out, expected(px))
    np.testing.assert_array_equal(out, ref)
    flood = np.full(1 << 22, 2, np.uint8)
    assert not decode_rgbe_numpy(flood, np.empty((2, 514, 3), np.float32))


def test_reading_and_projecting_a_probe_starts_no_numba(grace_path):
    """What the viewer's first frame rests on: a fresh process decodes a lat-long .hdr and
    projects it (lmax 2 and 8, the loader's path) without importing numba; the coefficients
    are the ones this process gets."""
    code = ("import sys, numpy as np; from shprobe.lighting.source import resolve_lighting; "
            "a = resolve_lighting(sys.argv[1], lmax=2, need_env=True); "
            "b = resolve_lighting(sys.argv[1], lmax=8, need_env=True); "
            "print('numba' in sys.modules); np.save(sys.stdout.buffer, np.concatenate("
            "[np.ravel(a.coeffs), np.ravel(b.coeffs)]))")
    r = subprocess.run([sys.executable, "-c", code, str(grace_path)], capture_output=True,
                       check=True)
    first, rest = r.stdout.split(b"\n", 1)
    assert first == b"False", r.stderr
    got = np.load(io.BytesIO(rest))
    want = np.concatenate([np.ravel(resolve_lighting(grace_path, lmax=lm).coeffs)
                           for lm in (2, 8)])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
