"""Lightmaps in files: the baked scene written as a .glb with TEXCOORD_1, TANGENT and the
``SHPROBE_lightmap`` coefficient textures (`shprobe.lightmaps.format`), and
[`load_lightmap`][shprobe.lightmaps.load_lightmap]."""

from __future__ import annotations

import copy
import io
import os
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from .format import add_lightmap, write_glb
from .scene import Primitive

if TYPE_CHECKING:  # pragma: no cover
    from .result import Lightmap

__all__ = ["write_lightmap_glb"]

_FLOAT, _U32 = 5126, 5125


class _Buf:
    def __init__(self, doc: dict, binary: bytes) -> None:
        self.doc, self.bin = doc, bytearray(binary)
        self.doc.setdefault("buffers", [{"byteLength": 0}])
        if not self.doc["buffers"]:
            self.doc["buffers"].append({"byteLength": 0})
        self.doc["buffers"][0].pop("uri", None)

    def view(self, data: bytes, target: int | None = None) -> int:
        self.bin.extend(b"\0" * (-len(self.bin) % 4))
        v = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target:
            v["target"] = target
        self.bin.extend(data)
        views = self.doc.setdefault("bufferViews", [])
        views.append(v)
        return len(views) - 1

    def accessor(self, a: NDArray, kind: str, index: bool = False) -> int:
        a = np.ascontiguousarray(a, dtype=np.uint32 if index else np.float32)
        acc = {"bufferView": self.view(a.tobytes(), 34963 if index else 34962),
               "componentType": _U32 if index else _FLOAT, "count": len(a), "type": kind}
        if kind == "VEC3" and not index:
            acc["min"] = a.min(0).tolist()
            acc["max"] = a.max(0).tolist()
        accs = self.doc.setdefault("accessors", [])
        accs.append(acc)
        return len(accs) - 1

    def png(self, rgb: NDArray) -> int:
        from PIL import Image

        out = io.BytesIO()
        Image.fromarray(np.round(np.clip(rgb, 0, 1) * 255).astype(np.uint8)).save(out, "PNG")
        images = self.doc.setdefault("images", [])
        images.append({"bufferView": self.view(out.getvalue()), "mimeType": "image/png"})
        textures = self.doc.setdefault("textures", [])
        textures.append({"source": len(images) - 1})
        return len(textures) - 1


def _linear_to_srgb(c: NDArray) -> NDArray:
    c = np.clip(c, 0, 1)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)


def _attributes(b: _Buf, p: Primitive, inv: NDArray, shift: NDArray) -> dict[str, int]:
    """Accessors of a baked primitive in its node's frame (inv: world → local linear part)."""
    nrm_m = np.linalg.inv(inv).T
    att = {"POSITION": b.accessor((p.positions - shift) @ inv.T, "VEC3")}
    n = p.normals @ nrm_m.T
    att["NORMAL"] = b.accessor(n / np.linalg.norm(n, axis=1, keepdims=True), "VEC3")
    # glTF numbers a semantic's sets from 0 without gaps: a primitive without its own
    # TEXCOORD_0 gets the lightmap UVs there too
    att["TEXCOORD_0"] = b.accessor(p.uv0 if p.uv0 is not None else p.uv1, "VEC2")
    att["TEXCOORD_1"] = b.accessor(p.uv1, "VEC2")
    t = p.tangents.copy()
    t[:, :3] = t[:, :3] @ inv.T
    t[:, :3] /= np.maximum(np.linalg.norm(t[:, :3], axis=1, keepdims=True), 1e-30)
    att["TANGENT"] = b.accessor(t, "VEC4")
    return att


def _node_world(doc: dict, node: int) -> NDArray:
    from .scene import _instances

    for n, _, m in _instances(doc):
        if n == node:
            return m
    return np.eye(4)


def _fresh(lm: Lightmap, b: _Buf) -> list[tuple[int, int]]:
    doc = b.doc
    doc.setdefault("scenes", [{"nodes": []}])
    doc.setdefault("scene", 0)
    prims = []
    for p in lm.atlas.primitives:  # type: ignore[union-attr]
        mat: dict = {"pbrMetallicRoughness": {"baseColorFactor": [float(x) for x in
                                                                   p.base_color[:4]],
                                              "metallicFactor": 0.0}}
        if p.base_texture is not None:
            mat["pbrMetallicRoughness"]["baseColorTexture"] = {
                "index": b.png(_linear_to_srgb(p.base_texture))}
        if p.normal_texture is not None:
            mat["normalTexture"] = {"index": b.png(p.normal_texture), "scale": p.normal_scale}
        doc.setdefault("materials", []).append(mat)
        prim = {"attributes": _attributes(b, p, np.eye(3), np.zeros(3)),
                "indices": b.accessor(p.faces.reshape(-1), "SCALAR", index=True),
                "material": len(doc["materials"]) - 1, "mode": 4}
        doc.setdefault("meshes", []).append({"primitives": [prim]})
        doc.setdefault("nodes", []).append({"mesh": len(doc["meshes"]) - 1})
        doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)
        prims.append((len(doc["meshes"]) - 1, 0))
    return prims


def _into_source(lm: Lightmap, b: _Buf) -> list[tuple[int, int]]:
    doc = b.doc
    owner: dict[int, int] = {}  # mesh → the node whose instance it now holds
    prims = []
    for p in lm.atlas.primitives:  # type: ignore[union-attr]
        node, mesh, k = p.source  # type: ignore[misc]
        if owner.setdefault(mesh, node) != node:  # a second instance: its own copy
            clone = copy.deepcopy(doc["meshes"][mesh])
            doc["meshes"].append(clone)
            new = len(doc["meshes"]) - 1
            doc["nodes"][node]["mesh"] = new
            owner[new] = node
            mesh = new
        elif doc["nodes"][node]["mesh"] != mesh:
            mesh = doc["nodes"][node]["mesh"]
        m = _node_world(doc, node)
        inv = np.linalg.inv(m[:3, :3])
        pr = doc["meshes"][mesh]["primitives"][k]
        old = pr.get("attributes", {})
        att = _attributes(b, p, inv, m[:3, 3])
        if lm.atlas.vmaps[lm.atlas.primitives.index(p)] is None:  # type: ignore[union-attr]
            att = {**old, **{k2: v for k2, v in att.items() if k2 in ("TEXCOORD_1", "TANGENT")
                             or k2 not in old}}
        pr["attributes"] = att
        pr["indices"] = b.accessor(p.faces.reshape(-1), "SCALAR", index=True)
        pr.pop("targets", None)  # morph targets do not survive the vertex split
        prims.append((mesh, k))
    return prims


def _embed_images(b: _Buf, source: str | None) -> None:
    """Images the source .gltf kept in files go into the .glb's buffer."""
    folder = os.path.dirname(os.path.abspath(source or "."))
    for im in b.doc.get("images", []):
        uri = im.pop("uri", None)
        if uri is None:
            continue
        if uri.startswith("data:"):
            import base64

            data = base64.b64decode(uri.split(",", 1)[1])
        else:
            try:
                with open(os.path.join(folder, uri), "rb") as f:
                    data = f.read()
            except OSError as e:
                raise ShprobeError(f"cannot read {uri}: {e.strerror or e}", source) from None
        im["bufferView"] = b.view(data)
        im.setdefault("mimeType", "image/jpeg" if data[:2] == b"\xff\xd8" else "image/png")


def write_lightmap_glb(lm: Lightmap, path: str | os.PathLike[str],
                       overwrite: bool = False) -> None:
    """Write the scene of a baked lightmap with its coefficient textures
    (`shprobe.lightmaps.format`).

    Parameters
    ----------
    lm : Lightmap
        A baked lightmap (with its atlas and scene).
    path : str or PathLike
        The output .glb.
    overwrite : bool
        Replace an existing file.
    """
    if lm.atlas is None:
        raise ShprobeError("only a baked lightmap (with its scene) can be written", path)
    scene = lm.scene
    if scene is not None and scene.doc is not None and all(
            p.source is not None for p in lm.atlas.primitives):
        doc = copy.deepcopy(scene.doc)
        for buf in doc.get("buffers", [])[1:]:
            if "uri" in buf and not buf["uri"].startswith("data:"):
                raise ShprobeError("glTF files with several external buffers are written "
                                   "as .glb only when their buffers are one", path)
        b = _Buf(doc, scene.binary)
        _embed_images(b, scene.path)
        prims = _into_source(lm, b)
    else:
        b = _Buf({"asset": {"version": "2.0", "generator": "shprobe"}}, b"")
        prims = _fresh(lm, b)
    b.doc.setdefault("asset", {"version": "2.0"})
    extra = {k: lm.stats[k] for k in ("samples", "bounces") if k in lm.stats}
    add_lightmap(b.doc, b.bin, lm.basis, lm.coefficients(), prims, extra)
    if lm.transfer and lm.basis in lm.transfer:
        from .transfer_format import add_transfer

        add_transfer(b.doc, b.bin, lm.transfer[lm.basis], lm.stats.get("sky"))
    write_glb(path, b.doc, b.bin, overwrite)
