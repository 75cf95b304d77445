"""Image I/O: HDR/EXR/PFM/TIFF/PNG/JPEG in, EXR/HDR/PFM/PNG/TIFF out.

Everything goes through OpenImageIO except two small formats it gets wrong or only half right:

- Radiance ``.hdr``: OpenImageIO reads flat and new-style (per-channel) RLE scanlines but not the
  old-style RLE (repeat-pixel markers ``1 1 1 n``); when it fails, shprobe's own RGBE decoder
  (flat, old and new RLE, ``±Y H ±X W`` orientations) takes over.
- ``.pfm``: rows are stored bottom-up; OpenImageIO 3.0 writes them bottom-up but reads them back
  unflipped, so shprobe reads and writes PFM itself (``PF`` RGB / ``Pf`` grey, either
  endianness from the sign of the scale, rows flipped to top-down).

``read_image`` returns linear RGB ``(H, W, 3) float32`` with row 0 at the top. 8/16-bit images
(PNG, JPEG, integer TIFF) are decoded from sRGB to linear and an :class:`LDRWarning` is issued:
display-referred pixels are not radiance. NaN, Inf or negative pixels are an error naming the
file, unless ``clamp=True`` (NaN → 0, −∞/negatives → 0, +∞ → the largest finite value).
"""

from __future__ import annotations

import os
import re
import sys
import tempfile
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..files import atomic_output, check_output_path
from ..limits import check_memory

#: Extensions read_image accepts.
READ_EXTENSIONS = (".hdr", ".rgbe", ".pic", ".exr", ".pfm", ".tif", ".tiff", ".png", ".jpg",
                   ".jpeg")
#: Extensions write_image accepts.
WRITE_EXTENSIONS = (".exr", ".hdr", ".pfm", ".png", ".tif", ".tiff")
_LDR_OUT = (".png",)


class LDRWarning(UserWarning):
    """An 8/16-bit image was read: its pixels are display values, not radiance."""


# ----------------------------------------------------------------------------- colour


def srgb_to_linear(v: ArrayLike) -> NDArray[np.float32]:
    """sRGB EOTF (IEC 61966-2-1), values in [0, 1]."""
    v = np.asarray(v, dtype=np.float32)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(v: ArrayLike) -> NDArray[np.float32]:
    """sRGB OETF (inverse of :func:`srgb_to_linear`), input clamped to [0, 1]."""
    v = np.clip(np.asarray(v, dtype=np.float32), 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055).astype(np.float32)


# ----------------------------------------------------------------------------- reading


def read_image(path: str | os.PathLike[str], clamp: bool = False) -> NDArray[np.float32]:
    """Read an image as linear RGB ``(H, W, 3) float32``, row 0 at the top.

    Grey images are repeated to 3 channels; a 4th (alpha) channel and any beyond are dropped
    (colour is read as stored, not multiplied by alpha).
    Raises :class:`ShprobeError` naming the file for a missing, empty, truncated, corrupt or
    unknown file, and for NaN/Inf/negative pixels unless ``clamp``.
    """
    p = Path(path)
    ext = p.suffix.lower()
    _check_readable(p, ext)
    ldr = False
    if ext == ".pfm":
        img = _read_pfm(p)
    else:
        if ext in (".hdr", ".rgbe", ".pic"):
            try:  # shprobe's decoder first: one compiled pass, the (m + 0.5) step built in
                return read_rgbe(p)  # finite and ≥ 0 by construction: nothing to check
            except ShprobeError as own:
                try:  # what it refuses (other FORMATs) OpenImageIO may still read
                    img = _rgbe_half_step(_read_oiio(p)[0])
                except ShprobeError:
                    raise own from None
        else:
            img, ldr = _read_oiio(p)
    img = _to_rgb(img, p)
    if ldr:
        warnings.warn(f"{p}: 8/16-bit image decoded from sRGB to linear — display values are "
                      "not radiance", LDRWarning, stacklevel=2)
    return check_pixels(img, p, clamp)


def _check_readable(p: Path, ext: str) -> None:
    """One line for an unknown extension, a missing file, a folder or an empty file."""
    if ext not in READ_EXTENSIONS:
        raise ShprobeError(
            f"unknown image extension {ext or '(none)'!r}; expected one of "
            + " ".join(READ_EXTENSIONS), p)
    if not p.exists():
        raise ShprobeError("no such file", p)
    if p.is_dir():
        raise ShprobeError("is a directory, not an image", p)
    if p.stat().st_size == 0:
        raise ShprobeError("file is empty", p)


def check_declared_size(p: Path, width: int, height: int, channels: int, min_bytes: int = 0,
                        have: int | None = None, whole: bool = True) -> None:
    """Believe an image header only as far as the file and the memory allow: the pixel data
    cannot be shorter than ``min_bytes`` (a lower bound for the format), and decoding it to
    float32 (with the copies reading makes) must fit :func:`shprobe.limits.check_memory` —
    both checked before anything is allocated (the memory only when the image is read
    ``whole``)."""
    have = p.stat().st_size if have is None else have
    if have < min_bytes:
        raise ShprobeError(f"header declares {width}x{height} pixels but the file holds only "
                           f"{have} bytes of pixel data (truncated or corrupt)", p)
    if whole:  # streamed reads hold a block of rows, not the image
        check_memory(float(width) * height * (4.0 * channels + 24.0),
                     f"decoding a {width}x{height} image", p)


def _read_oiio(p: Path) -> tuple[NDArray[np.float32], bool]:
    import OpenImageIO as oiio

    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)  # colour as stored, not premultiplied
    with _c_stderr() as c_messages:
        inp = oiio.ImageInput.open(str(p), config)
        if inp is None:
            raise ShprobeError("cannot read image: "
                               + (_oneline(oiio.geterror() or c_messages()) or "corrupt"), p)
        try:
            spec = inp.spec()
            if spec.width <= 0 or spec.height <= 0 or spec.nchannels <= 0:
                raise ShprobeError("image has zero size", p)
            rgbe = p.suffix.lower() in (".hdr", ".rgbe", ".pic")
            check_declared_size(p, spec.width, spec.height, spec.nchannels,
                                min_bytes=4 * spec.height if rgbe else 0)
            fmt = str(spec.format)
            data = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
            if data is None or inp.has_error:
                raise ShprobeError("cannot read image (truncated or corrupt): "
                                   + _oneline(inp.geterror() or c_messages()), p)
            cs = str(spec.getattribute("oiio:ColorSpace") or "").lower()
        finally:
            inp.close()
    data = np.asarray(data, dtype=np.float32)
    if data.ndim == 2:
        data = data[:, :, None]
    ldr = fmt in ("uint8", "uint16", "int8", "int16", "uint32", "int32")
    if ldr and not ("lin" in cs and "srgb" not in cs):
        data = srgb_to_linear(data)
    return data, ldr


@contextmanager
def _c_stderr() -> Iterator[Callable[[], str]]:
    """Catch what C libraries print on file descriptor 2 (libpng reports errors there itself).

    Yields a function returning the text caught so far. If the block raises, the text is dropped
    (the exception carries the message); otherwise it is passed on to stderr unchanged.
    """
    try:
        saved = os.dup(2)
    except OSError:  # no fd 2 (embedded interpreters): nothing to catch
        yield lambda: ""
        return
    with tempfile.TemporaryFile() as tmp:

        def caught() -> str:
            tmp.flush()
            tmp.seek(0)
            return tmp.read().decode(errors="replace")

        sys.stderr.flush()
        os.dup2(tmp.fileno(), 2)
        ok = False
        try:
            yield caught
            ok = True
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            if ok and (text := caught()):
                sys.stderr.write(text)


def _oneline(msg: str | None) -> str:
    return " ".join((msg or "").split())[:200]


def _to_rgb(img: NDArray[np.float32], p: Path) -> NDArray[np.float32]:
    if img.ndim != 3 or img.shape[0] == 0 or img.shape[1] == 0:
        raise ShprobeError("image has zero size", p)
    c = img.shape[2]
    if c in (1, 2):  # grey (+ alpha)
        img = np.repeat(img[:, :, :1], 3, axis=2)
    elif c >= 3:
        img = img[:, :, :3]
    return np.ascontiguousarray(img, dtype=np.float32)


def check_pixels(img: NDArray[np.float32], path: str | os.PathLike[str] | None = None,
                 clamp: bool = False) -> NDArray[np.float32]:
    """Refuse NaN, Inf or negative pixels (``ShprobeError`` with counts) unless ``clamp``."""
    if img.size == 0:
        return img
    lo, hi = img.min(), img.max()  # fast path: two reductions, no temporaries
    if lo >= 0 and np.isfinite(hi):
        return img
    bad_nan = np.isnan(img)
    bad_inf = np.isinf(img)
    bad_neg = img < 0
    n_nan, n_inf, n_neg = int(bad_nan.sum()), int(bad_inf.sum()), int((bad_neg & ~bad_inf).sum())
    if n_nan + n_inf + n_neg == 0:
        return img
    if not clamp:
        parts = [f"{n} {what}" for n, what in ((n_nan, "NaN"), (n_inf, "infinite"),
                                               (n_neg, "negative")) if n]
        raise ShprobeError(
            "image has " + ", ".join(parts) + " pixel values (use clamp / --clamp to zero them)",
            path)
    finite = img[np.isfinite(img)]
    big = float(finite.max()) if finite.size else 0.0
    out = np.nan_to_num(img, nan=0.0, posinf=max(big, 0.0), neginf=0.0)
    return np.maximum(out, 0.0).astype(np.float32)


# ----------------------------------------------------------------------------- streaming


#: Default size of one block of rows read by :class:`ImageRows` (decoded float32 RGB).
BLOCK_BYTES = 16 << 20


class ImageRows:
    """An image read in blocks of whole rows, straight from the file, in bounded memory.

    ``with ImageRows(path) as im:`` gives ``im.width`` and ``im.height`` from the header
    alone; ``for y0, block in im.blocks():`` yields ``(y0, (rows, W, 3) float32)`` top to
    bottom, decoded exactly as :func:`read_image` decodes the whole image (RGBE half step,
    sRGB → linear for 8/16-bit files with one :class:`LDRWarning`, grey → RGB, alpha dropped,
    NaN/Inf/negative refused unless ``clamp``). OpenImageIO reads scanline and tiled files a
    block at a time (tiled files a row of tiles at a time); PFM is memory-mapped. Peak memory
    is one block (``block_bytes``, default 16 MB) plus the reader's own buffers, whatever the
    image size.

    Two cases are not bounded: Radiance files that OpenImageIO refuses (old-style RLE) are
    decoded whole by :func:`read_rgbe` and handed out in blocks; and with ``clamp`` a +Inf
    pixel becomes the largest finite value *of its block* (the whole image's in
    :func:`read_image`).
    """

    def __init__(self, path: str | os.PathLike[str], clamp: bool = False,
                 block_bytes: int = BLOCK_BYTES) -> None:
        self.path = Path(path)
        self.clamp = clamp
        self.block_bytes = int(block_bytes)
        self._inp = None
        self._whole: NDArray[np.float32] | None = None
        self._pfm: tuple[np.memmap, int] | None = None
        self._fmt = ""
        self._ldr = False
        self._srgb = False
        self._nch = 3
        self._y = 0
        self._x = 0
        self._tile = 0
        p = self.path
        ext = p.suffix.lower()
        _check_readable(p, ext)
        self._rgbe = ext in (".hdr", ".rgbe", ".pic")
        self._rgbe_f = None
        self._own_rgbe = False  # decoded by read_rgbe / decode_rgbe: no pixel checks needed
        if ext == ".pfm":
            self.height, self.width = self._open_pfm()
        elif self._rgbe:
            try:
                self.height, self.width = self._open_rgbe()
            except ShprobeError:
                self.height, self.width = self._open_oiio()
        else:
            self.height, self.width = self._open_oiio()

    # opening ------------------------------------------------------------------
    def _open_pfm(self) -> tuple[int, int]:
        p = self.path
        with open(p, "rb") as f:
            head = f.read(256)
        h, w, c, dt, offset = _pfm_header(p, head, p.stat().st_size)
        mm = np.memmap(p, dtype=dt, mode="r", offset=offset, shape=(h, w, c))
        self._pfm = (mm, c)
        return h, w

    def _open_rgbe(self) -> tuple[int, int]:
        """shprobe's RGBE decoder, fed from the file a few MB at a time (top-down files;
        other orientations are decoded whole)."""
        p = self.path
        with open(p, "rb") as f:
            head = f.read(1 << 16)
        s1, a1, s2, n1, n2, offset = _rgbe_header(p, head)
        check_declared_size(p, n2, n1, 4, min_bytes=4 * n1, have=p.stat().st_size - offset,
                            whole=False)
        if (s1, a1, s2) != (b"-", b"Y", b"+"):
            self._whole = read_rgbe(p)
            self._own_rgbe = True  # only once decoded: OIIO's fallback pixels are checked
            return self._whole.shape[0], self._whole.shape[1]
        self._rgbe_f = open(p, "rb")  # closed by close()
        self._rgbe_f.seek(offset)
        self._buf = np.zeros(0, np.uint8)
        self._pos = 0
        self._next = 0
        self._own_rgbe = True
        return n1, n2

    def _read_rgbe(self, y0: int, y1: int, weights: NDArray[np.float32] | None = None
                   ) -> NDArray:
        """Rows y0..y1 decoded (float32), or with ``weights`` their row sums (float64)."""
        if y0 != self._next:
            raise ShprobeError("RGBE rows must be read in order", self.path)
        if weights is None:
            out = np.empty((y1 - y0, self.width, 3), np.float32)
        else:
            out = np.empty((y1 - y0, weights.shape[0], 3), np.float64)
        done = 0
        chunk = max(4096, min(1 << 22, self.block_bytes // 4))
        while done < out.shape[0]:
            if weights is None:
                status, rows, self._pos = _rgbe_rows(self._buf, self._pos, out[done:])
            else:
                status, rows, self._pos = _rgbe_row_sums(self._buf, self._pos, out[done:],
                                                         weights)
            done += rows
            if status == 2:
                raise ShprobeError("truncated or corrupt .hdr pixel data", self.path)
            if status == 1:
                more = self._rgbe_f.read(chunk)
                if not more:
                    raise ShprobeError("truncated or corrupt .hdr pixel data", self.path)
                self._buf = np.concatenate([self._buf[self._pos:],
                                            np.frombuffer(more, np.uint8)])
                self._pos = 0
        self._next = y1
        return out

    def _open_oiio(self) -> tuple[int, int]:
        import OpenImageIO as oiio

        p = self.path
        config = oiio.ImageSpec()
        config.attribute("oiio:UnassociatedAlpha", 1)
        with _c_stderr() as c_messages:
            inp = oiio.ImageInput.open(str(p), config)
            if inp is None:
                msg = _oneline(oiio.geterror() or c_messages()) or "corrupt"
                if self._rgbe:  # old-style RLE and other files OIIO refuses
                    self._whole = read_rgbe(p)
                    self._own_rgbe = True
                    return self._whole.shape[0], self._whole.shape[1]
                raise ShprobeError("cannot read image: " + msg, p)
        spec = inp.spec()
        if spec.width <= 0 or spec.height <= 0 or spec.nchannels <= 0:
            inp.close()
            raise ShprobeError("image has zero size", p)
        self._inp = inp
        self._y, self._x = spec.y, spec.x
        self._tile = int(spec.tile_height) if spec.tile_width else 0
        self._nch = spec.nchannels
        self._fmt = str(spec.format)
        cs = str(spec.getattribute("oiio:ColorSpace") or "").lower()
        self._ldr = self._fmt in ("uint8", "uint16", "int8", "int16", "uint32", "int32")
        self._srgb = self._ldr and not ("lin" in cs and "srgb" not in cs)
        return spec.height, spec.width

    # reading --------------------------------------------------------------------
    def rows_per_block(self) -> int:
        """Rows in one block: ``block_bytes`` of float32 RGB (at least one row, or one row of
        tiles)."""
        return self._align(max(1, min(self.height, self.block_bytes // max(1, 12 * self.width))))

    def _align(self, n: int) -> int:
        t = self._tile
        return n if t <= 1 else -(-n // t) * t

    def blocks(self, rows: int | None = None) -> Iterator[tuple[int, NDArray[np.float32]]]:
        """Yield ``(y0, block)`` top to bottom, ``block`` ``(rows, W, 3) float32``."""
        n = self._align(int(rows)) if rows else self.rows_per_block()
        if self._ldr:
            warnings.warn(f"{self.path}: 8/16-bit image decoded from sRGB to linear — display "
                          "values are not radiance", LDRWarning, stacklevel=2)
        for y0 in range(0, self.height, n):
            y1 = min(self.height, y0 + n)
            blk = self._read(y0, y1)
            # shprobe's RGBE decode is finite and ≥ 0 by construction: (m + 0.5) · 2^(e − 136)
            # ≤ 255.5 · 2^119 < float32 max
            yield y0, blk if self._own_rgbe else check_pixels(blk, self.path, self.clamp)

    def row_sums(self, weights: ArrayLike) -> Iterator[tuple[int, NDArray[np.float64]]]:
        """Yield ``(y0, sums)`` top to bottom, ``sums`` ``(rows, M, 3) float64`` with
        ``sums[r, m, c]`` = Σ_x ``weights[m, x]`` · pixel(y0 + r, x, c): what
        ``np.matmul(weights[None], block)`` gives for each block of :meth:`blocks` (weights
        ``(M, W)``, used as float32). Radiance files streamed by shprobe's decoder are decoded
        and summed in one compiled pass, each scanline while it is in cache (no block of
        floats is written; float32 products and sums, as the matrix product); other files go through
        :meth:`blocks` and one float32 matrix product per row."""
        w32 = np.ascontiguousarray(weights, dtype=np.float32)
        if w32.ndim != 2 or w32.shape[1] != self.width:
            raise ValueError(f"weights must be (M, {self.width}), got {w32.shape}")
        if self._rgbe_f is None:
            for y0, blk in self.blocks():
                yield y0, np.matmul(w32[None], blk).astype(np.float64)
            return
        n = self.rows_per_block()
        for y0 in range(0, self.height, n):
            y1 = min(self.height, y0 + n)
            yield y0, self._read_rgbe(y0, y1, w32)

    def _read(self, y0: int, y1: int) -> NDArray[np.float32]:
        p = self.path
        if self._whole is not None:
            return self._whole[y0:y1]
        if self._rgbe_f is not None:
            return self._read_rgbe(y0, y1)
        if self._pfm is not None:
            mm, _ = self._pfm
            h = self.height  # bottom-up rows: image rows y0..y1 are file rows h-y1..h-y0
            return _to_rgb(np.asarray(mm[h - y1:h - y0][::-1], dtype=np.float32), p)
        import OpenImageIO as oiio

        inp = self._inp
        with _c_stderr() as c_messages:
            if self._tile:  # a row of tiles (y0 is a multiple of the tile height)
                data = inp.read_tiles(0, 0, self._x, self._x + self.width, self._y + y0,
                                      self._y + y1, 0, 1, 0, self._nch, oiio.FLOAT)
            else:
                data = inp.read_scanlines(0, 0, self._y + y0, self._y + y1, 0, 0, self._nch,
                                          oiio.FLOAT)
            if data is None or inp.has_error:
                raise ShprobeError("cannot read image (truncated or corrupt): "
                                   + _oneline(inp.geterror() or c_messages()), p)
        data = np.asarray(data, dtype=np.float32)
        if data.ndim == 2:  # one channel
            data = data.reshape(y1 - y0, self.width, -1)
        if self._srgb:
            data = srgb_to_linear(data)
        if self._rgbe:
            data = _rgbe_half_step(data)
        return _to_rgb(data, p)

    def close(self) -> None:
        """Release the file."""
        if self._inp is not None:
            self._inp.close()
            self._inp = None
        if self._rgbe_f is not None:
            self._rgbe_f.close()
            self._rgbe_f = None
        self._pfm = None
        self._whole = None

    def __enter__(self) -> ImageRows:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"ImageRows({str(self.path)!r}, {self.width}x{self.height})"


def image_size(path: str | os.PathLike[str]) -> tuple[int, int]:
    """(width, height) of an image file from its header (no pixels decoded, except for
    Radiance files OpenImageIO cannot open)."""
    with ImageRows(path) as im:
        return im.width, im.height


# ----------------------------------------------------------------------------- PFM


_PFM_HEADER = re.compile(rb"\A(P[Ff])\s+(\d+)\s+(\d+)\s+([-+0-9.eE]+)\s")


def _pfm_header(p: Path, head: bytes, size: int) -> tuple[int, int, int, np.dtype, int]:
    """(H, W, channels, dtype, data offset) of a PFM file from its first bytes and size."""
    m = _PFM_HEADER.match(head[:256])
    if m is None:
        raise ShprobeError("not a PFM file (bad header)", p)
    kind, w, h = m.group(1), int(m.group(2)), int(m.group(3))
    try:
        scale = float(m.group(4))
    except ValueError:
        scale = float("nan")
    if not np.isfinite(scale) or scale == 0:
        raise ShprobeError(f"bad PFM scale line {m.group(4).decode('ascii', 'replace')!r}", p)
    if w == 0 or h == 0:
        raise ShprobeError("image has zero size", p)
    c = 3 if kind == b"PF" else 1
    dt = np.dtype("<f4") if scale < 0 else np.dtype(">f4")
    n = w * h * c
    if size - m.end() < 4 * n:
        raise ShprobeError(f"truncated PFM: {size - m.end()} of {4 * n} data bytes", p)
    return h, w, c, dt, m.end()


def _read_pfm(p: Path) -> NDArray[np.float32]:
    raw = p.read_bytes()
    h, w, c, dt, offset = _pfm_header(p, raw, len(raw))
    check_declared_size(p, w, h, c, have=len(raw))
    n = w * h * c
    body = raw[offset:]
    data = np.frombuffer(body, dtype=dt, count=n).reshape(h, w, c)
    return np.ascontiguousarray(data[::-1], dtype=np.float32)  # bottom-up -> top-down


def _write_pfm(path: Path, rgb: NDArray[np.float32]) -> None:
    h, w, _ = rgb.shape
    with open(path, "wb") as f:
        f.write(f"PF\n{w} {h}\n-1.0\n".encode("ascii"))
        f.write(np.ascontiguousarray(rgb[::-1], dtype="<f4").tobytes())


# ----------------------------------------------------------------------------- RGBE


_RGBE_SIZE = re.compile(rb"([-+])([XY])\s+(\d+)\s+([-+])([XY])\s+(\d+)")


def _rgbe_header(p: Path, raw: bytes) -> tuple[bytes, bytes, bytes, int, int, int]:
    """(s1, a1, s2, n1, n2, offset of the pixel data) of a Radiance header in ``raw`` (the
    file's first bytes); scanlines run along the second axis, ``n1`` of them."""
    if not (raw.startswith(b"#?") or raw.startswith(b"FORMAT")):
        raise ShprobeError("not a Radiance .hdr file (no '#?' signature)", p)
    end = raw.find(b"\n\n")
    if end < 0:
        raise ShprobeError("corrupt .hdr header (no blank line)", p)
    header = raw[:end]
    if b"FORMAT=" in header and b"32-bit_rle_rgbe" not in header:
        raise ShprobeError("unsupported .hdr FORMAT (only 32-bit_rle_rgbe)", p)
    nl = raw.find(b"\n", end + 2)
    m = _RGBE_SIZE.match(raw[end + 2: nl if nl >= 0 else len(raw)].strip())
    if m is None or nl < 0:
        raise ShprobeError("corrupt .hdr resolution line", p)
    s1, a1, n1, s2, _a2, n2 = m.groups()
    n1, n2 = int(n1), int(n2)
    if n1 == 0 or n2 == 0:
        raise ShprobeError("image has zero size", p)
    return s1, a1, s2, n1, n2, nl + 1


def _rgbe_rows(buf: NDArray[np.uint8], pos: int, out: NDArray[np.float32]
               ) -> tuple[int, int, int]:
    from ._kernels_rgbe import decode_rgbe  # numba, imported lazily

    status, rows, end = decode_rgbe(buf, pos, out, _rgbe_scale())
    return int(status), int(rows), int(end)


def _rgbe_row_sums(buf: NDArray[np.uint8], pos: int, sums: NDArray[np.float64],
                   weights: NDArray[np.float32]) -> tuple[int, int, int]:
    from ._kernels_rgbe import rgbe_row_sums  # numba, imported lazily

    status, rows, end = rgbe_row_sums(buf, pos, sums, weights, _rgbe_scale())
    return int(status), int(rows), int(end)


def read_rgbe(path: str | os.PathLike[str]) -> NDArray[np.float32]:
    """Decode a Radiance RGBE file (flat, old-style and new-style RLE) to ``(H, W, 3)``:
    (m + 0.5) · 2^(e − 136), as Radiance's colr_color, in one compiled pass per scanline."""
    p = Path(path)
    raw = p.read_bytes()
    s1, a1, s2, n1, n2, offset = _rgbe_header(p, raw)
    check_declared_size(p, n2, n1, 4, min_bytes=4 * n1, have=len(raw) - offset)
    body = np.frombuffer(raw, dtype=np.uint8, offset=offset)
    img = np.empty((n1, n2, 3), dtype=np.float32)
    if _rgbe_rows(body, 0, img)[0] != 0:
        raise ShprobeError("truncated or corrupt .hdr pixel data", p)
    # scanline order: first axis is the slow one
    if a1 == b"X":
        img = img.transpose(1, 0, 2)
        s1, s2 = s2, s1
    if s1 == b"+":  # +Y: bottom-to-top
        img = img[::-1]
    if s2 == b"-":
        img = img[:, ::-1]
    return np.ascontiguousarray(img)


def rgbe_to_float(rgbe: NDArray[np.uint8]) -> NDArray[np.float32]:
    """RGBE bytes (..., 4) → float RGB: (m + 0.5) · 2^(e − 136), as Radiance's colr_color
    (writers truncate, so the half step makes the round trip unbiased)."""
    e = rgbe[..., 3].astype(np.int32)
    f = np.where(e > 0, np.ldexp(np.float32(1.0), e - (128 + 8)), 0.0).astype(np.float32)
    return ((rgbe[..., :3].astype(np.float32) + 0.5) * f[..., None]).astype(np.float32)


def _rgbe_half_step(img: NDArray[np.float32]) -> NDArray[np.float32]:
    """OpenImageIO decodes RGBE as m · 2^k (k = e − 136); add Radiance's half step 0.5 · 2^k.

    k is recovered exactly from the largest channel, m_max · 2^k with m_max in [128, 255]
    (in place, one compiled pass)."""
    img = np.ascontiguousarray(img, dtype=np.float32)
    flat = img.reshape(-1, img.shape[-1])
    # 2^k from the float32 exponent field E of the largest channel: m_max in [128, 256)
    # means 2^(E−127) = 2^(k+7), so the half step is 2^(E−135)
    table = np.ldexp(np.float32(1.0), np.arange(256) - 135).astype(np.float32)
    from ._kernels_rgbe import half_step  # numba, imported lazily

    half_step(flat, flat.view(np.int32), table)
    return img


@lru_cache(maxsize=1)
def _rgbe_scale() -> NDArray[np.float32]:
    """2^(e − 136) for each exponent byte e as float32, 0 for e = 0 (as :func:`rgbe_to_float`)."""
    t = rgbe_to_float(np.stack([np.zeros(256, np.uint8)] * 3 + [np.arange(256, dtype=np.uint8)],
                               axis=-1))[:, 0] / np.float32(0.5)
    t.flags.writeable = False
    return t


# ----------------------------------------------------------------------------- writing


def tonemap(rgb: ArrayLike, exposure: float = 0.0) -> NDArray[np.uint8]:
    """Linear RGB → 8-bit sRGB: scale by 2**exposure, clamp to [0, 1], sRGB OETF, round.

    The one tone map: every PNG shprobe writes goes through it (:func:`write_image`)."""
    v = np.asarray(rgb, dtype=np.float32) * np.float32(2.0 ** exposure)
    v = np.nan_to_num(v, nan=0.0, posinf=1.0, neginf=0.0)
    return np.round(linear_to_srgb(v) * 255.0).astype(np.uint8)


def auto_exposure(radiance: ArrayLike, target: float = 0.8, percentile: float = 99.0) -> float:
    """Exposure in stops for :func:`tonemap` that maps the ``percentile``-th percentile of the
    largest channel of ``radiance`` (..., C) to ``target`` (0 when there is no light): bright
    enough to see, with at most ~1 % of the values clipped. The one exposure rule; pictures
    with labelled panels round it to 0.1 stop (:func:`shprobe.probes.figures.exposure_for`)."""
    a = np.asarray(radiance, dtype=np.float64)
    if a.size == 0:
        return 0.0
    peak = float(np.percentile(np.max(a, axis=-1), percentile))
    return float(np.log2(target / peak)) if np.isfinite(peak) and peak > 0 else 0.0


def check_image_output(path: str | os.PathLike[str], overwrite: bool = False) -> Path:
    """Refuse, before any work, an output :func:`write_image` cannot write or may not replace:
    an unknown extension, an existing file (unless ``overwrite``), a missing folder."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in WRITE_EXTENSIONS:
        raise ShprobeError(
            f"cannot write extension {ext or '(none)'!r}; expected one of "
            + " ".join(WRITE_EXTENSIONS), p)
    return check_output_path(p, overwrite)


def write_image(path: str | os.PathLike[str], rgb: ArrayLike, overwrite: bool = False,
                exposure: float = 0.0, half: bool = False) -> Path:
    """Write linear RGB ``(H, W, 3)`` (or ``(H, W)`` grey) atomically.

    ``.exr`` (float, or half with ``half=True``), ``.hdr`` (RGBE), ``.pfm`` and ``.tif`` are
    linear and ignore ``exposure``; ``.png`` is tone-mapped with :func:`tonemap` (exposure in
    stops). An existing file is replaced only with ``overwrite=True``. NaN or Inf values are
    refused; ``.hdr`` (RGBE, unsigned) stores negative values as 0.
    """
    p = check_image_output(path, overwrite)
    ext = p.suffix.lower()
    a = np.asarray(rgb, dtype=np.float32)
    if a.ndim == 2:
        a = np.repeat(a[:, :, None], 3, axis=2)
    if a.ndim != 3 or a.shape[2] not in (1, 3, 4) or a.shape[0] == 0 or a.shape[1] == 0:
        raise ShprobeError(f"image to write must be (H, W, 3), got {a.shape}", p)
    if a.shape[2] == 1:
        a = np.repeat(a, 3, axis=2)
    a = np.ascontiguousarray(a[:, :, :3])
    bad = int(np.count_nonzero(~np.isfinite(a)))
    if bad:
        raise ShprobeError(f"refusing to write an image with {bad} NaN or Inf values", p)
    if ext == ".hdr":
        a = np.maximum(a, 0.0)  # RGBE has no sign
    with atomic_output(p, overwrite) as tmp:
        if ext == ".pfm":
            _write_pfm(tmp, a)
        elif ext in _LDR_OUT:
            _write_oiio(tmp, tonemap(a, exposure), "uint8")
        else:
            fmt = "half" if (half and ext == ".exr") else "float"
            _write_oiio(tmp, a, fmt)
    return p


def _write_oiio(path: Path, data: NDArray, fmt: str) -> None:
    import OpenImageIO as oiio

    h, w, c = data.shape
    out = oiio.ImageOutput.create(str(path))
    if out is None:
        raise ShprobeError(f"cannot write image: {_oneline(oiio.geterror())}", path)
    spec = oiio.ImageSpec(w, h, c, {"uint8": oiio.UINT8, "half": oiio.HALF,
                                    "float": oiio.FLOAT}[fmt])
    if path.suffix.lower() in (".tif", ".tiff"):
        spec.attribute("compression", "zip")
    ok = out.open(str(path), spec) and out.write_image(data)
    err = out.geterror()
    out.close()
    if not ok:
        raise ShprobeError(f"cannot write image: {_oneline(err)}", path)
