"""glTF 2.0 binary (.glb) with ``KHR_gaussian_splatting``: read and write.

The splats are a POINTS primitive whose attributes are ``POSITION`` (VEC3 float, with the
min/max glTF requires), ``COLOR_0`` (VEC4 normalised bytes: C0·f_dc + 0.5 and the opacity, the
fallback for viewers without the extension) and the extension's
``KHR_gaussian_splatting:ROTATION`` (VEC4 float, x y z w, normalised as the extension
requires), ``…:SCALE`` (VEC3, linear:
exp of the log-scales), ``…:OPACITY`` (SCALAR, sigmoid of the logit) and
``…:SH_DEGREE_l_COEF_n`` (VEC3 per coefficient, the renderer's CS-phase SH, f_dc as degree 0),
laid out as PlayCanvas splat-transform writes them.

glTF's frame is +Y up, +Z forward, +X left (LUF); the trainer's PLY is RDF. Reading returns
splats in the PLY's frame and writing expects them there: the conversion is the 180° turn
about z ([`shprobe.splats.transform.frame`][shprobe.splats.frame]), SH included.
"""

from __future__ import annotations

import json
import os
import struct

import numpy as np

from ..errors import ShprobeError
from ..limits import check_memory
from .cloud import Splats
from .conventions import SH_C0
from .transform import apply, frame

EXT = "KHR_gaussian_splatting"
_FLOAT, _UBYTE = 5126, 5121
_GLB, _JSON, _BIN = 0x46546C67, 0x4E4F534A, 0x004E4942
_WIDTH = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}
#: Component types read (the extension allows quantised rotation, scale and opacity).
_COMPONENTS = {_FLOAT: np.dtype("<f4"), _UBYTE: np.dtype("u1"), 5120: np.dtype("i1"),
               5122: np.dtype("<i2"), 5123: np.dtype("<u2")}


def _unit(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (the extension requires them; trainer files store them unnormalised)."""
    q = q.astype(np.float64)
    n = np.linalg.norm(q, axis=1, keepdims=True)
    return (q / np.where(n > 0, n, 1.0)).astype(np.float32)


def _attributes(s: Splats) -> list[tuple[str, np.ndarray]]:
    """(name, (N, width) array) in the order written."""
    opacity = 1.0 / (1.0 + np.exp(-s.opacity.astype(np.float64)))
    rgb = np.clip(s.sh[:, 0].astype(np.float64) * SH_C0 + 0.5, 0.0, 1.0)
    colour = np.round(np.concatenate([rgb, opacity[:, None]], axis=1) * 255.0).astype(np.uint8)
    scales = s.log_scales
    if scales.shape[1] == 2:  # 2DGS: a flat third axis
        scales = np.concatenate([scales, np.full((s.count, 1), -np.inf, np.float32)], axis=1)
    out = [("POSITION", s.positions), ("COLOR_0", colour),
           (f"{EXT}:ROTATION", _unit(s.rotations)[:, [1, 2, 3, 0]]),
           (f"{EXT}:SCALE", np.exp(scales.astype(np.float64)).astype(np.float32)),
           (f"{EXT}:OPACITY", opacity.astype(np.float32)[:, None])]
    k = 0
    for l in range(s.degree + 1):
        for n in range(2 * l + 1):
            out.append((f"{EXT}:SH_DEGREE_{l}_COEF_{n}", s.sh[:, k]))
            k += 1
    return out


def _pad(b: bytes, fill: bytes) -> bytes:
    return b + fill * (-len(b) % 4)


def encode(s: Splats, generator: str = "shprobe") -> bytes:
    """The .glb bytes of splats given in the PLY's frame."""
    s = apply(s, frame("ply", "gltf"))
    views, accessors, attributes, blobs, offset = [], [], {}, [], 0
    for i, (name, a) in enumerate(_attributes(s)):
        a = np.ascontiguousarray(a)
        data = a.astype("<f4" if a.dtype != np.uint8 else "u1").tobytes()
        width = a.shape[1]
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(data),
                      "target": 34962})
        acc = {"bufferView": i, "byteOffset": 0,
               "componentType": _UBYTE if a.dtype == np.uint8 else _FLOAT,
               "count": s.count, "type": {1: "SCALAR", 3: "VEC3", 4: "VEC4"}[width]}
        if a.dtype == np.uint8:
            acc["normalized"] = True
        if name == "POSITION":
            acc["min"] = [float(v) for v in a.min(axis=0)]
            acc["max"] = [float(v) for v in a.max(axis=0)]
        accessors.append(acc)
        attributes[name] = i
        blobs.append(_pad(data, b"\0"))
        offset += len(blobs[-1])
    binary = b"".join(blobs)
    doc = {"asset": {"version": "2.0", "generator": generator},
           "extensionsUsed": [EXT], "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}], "buffers": [{"byteLength": len(binary)}],
           "bufferViews": views, "accessors": accessors,
           "meshes": [{"primitives": [{"attributes": attributes, "mode": 0, "extensions": {
               EXT: {"kernel": "ellipse", "colorSpace": "srgb_rec709_display",
                     "sortingMethod": "cameraDistance", "projection": "perspective"}}}]}]}
    js = _pad(json.dumps(doc, separators=(",", ":")).encode("utf-8"), b" ")
    total = 12 + 8 + len(js) + 8 + len(binary)
    return b"".join([struct.pack("<III", _GLB, 2, total), struct.pack("<II", len(js), _JSON),
                     js, struct.pack("<II", len(binary), _BIN), binary])


def write(path: str | os.PathLike[str], s: Splats, overwrite: bool = False) -> None:
    """Write a .glb through `shprobe.files` (temporary file renamed into place)."""
    from ..files import atomic_output

    data = encode(s)
    with atomic_output(path, overwrite) as tmp, open(tmp, "wb") as f:
        f.write(data)


def parse(raw: bytes, p: str | None = None) -> tuple[dict, bytes]:
    """(glTF JSON, BIN chunk) of .glb bytes; one line naming the file on any damage."""
    if len(raw) < 20 or struct.unpack_from("<I", raw)[0] != _GLB:
        raise ShprobeError("not a binary glTF (.glb) file", p)
    _, version, total = struct.unpack_from("<III", raw)
    if version != 2 or total > len(raw):
        raise ShprobeError(f"glb version {version} or length {total} is wrong (truncated?)", p)
    jlen, jtype = struct.unpack_from("<II", raw, 12)
    if jtype != _JSON or 20 + jlen > total:
        raise ShprobeError("glb has no JSON chunk first", p)
    try:
        doc = json.loads(raw[20 : 20 + jlen])
    except ValueError:
        raise ShprobeError("glb JSON chunk is not JSON", p) from None
    pos, binary = 20 + jlen, b""
    if pos + 8 <= total:
        blen, btype = struct.unpack_from("<II", raw, pos)
        if btype == _BIN:
            binary = raw[pos + 8 : pos + 8 + blen]
    return doc, binary


def _accessor(doc: dict, binary: bytes, index: int, p) -> np.ndarray:
    try:
        acc = doc["accessors"][index]
        view = doc["bufferViews"][acc["bufferView"]]
        width = _WIDTH[acc["type"]]
        count = int(acc["count"])
        dtype = _COMPONENTS[acc["componentType"]]
    except (KeyError, IndexError, TypeError):
        raise ShprobeError(f"glb accessor {index} is malformed or of an unsupported type",
                           p) from None
    start = int(view.get("byteOffset", 0)) + int(acc.get("byteOffset", 0))
    stride = int(view.get("byteStride", 0)) or width * dtype.itemsize
    need = start + stride * (count - 1) + width * dtype.itemsize
    if count <= 0 or need > len(binary):
        raise ShprobeError(f"glb accessor {index} runs past its buffer (truncated)", p)
    a = np.ndarray((count, width), dtype=dtype, buffer=binary, offset=start,
                   strides=(stride, dtype.itemsize))
    if dtype.kind == "f":
        return a.astype(np.float32)
    if not acc.get("normalized", False):  # e.g. signed-byte SCALE: the integer values
        return a.astype(np.float32)
    # glTF's normalised integers: unsigned c / max, signed max(c / max, −1)
    top = float(np.iinfo(dtype).max)
    return np.maximum(a.astype(np.float32) / np.float32(top), np.float32(-1.0))


def read(path: str | os.PathLike[str]) -> Splats:
    """The splats of a .glb's first ``KHR_gaussian_splatting`` primitive, in the PLY's frame."""
    p = os.fspath(path)
    try:
        size = os.path.getsize(p)
        check_memory(4 * size, "reading this glTF", p)
        with open(p, "rb") as f:
            raw = f.read()
    except FileNotFoundError:
        raise ShprobeError("no such file", p) from None
    except OSError as e:
        raise ShprobeError(f"cannot read: {e.strerror or e}", p) from None
    doc, binary = parse(raw, p)
    prims = [pr for m in doc.get("meshes", []) for pr in m.get("primitives", [])
             if EXT in pr.get("extensions", {})]
    if not prims:
        raise ShprobeError(f"glb has no {EXT} primitive: not Gaussian splats", p)
    att = prims[0].get("attributes", {})
    need = ["POSITION", f"{EXT}:ROTATION", f"{EXT}:SCALE", f"{EXT}:OPACITY",
            f"{EXT}:SH_DEGREE_0_COEF_0"]
    missing = [n for n in need if n not in att]
    if missing:
        raise ShprobeError(f"glb splat primitive lacks {', '.join(missing)}", p)
    get = {n: _accessor(doc, binary, att[n], p) for n in need}
    degree = 0
    while degree < 3 and f"{EXT}:SH_DEGREE_{degree + 1}_COEF_0" in att:
        degree += 1
    if f"{EXT}:SH_DEGREE_4_COEF_0" in att:
        raise ShprobeError("glb holds SH degree 4: the 3DGS renderer evaluates degree ≤ 3", p)
    sh = [get[f"{EXT}:SH_DEGREE_0_COEF_0"]]
    for l in range(1, degree + 1):
        for n in range(2 * l + 1):
            name = f"{EXT}:SH_DEGREE_{l}_COEF_{n}"
            if name not in att:
                raise ShprobeError(f"glb splat primitive lacks {name}", p)
            sh.append(_accessor(doc, binary, att[name], p))
    counts = {a.shape[0] for a in [*get.values(), *sh]}
    if len(counts) != 1:
        raise ShprobeError("glb splat attributes have different counts", p)
    a = np.clip(get[f"{EXT}:OPACITY"][:, 0].astype(np.float64), 1e-7, 1 - 1e-7)
    scale = get[f"{EXT}:SCALE"]
    if np.all(scale[:, 2] == 0):  # 2DGS surfels, as written above: two scales
        scale = scale[:, :2]
    with np.errstate(divide="ignore"):
        log_scales = np.log(scale)
    s = Splats(get["POSITION"], log_scales, get[f"{EXT}:ROTATION"][:, [3, 0, 1, 2]],
               np.log(a / (1.0 - a)), np.stack(sh, axis=1))
    return apply(s, frame("gltf", "ply"))
