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
from .cloud import READ_BYTES_PER_FLOAT, Splats, read_bytes
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


#: Largest natural-log scale a .glb can hold: SCALE is exp(log-scale) in float32, whose
#: largest value is 3.4e38 = exp(88.72).
MAX_LOG_SCALE = float(np.log(np.finfo(np.float32).max))


def _sigmoid(x: np.ndarray) -> np.ndarray:
    """1 / (1 + e^−x) in float64; a logit below −709 (e^−x overflows) is exactly 0."""
    with np.errstate(over="ignore"):
        return 1.0 / (1.0 + np.exp(-x.astype(np.float64)))


def _attributes(s: Splats, where=None) -> list[tuple[str, np.ndarray]]:
    """(name, (N, width) array) in the order written; a log-scale whose exp overflows
    float32 is refused."""
    big = s.log_scales.max(axis=1) >= MAX_LOG_SCALE
    if big.any():
        i = int(np.argmax(big))
        raise ShprobeError(f"splat {i} has a log-scale of {float(s.log_scales[i].max()):.4g}: "
                           f"a .glb stores exp(log-scale) as float32, which overflows above "
                           f"{MAX_LOG_SCALE:.4g} (nothing written)", where)
    opacity = _sigmoid(s.opacity)
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


def encode(s: Splats, generator: str = "shprobe", where=None) -> bytes:
    """The .glb bytes of splats given in the PLY's frame.

    Parameters
    ----------
    s : Splats
        The splats, in the PLY's frame.
    generator : str
        The ``asset.generator`` written.
    where : str or os.PathLike, optional
        The file named in a refusal.

    Returns
    -------
    bytes
        The whole .glb file.
    """
    s = apply(s, frame("ply", "gltf"))
    views, accessors, attributes, blobs, offset = [], [], {}, [], 0
    for i, (name, a) in enumerate(_attributes(s, where)):
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

    s.check_finite(os.fspath(path))
    s.check_rotations(os.fspath(path))
    data = encode(s, where=os.fspath(path))
    with atomic_output(path, overwrite) as tmp, open(tmp, "wb") as f:
        f.write(data)


def parse(raw: bytes, p: str | None = None) -> tuple[dict, bytes]:
    """(glTF JSON, BIN chunk) of .glb bytes; one line naming the file on any damage.

    Parameters
    ----------
    raw : bytes
        The whole .glb file.
    p : str, optional
        The file's name, for the messages.

    Returns
    -------
    tuple of (dict, bytes)
        The JSON document (an object: checked) and the binary chunk (empty if none).
    """
    from ..lighting.document import parse_json

    if len(raw) < 20 or struct.unpack_from("<I", raw)[0] != _GLB:
        raise ShprobeError("not a binary glTF (.glb) file", p)
    _, version, total = struct.unpack_from("<III", raw)
    if version != 2 or total > len(raw):
        raise ShprobeError(f"glb version {version} or length {total} is wrong (truncated?)", p)
    jlen, jtype = struct.unpack_from("<II", raw, 12)
    if jtype != _JSON or 20 + jlen > total:
        raise ShprobeError("glb has no JSON chunk first", p)
    try:
        text = raw[20 : 20 + jlen].decode("utf-8")
    except UnicodeDecodeError:
        raise ShprobeError("glb JSON chunk is not UTF-8 text", p) from None
    doc = parse_json(text, p)  # strict: no NaN / Infinity, bounded nesting
    if not isinstance(doc, dict):
        raise ShprobeError(f"glb JSON is a {_kind(doc)}, not an object", p)
    pos, binary = 20 + jlen, b""
    if pos + 8 <= total:
        blen, btype = struct.unpack_from("<II", raw, pos)
        if btype == _BIN:
            binary = raw[pos + 8 : pos + 8 + blen]
    return doc, binary


def _kind(x: object) -> str:
    return {dict: "object", list: "list", str: "string", bool: "boolean", int: "number",
            float: "number", type(None): "null"}.get(type(x), type(x).__name__)


def _get(obj: dict, key: str, kind: type, where: str, p, default: object = ...) -> object:
    """``obj[key]`` checked to be a ``kind`` (an int is never a bool), or one line."""
    if key not in obj:
        if default is ...:
            raise ShprobeError(f"glb {where} has no {key!r}", p)
        return default
    v = obj[key]
    ok = isinstance(v, kind) and not (kind is int and isinstance(v, bool))
    if not ok:
        want = {dict: "an object", list: "a list", int: "an integer", str: "a string",
                bool: "a boolean"}[kind]
        raise ShprobeError(f"glb {where} {key!r} is a {_kind(v)} ({str(v)[:40]}), not {want}",
                           p)
    return v


def _index(obj: dict, key: str, items: list, where: str, p) -> int:
    """An index into ``items``, in range (−1 does not mean the last)."""
    i = _get(obj, key, int, where, p)
    if not 0 <= i < len(items):
        raise ShprobeError(f"glb {where} {key!r} {i} is out of range (0 to {len(items) - 1})", p)
    return i


#: The accessor type of each splat attribute (SH coefficients: VEC3).
_TYPES = {"POSITION": "VEC3", f"{EXT}:ROTATION": "VEC4", f"{EXT}:SCALE": "VEC3",
          f"{EXT}:OPACITY": "SCALAR"}


def _accessor(doc: dict, binary: bytes, index: int, p, name: str = "") -> np.ndarray:
    """The (count, width) values of the accessor of attribute ``name``, every field checked
    (types, ranges, the accessor inside its view, the view inside the buffer) before reading."""
    accessors = _get(doc, "accessors", list, "document", p)
    views = _get(doc, "bufferViews", list, "document", p)
    i = _index({"accessor": index}, "accessor", accessors, f"attribute {name or index}", p)
    acc, where = accessors[i], f"accessor {i} ({name})"
    if not isinstance(acc, dict):
        raise ShprobeError(f"glb {where} is a {_kind(acc)}, not an object", p)
    view_i = _index(acc, "bufferView", views, where, p)
    view = views[view_i]
    if not isinstance(view, dict):
        raise ShprobeError(f"glb bufferView {view_i} is a {_kind(view)}, not an object", p)
    kind = _get(acc, "type", str, where, p)
    want = _TYPES.get(name, "VEC3") if name else kind
    if kind != want or kind not in _WIDTH:
        raise ShprobeError(f"glb {where} is {kind[:20]}, expected {want}", p)
    ctype = _get(acc, "componentType", int, where, p)
    if ctype not in _COMPONENTS:
        raise ShprobeError(f"glb {where} has componentType {ctype}, not one read here", p)
    dtype, width = _COMPONENTS[ctype], _WIDTH[kind]
    count = _get(acc, "count", int, where, p)
    if not 0 < count <= len(binary):
        raise ShprobeError(f"glb {where} count {count} is not between 1 and the buffer's "
                           f"{len(binary)} bytes", p)
    a_off = _get(acc, "byteOffset", int, where, p, 0)
    v_where = f"bufferView {view_i}"
    v_off = _get(view, "byteOffset", int, v_where, p, 0)
    v_len = _get(view, "byteLength", int, v_where, p)
    stride = _get(view, "byteStride", int, v_where, p, 0)
    _get(view, "buffer", int, v_where, p)
    normalized = _get(acc, "normalized", bool, where, p, False)
    item = width * dtype.itemsize
    if min(a_off, v_off, v_len, stride) < 0:
        raise ShprobeError(f"glb {where} or its view has a negative byteOffset, byteLength or "
                           "byteStride", p)
    if stride and stride < item:
        raise ShprobeError(f"glb {v_where} byteStride {stride} is below the element's "
                           f"{item} bytes", p)
    if v_off + v_len > len(binary):
        raise ShprobeError(f"glb {v_where} runs past its buffer (truncated)", p)
    stride = stride or item
    if a_off + stride * (count - 1) + item > v_len:
        raise ShprobeError(f"glb accessor {i} runs past its buffer view (truncated)", p)
    a = np.ndarray((count, width), dtype=dtype, buffer=binary, offset=v_off + a_off,
                   strides=(stride, dtype.itemsize))
    if dtype.kind == "f":
        return a.astype(np.float32)
    if not normalized:  # e.g. signed-byte SCALE: the integer values
        return a.astype(np.float32)
    # glTF's normalised integers: unsigned c / max, signed max(c / max, −1)
    top = float(np.iinfo(dtype).max)
    return np.maximum(a.astype(np.float32) / np.float32(top), np.float32(-1.0))


def _splat_primitive(doc: dict, p) -> dict:
    """The attributes (name → accessor index) of the first splat primitive, every level of
    the JSON checked to be of its type."""
    meshes = _get(doc, "meshes", list, "document", p, [])
    for mi, mesh in enumerate(meshes):
        if not isinstance(mesh, dict):
            raise ShprobeError(f"glb mesh {mi} is a {_kind(mesh)}, not an object", p)
        prims = _get(mesh, "primitives", list, f"mesh {mi}", p, [])
        for pi, prim in enumerate(prims):
            where = f"mesh {mi} primitive {pi}"
            if not isinstance(prim, dict):
                raise ShprobeError(f"glb {where} is a {_kind(prim)}, not an object", p)
            if EXT in _get(prim, "extensions", dict, where, p, {}):
                return _get(prim, "attributes", dict, where, p)
    raise ShprobeError(f"glb has no {EXT} primitive: not Gaussian splats", p)


def read(path: str | os.PathLike[str]) -> Splats:
    """The splats of a .glb's first ``KHR_gaussian_splatting`` primitive, in the PLY's frame."""
    p = os.fspath(path)
    # a FIFO or /dev/zero is refused at once, never read; a splat is ~4 bytes a float in the
    # file, and READ_BYTES_PER_FLOAT in memory while read
    raw = read_bytes(p, round(READ_BYTES_PER_FLOAT[".glb"] / 4))
    doc, binary = parse(raw, p)
    att = _splat_primitive(doc, p)
    need = ["POSITION", f"{EXT}:ROTATION", f"{EXT}:SCALE", f"{EXT}:OPACITY",
            f"{EXT}:SH_DEGREE_0_COEF_0"]
    missing = [n for n in need if n not in att]
    if missing:
        raise ShprobeError(f"glb splat primitive lacks {', '.join(missing)}", p)
    get = {n: _accessor(doc, binary, att[n], p, n) for n in need}
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
            sh.append(_accessor(doc, binary, att[name], p, name))
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
