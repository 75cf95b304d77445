"""Image codecs: OpenImageIO for most formats, shprobe's own PFM and Radiance RGBE.

Everything goes through OpenImageIO except two small formats it gets wrong or only half right:

- Radiance ``.hdr``: OpenImageIO reads flat and new-style (per-channel) RLE scanlines but not the
  old-style RLE (repeat-pixel markers ``1 1 1 n``); shprobe's own RGBE decoder (flat, old and new
  RLE, ``±Y H ±X W`` orientations) reads them all, ``(m + 0.5)·2^(e−136)`` as Radiance does.
- ``.pfm``: rows are stored bottom-up; OpenImageIO 3.0 writes them bottom-up but reads them back
  unflipped, so shprobe reads and writes PFM itself (``PF`` RGB / ``Pf`` grey, either
  endianness from the sign of the scale, rows flipped to top-down).

C libraries print their errors on file descriptor 2 (libpng does): `c_stderr` catches
them so a corrupt file is one line naming it. The front door is `shprobe.probes.images`
(``read_image``/``write_image``); `shprobe.probes.streaming` reads big files a block of rows at a
time.
"""

from __future__ import annotations

import os
import re
import sys
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..limits import check_memory
from .rgbe_numpy import rgbe_scale
from .tonemap import srgb_to_linear

#: Integer pixel formats: display-referred (sRGB-encoded unless tagged linear).
LDR_FORMATS = ("uint8", "uint16", "int8", "int16", "uint32", "int32")


def check_declared_size(p: Path, width: int, height: int, channels: int, min_bytes: int = 0,
                        have: int | None = None, whole: bool = True) -> None:
    """Believe an image header only as far as the file and the memory allow: the pixel data
    cannot be shorter than ``min_bytes`` (a lower bound for the format), and decoding it to
    float32 (with the copies reading makes) must fit
    [`shprobe.limits.check_memory`][shprobe.limits.check_memory] — both checked before anything is
    allocated (the memory only when the image is read ``whole``)."""
    have = p.stat().st_size if have is None else have
    if have < min_bytes:
        raise ShprobeError(f"header declares {width}x{height} pixels but the file holds only "
                           f"{have} bytes of pixel data (truncated or corrupt)", p)
    if whole:  # streamed reads hold a block of rows, not the image
        check_memory(float(width) * height * (4.0 * channels + 24.0),
                     f"decoding a {width}x{height} image", p)



# ----------------------------------------------------------------------------- OpenImageIO


def read_oiio(p: Path) -> tuple[NDArray[np.float32], bool]:
    import OpenImageIO as oiio

    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)  # colour as stored, not premultiplied
    with c_stderr() as c_messages:
        inp = oiio.ImageInput.open(str(p), config)
        if inp is None:
            raise ShprobeError("cannot read image: "
                               + (oneline(oiio.geterror() or c_messages()) or "corrupt"), p)
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
                                   + oneline(inp.geterror() or c_messages()), p)
            cs = str(spec.getattribute("oiio:ColorSpace") or "").lower()
        finally:
            inp.close()
    data = np.asarray(data, dtype=np.float32)
    if data.ndim == 2:
        data = data[:, :, None]
    ldr = fmt in LDR_FORMATS
    if ldr and not ("lin" in cs and "srgb" not in cs):
        data = srgb_to_linear(data)
    return data, ldr



def write_oiio(path: Path, data: NDArray, fmt: str,
               attributes: dict[str, str | float] | None = None) -> None:
    """Write ``data`` (H, W, C) as ``fmt`` (uint8, half, float) with metadata ``attributes``
    (strings: PNG keeps them as text chunks, EXR and TIFF as header attributes)."""
    import OpenImageIO as oiio

    h, w, c = data.shape
    out = oiio.ImageOutput.create(str(path))
    if out is None:
        raise ShprobeError(f"cannot write image: {oneline(oiio.geterror())}", path)
    spec = oiio.ImageSpec(w, h, c, {"uint8": oiio.UINT8, "half": oiio.HALF,
                                    "float": oiio.FLOAT}[fmt])
    if path.suffix.lower() in (".tif", ".tiff"):
        spec.attribute("compression", "zip")
    if path.suffix.lower() in (".jpg", ".jpeg"):
        spec.attribute("Compression", "jpeg:95")
    for key, value in (attributes or {}).items():
        spec.attribute(key, value)
    ok = out.open(str(path), spec) and out.write_image(data)
    err = out.geterror()
    out.close()
    if not ok:
        raise ShprobeError(f"cannot write image: {oneline(err)}", path)


#: The metadata of the exposure (EV) a picture was written with: its pixels are the radiance
#: × 2^EV (then sRGB-encoded for 8-bit files). ``shprobe:exposure`` is exact text (a PNG text
#: chunk, an EXR attribute); JPEG and TIFF keep only standard tags, so the EV is also the Exif
#: exposure bias, believed only in a file whose ``Software`` tag says shprobe (a camera's own
#: exposure bias is not a scale of its pixels).
EXPOSURE_KEY = "shprobe:exposure"
_EXIF_EXPOSURE = "Exif:ExposureBiasValue"


def exposure_metadata(exposure: float, colour_space: str) -> dict[str, str | float]:
    """The attributes `write_oiio` records for a picture written at ``exposure`` stops in
    ``colour_space`` (an OpenImageIO name: "sRGB" for 8-bit pictures, "lin_rec709" for linear
    files)."""
    from .._version import __version__

    return {EXPOSURE_KEY: f"{float(exposure):.9g}", _EXIF_EXPOSURE: float(exposure),
            "oiio:ColorSpace": colour_space, "Software": f"shprobe {__version__}"}


def read_exposure(path: str | os.PathLike[str]) -> float | None:
    """The exposure (EV) shprobe recorded in an image's metadata (`exposure_metadata`),
    or None when the file carries none (a photo, or a format without metadata such as PFM and
    Radiance .hdr)."""
    p = Path(path)
    if p.suffix.lower() == ".pfm" or not p.is_file():
        return None
    import OpenImageIO as oiio

    with c_stderr():
        inp = oiio.ImageInput.open(str(p))
        if inp is None:
            oiio.geterror()  # clear it: reading the pixels reports the problem
            return None
        try:
            spec = inp.spec()
            value = spec.getattribute(EXPOSURE_KEY)
            if value is None and str(spec.getattribute("Software") or "").startswith("shprobe"):
                value = spec.getattribute(_EXIF_EXPOSURE)
        finally:
            inp.close()
    try:
        ev = float(value)
    except (TypeError, ValueError):
        return None
    return ev if np.isfinite(ev) else None


@contextmanager
def c_stderr() -> Iterator[Callable[[], str]]:
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


def oneline(msg: str | None) -> str:
    return " ".join((msg or "").split())[:200]



# ----------------------------------------------------------------------------- PFM


_PFM_HEADER = re.compile(rb"\A(P[Ff])\s+(\d+)\s+(\d+)\s+([-+0-9.eE]+)\s")


def pfm_header(p: Path, head: bytes, size: int) -> tuple[int, int, int, np.dtype, int]:
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


def read_pfm(p: Path) -> NDArray[np.float32]:
    raw = p.read_bytes()
    h, w, c, dt, offset = pfm_header(p, raw, len(raw))
    check_declared_size(p, w, h, c, have=len(raw))
    n = w * h * c
    body = raw[offset:]
    data = np.frombuffer(body, dtype=dt, count=n).reshape(h, w, c)
    return np.ascontiguousarray(data[::-1], dtype=np.float32)  # bottom-up -> top-down


def write_pfm(path: Path, rgb: NDArray[np.float32]) -> None:
    h, w, _ = rgb.shape
    with open(path, "wb") as f:
        f.write(f"PF\n{w} {h}\n-1.0\n".encode("ascii"))
        f.write(np.ascontiguousarray(rgb[::-1], dtype="<f4").tobytes())



# ----------------------------------------------------------------------------- RGBE


_RGBE_SIZE = re.compile(rb"([-+])([XY])\s+(\d+)\s+([-+])([XY])\s+(\d+)")


def rgbe_header(p: Path, raw: bytes) -> tuple[bytes, bytes, bytes, int, int, int]:
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


def rgbe_rows(buf: NDArray[np.uint8], pos: int, out: NDArray[np.float32]
               ) -> tuple[int, int, int]:
    from ._kernels_rgbe import decode_rgbe  # numba, imported lazily

    status, rows, end = decode_rgbe(buf, pos, out, rgbe_scale())
    return int(status), int(rows), int(end)


def rgbe_row_sums(buf: NDArray[np.uint8], pos: int, sums: NDArray[np.float64],
                   weights: NDArray[np.float32]) -> tuple[int, int, int]:
    from ._kernels_rgbe import rgbe_row_sums  # numba, imported lazily

    status, rows, end = rgbe_row_sums(buf, pos, sums, weights, rgbe_scale())
    return int(status), int(rows), int(end)


def read_rgbe(path: str | os.PathLike[str]) -> NDArray[np.float32]:
    """Decode a Radiance RGBE file (flat, old-style and new-style RLE) to ``(H, W, 3)``:
    (m + 0.5) · 2^(e − 136), as Radiance's colr_color. Images up to
    `RGBE_NUMPY_MAX_PIXELS` are decoded by NumPy (no compiled
    kernel to start: `shprobe.probes.rgbe_numpy`), larger ones and what NumPy declines by one
    compiled pass per scanline; the two agree bit for bit."""
    from . import rgbe_numpy

    p = Path(path)
    raw = p.read_bytes()
    s1, a1, s2, n1, n2, offset = rgbe_header(p, raw)
    check_declared_size(p, n2, n1, 4, min_bytes=4 * n1, have=len(raw) - offset)
    body = np.frombuffer(raw, dtype=np.uint8, offset=offset)
    img = np.empty((n1, n2, 3), dtype=np.float32)
    done = n1 * n2 <= rgbe_numpy.RGBE_NUMPY_MAX_PIXELS and rgbe_numpy.decode_rgbe_numpy(body, img)
    if not done and rgbe_rows(body, 0, img)[0] != 0:
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


def rgbe_half_step(img: NDArray[np.float32]) -> NDArray[np.float32]:
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
