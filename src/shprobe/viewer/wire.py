"""The viewer's wire format: the binary messages the page reads (`pack_binary`), the
several files of one upload (`unpack_files`) and the camera as the page needs it."""

from __future__ import annotations

import json
from typing import Any, BinaryIO

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError

__all__ = ["camera_json", "pack_binary", "unpack_files"]


def pack_binary(header: dict[str, Any], arrays: dict[str, NDArray]) -> bytes:
    """One binary message: uint32 header length, JSON header (with each array's dtype, shape
    and byte offset), padding to 4 bytes, then the arrays (little-endian float16 / float32 /
    uint32), each padded to 4 bytes. A NaN or ∞ — in the header, or in an array once cast to
    its wire type — is refused (one-line ShprobeError): the page is never sent one."""
    parts, meta, off = [], {}, 0
    for name, a in arrays.items():
        kind = "f2" if a.dtype == np.float16 else "f4" if a.dtype.kind == "f" else "u4"
        with np.errstate(over="ignore", invalid="ignore"):
            a = np.ascontiguousarray(a, dtype="<" + kind)
        if kind != "u4" and not np.all(np.isfinite(a)):  # never a NaN or ∞ to the page
            raise ShprobeError(f"{name}: values too large for the page's "
                               f"{16 if kind == 'f2' else 32}-bit floats (or not finite)")
        meta[name] = {"dtype": kind, "shape": list(a.shape), "offset": off}
        parts.append(a.tobytes())
        off += a.nbytes + (-a.nbytes % 4)
        parts.append(b"\0" * (-a.nbytes % 4))
    try:
        head = json.dumps({**header, "arrays": meta}, allow_nan=False).encode()
    except ValueError:
        raise ShprobeError("a number for the page is not finite (NaN or ∞)") from None
    head += b" " * (-(len(head) + 4) % 4)
    return len(head).to_bytes(4, "little") + head + b"".join(parts)


def unpack_files(f: BinaryIO, size: int, most: int = 6) -> list[tuple[str, int, int]]:
    """Where the files lie in a multi-file upload body (``f``, ``size`` bytes), as the page
    packs them: uint32 (little-endian) length of a JSON header ``{"files": [{"name": str,
    "size": int}, ...]}``, the header, then the files' bytes one after another; → [(name,
    offset, size)]. Only the header is read. Malformed bodies are a one-line ShprobeError."""
    bad = ShprobeError("malformed multi-file upload")
    head = f.read(4)
    if len(head) < 4:
        raise bad
    n = int.from_bytes(head, "little")
    if not 0 < n <= min(size - 4, 1 << 16):
        raise bad
    try:
        files = json.loads(f.read(n).decode())["files"]
        items = [(str(x["name"]), int(x["size"])) for x in files]
    except (ValueError, KeyError, TypeError, OverflowError, UnicodeDecodeError):
        raise bad from None  # OverflowError: "size": 1e999 → int(inf)
    if not 0 < len(items) <= most or any(s < 0 for _, s in items) \
            or sum(s for _, s in items) != size - 4 - n:
        raise bad
    out, off = [], 4 + n
    for name, k in items:
        out.append((name, off, k))
        off += k
    return out


def camera_json(cam: Any, center: NDArray, radius: float) -> dict[str, Any]:
    """The library camera ([`shprobe.scene.render.Camera`][shprobe.scene.Camera]) as the page needs
    it."""
    c, d, _ = cam.framing(center, radius)
    fwd, _, up = cam.basis()
    eye = c - d * fwd
    return {"eye": eye.tolist(), "target": list(map(float, c)), "up": up.tolist(),
            "fov": cam.fov, "width": cam.width, "height": cam.height,
            "azimuth": cam.azimuth, "elevation": cam.elevation,
            "near": max(d - 2.0 * radius * cam.margin, 1e-3 * d), "far": d + 50.0 * radius}
