"""Streamed image reading: an image a block of whole rows at a time, in bounded memory, and the
row sums of a projection computed while the rows are in cache (Radiance files)."""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from .codecs import (
    LDR_FORMATS,
    c_stderr,
    check_declared_size,
    oneline,
    pfm_header,
    read_rgbe,
    rgbe_half_step,
    rgbe_header,
    rgbe_row_sums,
    rgbe_rows,
)
from .images import LDRWarning, check_pixels, check_readable, to_rgb
from .tonemap import srgb_to_linear

#: Default size of one block of rows read by :class:`ImageRows` (decoded float32 RGB).
BLOCK_BYTES = 16 << 20


class ImageRows:
    """An image read in blocks of whole rows, straight from the file, in bounded memory.

    ``with ImageRows(path) as im:`` gives ``im.width`` and ``im.height`` from the header
    alone; ``for y0, block in im.blocks():`` yields ``(y0, (rows, W, 3) float32)`` top to
    bottom, decoded exactly as [`read_image`][shprobe.probes.images.read_image] decodes the whole
    image (RGBE half step, sRGB → linear for 8/16-bit files with one
    [`LDRWarning`][shprobe.probes.images.LDRWarning], grey → RGB, alpha dropped, NaN/Inf/negative
    refused unless ``clamp``). OpenImageIO reads scanline and tiled files a block at a time (tiled
    files a row of tiles at a time); PFM is memory-mapped. Peak memory is one block
    (``block_bytes``, default 16 MB) plus the reader's own buffers, whatever the image size.

    Two cases are not bounded: Radiance files that OpenImageIO refuses (old-style RLE) are
    decoded whole by `read_rgbe` and handed out in blocks; and with ``clamp`` a +Inf
    pixel becomes the largest finite value *of its block* (the whole image's in
    [`read_image`][shprobe.probes.images.read_image]).
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
        check_readable(p, ext)
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
        h, w, c, dt, offset = pfm_header(p, head, p.stat().st_size)
        mm = np.memmap(p, dtype=dt, mode="r", offset=offset, shape=(h, w, c))
        self._pfm = (mm, c)
        return h, w

    def _open_rgbe(self) -> tuple[int, int]:
        """shprobe's RGBE decoder, fed from the file a few MB at a time (top-down files;
        other orientations are decoded whole)."""
        p = self.path
        with open(p, "rb") as f:
            head = f.read(1 << 16)
        s1, a1, s2, n1, n2, offset = rgbe_header(p, head)
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
                status, rows, self._pos = rgbe_rows(self._buf, self._pos, out[done:])
            else:
                status, rows, self._pos = rgbe_row_sums(self._buf, self._pos, out[done:],
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
        with c_stderr() as c_messages:
            inp = oiio.ImageInput.open(str(p), config)
            if inp is None:
                msg = oneline(oiio.geterror() or c_messages()) or "corrupt"
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
        self._ldr = self._fmt in LDR_FORMATS
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
            yield y0, blk if self._own_rgbe else check_pixels(blk, self.path, self.clamp,
                                                              whole=False)

    def row_sums(self, weights: ArrayLike) -> Iterator[tuple[int, NDArray[np.float64]]]:
        """Yield ``(y0, sums)`` top to bottom, ``sums`` ``(rows, M, 3) float64`` with
        ``sums[r, m, c]`` = Σ_x ``weights[m, x]`` · pixel(y0 + r, x, c): what
        ``np.matmul(weights[None], block)`` gives for each block of `blocks` (weights
        ``(M, W)``, used as float32). Radiance files streamed by shprobe's decoder are decoded
        and summed in one compiled pass, each scanline while it is in cache (no block of
        floats is written; float32 products and sums, as the matrix product); other files go through
        `blocks` and one float32 matrix product per row."""
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
            return to_rgb(np.asarray(mm[h - y1:h - y0][::-1], dtype=np.float32), p)
        import OpenImageIO as oiio

        inp = self._inp
        with c_stderr() as c_messages:
            if self._tile:  # a row of tiles (y0 is a multiple of the tile height)
                data = inp.read_tiles(0, 0, self._x, self._x + self.width, self._y + y0,
                                      self._y + y1, 0, 1, 0, self._nch, oiio.FLOAT)
            else:
                data = inp.read_scanlines(0, 0, self._y + y0, self._y + y1, 0, 0, self._nch,
                                          oiio.FLOAT)
            if data is None or inp.has_error:
                raise ShprobeError("cannot read image (truncated or corrupt): "
                                   + oneline(inp.geterror() or c_messages()), p)
        data = np.asarray(data, dtype=np.float32)
        if data.ndim == 2:  # one channel
            data = data.reshape(y1 - y0, self.width, -1)
        if self._srgb:
            data = srgb_to_linear(data)
        if self._rgbe:
            data = rgbe_half_step(data)
        return to_rgb(data, p)

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

