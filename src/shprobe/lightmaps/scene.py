"""Scenes to bake: glTF 2.0 (.glb / .gltf) and OBJ read into flat world-space primitives with
their materials' base colour (factor and texture) and normal maps.

Every (node, mesh primitive) instance of a TRIANGLES primitive becomes one
[`Primitive`][shprobe.lightmaps.Primitive] in world space (a mesh used by two nodes needs two
lightmap regions). Textures are decoded to float arrays: base colour sRGB → linear, normal maps as
stored.
"""

from __future__ import annotations

import base64
import io
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from .format import parse_glb

__all__ = ["LightmapScene", "Primitive", "load_scene"]

_DTYPES = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


@dataclass(eq=False)
class Primitive:
    """One triangle primitive in world space.

    Parameters
    ----------
    positions : ndarray (V, 3)
        World-space vertex positions.
    faces : ndarray (F, 3)
        Vertex indices, counter-clockwise = front.
    normals : ndarray (V, 3), optional
        World-space unit vertex normals (None: flat normals are made).
    uv0, uv1 : ndarray (V, 2), optional
        TEXCOORD_0 (material textures) and TEXCOORD_1 (lightmap) in glTF UV convention.
    tangents : ndarray (V, 4), optional
        World-space TANGENT (xyz, handedness w).
    base_color : ndarray (4,)
        Base colour factor (linear RGBA).
    base_texture : ndarray (H, W, 3), optional
        Base colour texture, linear.
    normal_texture : ndarray (H, W, 3), optional
        Normal map values in [0, 1] as stored.
    normal_scale : float
        glTF normalTexture.scale.
    source : tuple, optional
        (node, mesh, primitive) indices in the glTF document.
    """

    positions: NDArray[np.float64]
    faces: NDArray[np.int64]
    normals: NDArray[np.float64] | None = None
    uv0: NDArray[np.float64] | None = None
    uv1: NDArray[np.float64] | None = None
    tangents: NDArray[np.float64] | None = None
    base_color: NDArray[np.float64] = field(default_factory=lambda: np.ones(4))
    base_texture: NDArray[np.float32] | None = field(default=None, repr=False)
    normal_texture: NDArray[np.float32] | None = field(default=None, repr=False)
    normal_scale: float = 1.0
    source: tuple[int, int, int] | None = None


@dataclass(eq=False)
class LightmapScene:
    """Primitives to bake, and the glTF document they came from (None for OBJ / arrays).

    Parameters
    ----------
    primitives : list of Primitive
        The scene's triangle primitives in world space.
    doc : dict, optional
        The glTF JSON (kept so that the output keeps the scene).
    binary : bytes
        Its BIN chunk.
    path : str, optional
        The file read.
    """

    primitives: list[Primitive]
    doc: dict | None = field(default=None, repr=False)
    binary: bytes = field(default=b"", repr=False)
    path: str | None = None

    @property
    def n_faces(self) -> int:
        """Triangles over all primitives."""
        return sum(len(p.faces) for p in self.primitives)


def _srgb_to_linear(c: NDArray) -> NDArray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _decode_image(data: bytes, where: str) -> NDArray[np.float32]:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(io.BytesIO(data)) as im:
            a = np.asarray(im.convert("RGB"), dtype=np.float32) / 255.0
    except (UnidentifiedImageError, OSError, ValueError):
        raise ShprobeError("a texture cannot be decoded (not a readable PNG/JPEG)",
                           where) from None
    return a


class _Reader:
    def __init__(self, doc: dict, binary: bytes, path: str) -> None:
        self.doc, self.binary, self.path = doc, binary, path
        self.folder = os.path.dirname(os.path.abspath(path))
        self._buffers: dict[int, bytes] = {}
        self._images: dict[int, NDArray] = {}

    def _uri(self, uri: str) -> bytes:
        if uri.startswith("data:"):
            try:
                return base64.b64decode(uri.split(",", 1)[1])
            except (ValueError, IndexError):
                raise ShprobeError("a data URI is not base64", self.path) from None
        p = os.path.join(self.folder, uri)
        try:
            with open(p, "rb") as f:
                return f.read()
        except OSError as e:
            raise ShprobeError(f"cannot read {uri}: {e.strerror or e}", self.path) from None

    def buffer(self, i: int) -> bytes:
        if i not in self._buffers:
            b = self.doc["buffers"][i]
            self._buffers[i] = self._uri(b["uri"]) if "uri" in b else self.binary
        return self._buffers[i]

    def view(self, i: int) -> bytes:
        v = self.doc["bufferViews"][i]
        start = int(v.get("byteOffset", 0))
        data = self.buffer(int(v["buffer"]))
        if start + int(v["byteLength"]) > len(data):
            raise ShprobeError(f"bufferView {i} runs past its buffer (truncated)", self.path)
        return data[start:start + int(v["byteLength"])]

    def accessor(self, i: int) -> NDArray[np.float64]:
        try:
            a = self.doc["accessors"][i]
            dt = np.dtype(_DTYPES[a["componentType"]])
            width, count = _WIDTH[a["type"]], int(a["count"])
        except (KeyError, IndexError, TypeError):
            raise ShprobeError(f"accessor {i} is malformed", self.path) from None
        if "bufferView" not in a:
            return np.zeros((count, width))
        v = self.doc["bufferViews"][a["bufferView"]]
        data = self.view(int(a["bufferView"]))
        off = int(a.get("byteOffset", 0))
        stride = int(v.get("byteStride", 0)) or width * dt.itemsize
        if count and off + stride * (count - 1) + width * dt.itemsize > len(data):
            raise ShprobeError(f"accessor {i} runs past its bufferView (truncated)", self.path)
        out = np.ndarray((count, width), dt, data, off, (stride, dt.itemsize)).astype(np.float64)
        if a.get("normalized") and dt.kind in "iu":
            out = np.maximum(out / np.iinfo(dt).max, -1.0)
        return out

    def image(self, tex_index: int) -> NDArray[np.float32]:
        try:
            src = int(self.doc["textures"][tex_index]["source"])
            im = self.doc["images"][src]
        except (KeyError, IndexError, TypeError):
            raise ShprobeError(f"texture {tex_index} has no readable image", self.path) from None
        if src not in self._images:
            data = self.view(int(im["bufferView"])) if "bufferView" in im else self._uri(
                im.get("uri", ""))
            self._images[src] = _decode_image(data, self.path)
        return self._images[src]


def _node_matrix(n: dict) -> NDArray[np.float64]:
    if "matrix" in n:
        return np.asarray(n["matrix"], dtype=np.float64).reshape(4, 4).T
    t = np.asarray(n.get("translation", [0, 0, 0]), dtype=np.float64)
    x, y, z, w = np.asarray(n.get("rotation", [0, 0, 0, 1]), dtype=np.float64)
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = r * np.asarray(n.get("scale", [1, 1, 1]), dtype=np.float64)
    m[:3, 3] = t
    return m


def _instances(doc: dict) -> list[tuple[int, int, NDArray[np.float64]]]:
    """(node, mesh, world matrix) of every node with a mesh, in the default scene."""
    nodes = doc.get("nodes", [])
    scenes = doc.get("scenes")
    roots = (scenes[doc.get("scene", 0)].get("nodes", []) if scenes
             else list(range(len(nodes))))
    out, stack = [], [(int(r), np.eye(4)) for r in roots]
    seen = 0
    while stack:
        i, parent = stack.pop()
        seen += 1
        if seen > 1_000_000:
            raise ShprobeError("the node hierarchy has a cycle")
        m = parent @ _node_matrix(nodes[i])
        if "mesh" in nodes[i]:
            out.append((i, int(nodes[i]["mesh"]), m))
        stack.extend((int(c), m) for c in nodes[i].get("children", []))
    return sorted(out, key=lambda t: t[0])


def _primitive(r: _Reader, node: int, mesh: int, k: int, pr: dict, m: NDArray) -> Primitive:
    att = pr.get("attributes", {})
    if "POSITION" not in att:
        raise ShprobeError(f"mesh {mesh} primitive {k} has no POSITION", r.path)
    pos = r.accessor(att["POSITION"])
    faces = (r.accessor(pr["indices"]).reshape(-1).astype(np.int64) if "indices" in pr
             else np.arange(len(pos)))
    if len(faces) % 3:
        raise ShprobeError(f"mesh {mesh} primitive {k}: index count not a multiple of 3", r.path)
    faces = faces.reshape(-1, 3)
    if faces.size and (faces.max() >= len(pos) or faces.min() < 0):
        raise ShprobeError(f"mesh {mesh} primitive {k} indexes past its vertices", r.path)
    lin, nrm_m = m[:3, :3], np.linalg.inv(m[:3, :3]).T
    if np.linalg.det(lin) < 0:
        faces = faces[:, ::-1].copy()
    p = Primitive(pos @ lin.T + m[:3, 3], faces, source=(node, mesh, k))
    if "NORMAL" in att:
        n = r.accessor(att["NORMAL"]) @ nrm_m.T
        p.normals = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    if "TEXCOORD_0" in att:
        p.uv0 = r.accessor(att["TEXCOORD_0"])
    if "TEXCOORD_1" in att:
        p.uv1 = r.accessor(att["TEXCOORD_1"])
    if "TANGENT" in att:
        t = r.accessor(att["TANGENT"])
        t[:, :3] = t[:, :3] @ lin.T
        t[:, :3] /= np.maximum(np.linalg.norm(t[:, :3], axis=1, keepdims=True), 1e-30)
        p.tangents = t
    if "material" in pr:
        mat = r.doc["materials"][int(pr["material"])]
        pbr = mat.get("pbrMetallicRoughness", {})
        p.base_color = np.asarray(pbr.get("baseColorFactor", [1, 1, 1, 1]), dtype=np.float64)
        if "baseColorTexture" in pbr:
            p.base_texture = _srgb_to_linear(r.image(int(pbr["baseColorTexture"]["index"])))
        if "normalTexture" in mat:
            p.normal_texture = r.image(int(mat["normalTexture"]["index"]))
            p.normal_scale = float(mat["normalTexture"].get("scale", 1.0))
    return p


def _load_gltf(path: str) -> LightmapScene:
    with open(path, "rb") as f:
        raw = f.read()
    if path.lower().endswith(".glb"):
        doc, binary = parse_glb(raw, path)
    else:
        import json

        try:
            doc, binary = json.loads(raw), b""
        except ValueError:
            raise ShprobeError("is not glTF JSON", path) from None
    r = _Reader(doc, binary, path)
    prims = []
    try:
        for node, mesh, m in _instances(doc):
            for k, pr in enumerate(doc["meshes"][mesh].get("primitives", [])):
                if pr.get("mode", 4) == 4:
                    prims.append(_primitive(r, node, mesh, k, pr, m))
    except (KeyError, IndexError, TypeError, ValueError) as e:
        raise ShprobeError(f"malformed glTF ({type(e).__name__}: {e})", path) from None
    if doc.get("buffers") and "uri" in doc["buffers"][0]:
        binary = r.buffer(0)  # written back as the .glb's BIN chunk
    return LightmapScene(prims, doc, binary, path)


def _load_obj(path: str) -> LightmapScene:
    import trimesh

    try:
        loaded = trimesh.load(path, force="scene", process=False)
    except Exception as e:  # trimesh raises many types on bad files
        raise ShprobeError(f"cannot read OBJ: {e}", path) from None
    prims = []
    for geom in loaded.dump():
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        p = Primitive(np.asarray(geom.vertices, dtype=np.float64),
                      np.asarray(geom.faces, dtype=np.int64))
        p.normals = np.asarray(geom.vertex_normals, dtype=np.float64)  # the file's, else made
        vis = getattr(geom, "visual", None)
        uv = getattr(vis, "uv", None)
        if uv is not None and len(uv) == len(geom.vertices):
            p.uv0 = np.asarray(uv, dtype=np.float64) * [1, -1] + [0, 1]  # OBJ v is up
        mat = getattr(vis, "material", None)
        img = getattr(mat, "image", None) if mat is not None else None
        if img is not None:
            p.base_texture = _srgb_to_linear(np.asarray(img.convert("RGB"), np.float32) / 255)
        diffuse = getattr(mat, "diffuse", None) if mat is not None else None
        if diffuse is not None and img is None:
            p.base_color = _srgb_to_linear(np.asarray(diffuse, dtype=np.float64)[:4] / 255.0)
        prims.append(p)
    return LightmapScene(prims, None, b"", path)


def load_scene(path: str | os.PathLike[str]) -> LightmapScene:
    """Read a .glb, .gltf or .obj scene.

    Parameters
    ----------
    path : str or PathLike
        The scene file.

    Returns
    -------
    LightmapScene
        Its triangle primitives in world space (and the glTF document, for glTF).
    """
    p = os.fspath(path)
    if not os.path.isfile(p):
        raise ShprobeError("no such file", p)
    ext = os.path.splitext(p)[1].lower()
    if ext in (".glb", ".gltf"):
        return _load_gltf(p)
    if ext == ".obj":
        return _load_obj(p)
    raise ShprobeError(f"unknown scene format {ext!r} (.glb, .gltf or .obj)", p)


def scene_info(scene: LightmapScene) -> dict[str, Any]:
    """A summary of a scene (counts), JSON-able.

    Parameters
    ----------
    scene : LightmapScene
        The scene.

    Returns
    -------
    dict
        Primitive, triangle and normal-map counts.
    """
    return {"primitives": len(scene.primitives), "triangles": scene.n_faces,
            "normal_maps": sum(p.normal_texture is not None for p in scene.primitives)}
