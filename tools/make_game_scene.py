"""Make src/shprobe/lightmaps/data/courtyard.glb: the packaged game scene for the lightmap bake.

Run from the repository root: ``python tools/make_game_scene.py [-o OUT.glb]``.

A walled courtyard (16 m × 16 m, walls 6 m high, a doorway in the west wall) with an arcade
along the south side (five semicircular stone arches on four columns under a roof slab, the
covered walk behind it lit mostly by bounced light) and a stack of wooden crates: about 2,500
triangles in five nodes (floor, walls, arcade, pillars, crates) and four materials, each with
a procedural base-colour texture and a tangent-space normal map made here from a height
field (flagstone grooves, brick mortar, ashlar joints, crate planks and frame).

Conventions (glTF 2.0): +Y up, metres, faces wound counter-clockwise seen from outside, the
walls' outer faces left out (never seen from the courtyard, as game levels do). TEXCOORD_0
tiles the textures by world size (bricks 0.5 m × 0.25 m); there is no TEXCOORD_1 (the bake
makes the lightmap atlas). Normal maps are OpenGL-style as glTF requires: red = +u (image
right), green = image up (decreasing v), blue = out of the surface. Every primitive carries
TANGENT: xyz along increasing u, w such that cross(normal, tangent.xyz)·w points up the image
(decreasing v), the frame MikkTSpace gives these flat and cylindrical faces.

Deterministic: fixed seeds, integer-exact noise, PNGs compressed by zlib at level 9; a test
checks that the committed file equals this script's output.
"""

from __future__ import annotations

import argparse
import itertools
import json
import struct
import zlib
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
TARGET = REPO / "src" / "shprobe" / "lightmaps" / "data" / "courtyard.glb"
TEX = 256  # texture side, px
UP = np.array([0.0, 1.0, 0.0])


# ---------------------------------------------------------------------------- textures
def _noise(rng: np.random.Generator, cells: int, size: int = TEX) -> np.ndarray:
    """Periodic value noise in [0, 1): a ``cells``² random lattice, smoothstep-interpolated."""
    g = rng.random((cells, cells))
    x = np.arange(size) * cells / size
    i0 = np.floor(x).astype(int)
    f = x - i0
    f = f * f * (3 - 2 * f)
    i1 = (i0 + 1) % cells
    a = g[i0][:, i0] * (1 - f)[None, :] + g[i0][:, i1] * f[None, :]
    b = g[i1][:, i0] * (1 - f)[None, :] + g[i1][:, i1] * f[None, :]
    return a * (1 - f)[:, None] + b * f[:, None]


def _fbm(rng: np.random.Generator, cells: int, octaves: int = 4) -> np.ndarray:
    """Fractal sum of periodic value noise, mean about 0, amplitude about 1."""
    out = np.zeros((TEX, TEX))
    amp = 1.0
    for _ in range(octaves):
        out += amp * (_noise(rng, cells) - 0.5)
        cells, amp = min(cells * 2, TEX), amp * 0.5
    return out


def _blocks(rows: int, widths: list[list[int]], offsets: list[int], joint: float):
    """Running-bond blocks: per pixel the block id and the distance (px) to the nearest joint.

    ``widths[r]`` are the block widths (px, summing to TEX) of row ``r``, shifted by
    ``offsets[r]`` px; rows are ``TEX / rows`` px high; ``joint`` is the half-width of the joints.
    """
    h = TEX // rows
    ids = np.zeros((TEX, TEX), int)
    dist = np.zeros((TEX, TEX))
    col = np.arange(TEX)
    n = 0
    for r in range(rows):
        edges = np.concatenate([[0], np.cumsum(widths[r])])
        x = (col - offsets[r]) % TEX
        k = np.searchsorted(edges, x, side="right") - 1
        dx = np.minimum(x - edges[k], edges[k + 1] - x)
        y = np.arange(h)
        dy = np.minimum(y, h - y)
        ids[r * h:(r + 1) * h] = n + k[None, :]
        dist[r * h:(r + 1) * h] = np.minimum(dx[None, :], dy[:, None]) - joint
        n += len(widths[r])
    return ids, dist


def _srgb8(lin: np.ndarray) -> np.ndarray:
    c = np.clip(lin, 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    return np.round(s * 255).astype(np.uint8)


def _normal8(height: np.ndarray, depth: float) -> np.ndarray:
    """Tangent-space normal map (glTF: +X image right, +Y image up) of a periodic height field
    given in px units times ``depth``."""
    dcol = (np.roll(height, -1, 1) - np.roll(height, 1, 1)) * 0.5 * depth
    drow = (np.roll(height, -1, 0) - np.roll(height, 1, 0)) * 0.5 * depth
    n = np.stack([-dcol, drow, np.ones_like(height)], -1)  # image up = decreasing row
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.round((n * 0.5 + 0.5) * 255).astype(np.uint8)


def _tint(rng, n: int, base, spread: float) -> np.ndarray:
    return np.asarray(base) * (1 + spread * (rng.random((n, 1)) - 0.5)) * (
        1 + 0.1 * spread * (rng.random((n, 3)) - 0.5))


def brick(rng):
    """Red bricks in running bond, 8 courses of 4 per texture (2 m × 2 m), grey mortar."""
    ids, d = _blocks(8, [[64] * 4] * 8, [0, 32] * 4, 1.5)
    bevel = np.clip(d / 3.0, 0, 1)
    grain = _fbm(rng, 16)
    height = np.where(d > 0, 2.0 * bevel + 0.4 * grain, 0.3 * grain)
    tint = _tint(rng, ids.max() + 1, (0.42, 0.15, 0.09), 0.5)
    col = np.where((d > 0)[..., None], tint[ids], np.array([0.45, 0.43, 0.40]))
    col *= (1 + 0.35 * _fbm(rng, 32))[..., None]
    return _srgb8(col), _normal8(height, 1.2)


def flagstone(rng):
    """Grey flagstones, 4 rows of irregular widths per texture (4 m × 4 m), sunken joints."""
    widths = [[64, 96, 96], [80, 48, 128], [112, 80, 64], [48, 96, 112]]
    ids, d = _blocks(4, widths, [0, 40, 17, 90], 2.0)
    bevel = np.clip(d / 5.0, 0, 1)
    bumps = _fbm(rng, 8, 5)
    height = np.where(d > 0, 3.0 * bevel + 2.0 * bumps, 0.5 * bumps)
    tint = _tint(rng, ids.max() + 1, (0.30, 0.28, 0.25), 0.5)
    col = np.where((d > 0)[..., None], tint[ids], np.array([0.12, 0.11, 0.10]))
    col *= (1 + 0.4 * _fbm(rng, 16))[..., None]
    return _srgb8(col), _normal8(height, 1.0)


def ashlar(rng):
    """Sandstone ashlar, 4 courses of 2 blocks per texture (2 m × 2 m), bumpy faces."""
    ids, d = _blocks(4, [[128, 128]] * 4, [0, 64] * 2, 1.0)
    bevel = np.clip(d / 4.0, 0, 1)
    bumps = _fbm(rng, 8, 5)
    height = np.where(d > 0, 2.0 * bevel + 3.0 * bumps, 0.0)
    tint = _tint(rng, ids.max() + 1, (0.55, 0.45, 0.30), 0.3)
    col = np.where((d > 0)[..., None], tint[ids], np.array([0.40, 0.36, 0.30]))
    col *= (1 + 0.25 * _fbm(rng, 16))[..., None]
    return _srgb8(col), _normal8(height, 1.0)


def crate(rng):
    """A crate face (the whole texture per face): a raised frame and diagonal brace over five
    vertical planks with seams and grain."""
    y, x = np.mgrid[0:TEX, 0:TEX] + 0.5
    plank = np.floor(x / (TEX / 5)).astype(int)
    seam = np.abs((x % (TEX / 5)) - TEX / 10)  # distance from the plank's middle
    seam = np.clip((TEX / 10 - seam) / 2.0, 0, 1)  # 0 in the seam, 1 on the plank
    grain = np.sin(x * 0.9 + 6 * _fbm(rng, 8)) * 0.5 + 0.5
    frame = np.minimum.reduce([x, y, TEX - x, TEX - y]) < 28
    brace = np.abs(x - y) < 20
    top = frame | brace
    height = np.where(top, 3.0, 1.5 * seam) + 0.15 * grain
    tint = _tint(rng, 5, (0.40, 0.24, 0.11), 0.35)
    col = tint[plank] * (0.8 + 0.2 * grain)[..., None]
    col = np.where(top[..., None], np.array([0.33, 0.19, 0.08]) * (0.85 + 0.15 * grain)[..., None],
                   col)
    return _srgb8(col), _normal8(height, 1.0)


# ---------------------------------------------------------------------------- geometry
class Mesh:
    """Triangles with per-vertex normals and TEXCOORD_0, built face by face."""

    def __init__(self, scale: float):
        self.scale = scale  # metres per texture repeat (0 = one repeat per face)
        self.p: list[np.ndarray] = []
        self.n: list[np.ndarray] = []
        self.uv: list[np.ndarray] = []
        self.f: list[np.ndarray] = []
        self.count = 0

    def grid(self, p: np.ndarray, n: np.ndarray, uv: np.ndarray) -> None:
        """Add an (a+1, b+1) vertex grid as a×b quads (counter-clockwise about ``n``)."""
        a, b = p.shape[0] - 1, p.shape[1] - 1
        idx = self.count + np.arange((a + 1) * (b + 1)).reshape(a + 1, b + 1)
        q00, q10, q11, q01 = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
        tri = np.stack([np.stack([q00, q10, q11], -1), np.stack([q00, q11, q01], -1)], 2)
        self.f.append(tri.reshape(-1, 3))
        self.p.append(p.reshape(-1, 3))
        self.n.append(np.broadcast_to(n, p.shape).reshape(-1, 3))
        self.uv.append(uv.reshape(-1, 2))
        self.count += (a + 1) * (b + 1)

    def quad(self, o, ea, eb, step: float = 1.0) -> None:
        """A planar rectangle from corner ``o`` spanned by ``ea``, ``eb`` (normal ea × eb),
        subdivided to about ``step`` metres; box-mapped UVs."""
        o, ea, eb = (np.asarray(v, float) for v in (o, ea, eb))
        na = max(1, round(np.linalg.norm(ea) / step))
        nb = max(1, round(np.linalg.norm(eb) / step))
        s, t = np.linspace(0, 1, na + 1), np.linspace(0, 1, nb + 1)
        p = o + s[:, None, None] * ea + t[None, :, None] * eb
        n = np.cross(ea, eb)
        n /= np.linalg.norm(n)
        if self.scale == 0:  # one texture repeat over the face, image up along eb
            uv = np.stack(np.broadcast_arrays(s[:, None], 1 - t[None, :]), -1)
        elif abs(n[1]) > 0.5:  # floors, tops and ceilings: u = x, v = z
            uv = p[..., [0, 2]] / self.scale
        else:  # walls: u along the wall, image up = world up
            tu = np.cross(UP, n)
            uv = np.stack([p @ tu, -p[..., 1]], -1) / self.scale
        self.grid(p, n, uv)

    def box(self, lo, hi, skip: str = "", step: float = 1.0, rot: float = 0.0) -> None:
        """An axis-aligned box (turned by ``rot`` radians about its vertical axis) without the
        faces named in ``skip`` (any of "-x +x -y +y -z +z")."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        c, e = (lo + hi) / 2, (hi - lo)
        cr, sr = np.cos(rot), np.sin(rot)
        R = np.array([[cr, 0, sr], [0, 1, 0], [-sr, 0, cr]])
        X, Y, Z = R @ [e[0], 0, 0], R @ [0, e[1], 0], R @ [0, 0, e[2]]
        o = c - (X + Y + Z) / 2
        faces = {"-x": (o, Z, Y), "+x": (o + X + Z, -Z, Y), "-z": (o + X, -X, Y),
                 "+z": (o + Z, X, Y), "-y": (o, X, Z), "+y": (o + Y + Z, X, -Z)}
        for name, (fo, ea, eb) in faces.items():
            if name not in skip.split():
                self.quad(fo, ea, eb, step)

    def arrays(self):
        return (np.concatenate(self.p), np.concatenate(self.n), np.concatenate(self.uv),
                np.concatenate(self.f))

    def cylinder(self, cx: float, cz: float, r: float, y0: float, y1: float, sides: int) -> None:
        """The side of an upright cylinder (no caps), UVs wrapped around it."""
        th = -2 * np.pi * np.arange(sides + 1) / sides  # decreasing: counter-clockwise outside
        ys = np.array([y0, y1])
        n = np.stack(np.broadcast_arrays(np.cos(th)[:, None], 0.0 * ys, np.sin(th)[:, None]), -1)
        p = np.array([cx, 0.0, cz]) + r * n + ys[None, :, None] * UP
        u = np.arange(sides + 1)[:, None] / sides * 2 * np.pi * r + 0 * ys
        uv = np.stack([u, -p[..., 1]], -1) / self.scale
        self.grid(p, n, uv)

    def arch(self, x0: float, x1: float, pad0: float, pad1: float, y: tuple, z: tuple,
             segs: int = 24) -> None:
        """A wall panel from x0 to x1 and y[0] (the springing) to y[1], z[0] to z[1] thick, with
        a semicircular opening from x0 + pad0 to x1 - pad1: front, back and the intrados."""
        xa, xb = x0 + pad0, x1 - pad1
        xc, r = (xa + xb) / 2, (xb - xa) / 2
        th = np.linspace(np.pi, 0, segs + 1)
        xs = np.concatenate([[x0] if pad0 else [], xc + r * np.cos(th), [x1] if pad1 else []])
        yb = np.concatenate([[y[0]] if pad0 else [], y[0] + r * np.sin(th),
                             [y[0]] if pad1 else []])
        for zz, sign in ((z[0], -1.0), (z[1], 1.0)):
            order = slice(None, None, -1) if sign < 0 else slice(None)
            xo, yo = xs[order], yb[order]
            p = np.stack(np.broadcast_arrays(xo[:, None], np.stack([yo, 0 * yo + y[1]], 1),
                                             zz + 0 * yo[:, None]), -1)
            uv = np.stack([sign * p[..., 0], -p[..., 1]], -1) / self.scale
            self.grid(p, np.array([0, 0, sign]), uv)
        zs = np.array(z)
        c = np.stack([np.cos(th), np.sin(th), 0 * th], -1)
        p = (np.array([xc, y[0], 0]) + r * c)[:, None, :] + zs[None, :, None] * [0, 0, 1]
        arc = r * (np.pi - th)
        uv = np.stack(np.broadcast_arrays(arc[:, None], zs[None, :]), -1) / self.scale
        self.grid(p, -c[:, None, :] + 0 * p, uv)


def tangents(p, n, uv, f):
    """glTF TANGENT (x, y, z, w) per vertex: xyz along increasing u, orthogonal to the normal;
    w = ±1 so that cross(normal, xyz)·w points up the image (decreasing v)."""
    e1, e2 = p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]
    d1, d2 = uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    r = np.where(np.abs(det) > 1e-12, 1 / np.where(det == 0, 1, det), 0)[:, None]
    dpdu = (e1 * d2[:, 1:] - e2 * d1[:, 1:]) * r
    dpdv = (e2 * d1[:, :1] - e1 * d2[:, :1]) * r
    tu, tv = np.zeros_like(p), np.zeros_like(p)
    for k in range(3):
        np.add.at(tu, f[:, k], dpdu)
        np.add.at(tv, f[:, k], dpdv)
    t = tu - n * np.sum(tu * n, -1, keepdims=True)
    t /= np.linalg.norm(t, axis=-1, keepdims=True)
    w = np.where(np.sum(np.cross(n, t) * -tv, -1) >= 0, 1.0, -1.0)
    return np.concatenate([t, w[:, None]], -1)


def build():
    """The courtyard's meshes: {node name: (Mesh, material index)}."""
    floor, walls, arcade, pillars, crates = Mesh(4), Mesh(2), Mesh(2), Mesh(2), Mesh(0)
    floor.quad((-8, 0, 8), (16, 0, 0), (0, 0, -16))
    walls.box((-8, 0, -8.5), (8, 6, -8), "-x +x -y -z")  # north
    walls.box((-8, 0, 8), (8, 6, 8.5), "-x +x -y +z")  # south, behind the arcade
    walls.box((8, 0, -8.5), (8.5, 6, 8.5), "+x -y -z +z")  # east
    walls.box((-8.5, 0, -8.5), (-8, 6, -1), "-x -y -z")  # west, beside the doorway
    walls.box((-8.5, 0, 1), (-8, 6, 8.5), "-x -y +z")
    walls.box((-8.5, 3, -1), (-8, 6, 1), "-x -z +z")  # the doorway's lintel
    supports = [-8.0, -4.8, -1.6, 1.6, 4.8, 8.0]  # the walls and the four columns
    z, ys, ytop = (4.75, 5.25), 3.2, 5.0
    for a, b in itertools.pairwise(supports):
        arcade.arch(a, b, 0.25, 0.25, (ys, ytop), z)
    arcade.box((-8, 0, 4.75), (-7.75, ys, 5.25), "-x -y +y")  # pilasters against the walls
    arcade.box((7.75, 0, 4.75), (8, ys, 5.25), "+x -y +y")
    arcade.box((-8, ytop, 4.75), (8, 5.3, 8), "-x +x +z")  # the walk's roof
    for x in supports[1:-1]:
        pillars.box((x - 0.3, 0, 4.7), (x + 0.3, 0.3, 5.3), "-y")  # plinth
        pillars.cylinder(x, 5.0, 0.2, 0.3, 2.95, 16)
        pillars.box((x - 0.3, 2.95, 4.7), (x + 0.3, ys, 5.3))  # capital
    for lo, hi, rot in [((5.5, 0, -7.9), (6.5, 1, -6.9), 0.0),
                        ((6.6, 0, -7.9), (7.6, 1, -6.9), 0.0),
                        ((6.0, 1, -7.85), (7.0, 2, -6.85), 0.1),
                        ((6.7, 0, -6.5), (7.4, 0.7, -5.8), 0.35),
                        ((-6.5, 0, -3.0), (-5.7, 0.8, -2.2), -0.4),
                        ((2.0, 0, -1.0), (3.0, 1.0, 0.0), 0.6)]:
        crates.box(lo, hi, "-y", step=2.0, rot=rot)
    return {"floor": (floor, 0), "walls": (walls, 1), "arcade": (arcade, 2),
            "pillars": (pillars, 2), "crates": (crates, 3)}


# ---------------------------------------------------------------------------- glTF
def png(img: np.ndarray) -> bytes:
    """A PNG (8-bit RGB, filter 0, zlib level 9) of an (H, W, 3) uint8 image."""
    h, w = img.shape[:2]

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    raw = b"".join(b"\x00" + img[r].tobytes() for r in range(h))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


MATERIALS = [("flagstone", flagstone, 11), ("brick", brick, 12), ("ashlar", ashlar, 13),
             ("crate", crate, 14)]


def make() -> bytes:
    """The bytes of the courtyard .glb."""
    doc: dict = {"asset": {"version": "2.0", "generator": "shprobe tools/make_game_scene.py"},
                 "scene": 0, "scenes": [{"name": "courtyard", "nodes": []}], "nodes": [],
                 "meshes": [], "materials": [], "textures": [], "images": [],
                 "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497,
                               "wrapT": 10497}],
                 "accessors": [], "bufferViews": []}
    blob = bytearray()

    def view(data: bytes, target: int | None = None) -> int:
        blob.extend(b"\0" * (-len(blob) % 4))
        v = {"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)}
        if target:
            v["target"] = target
        blob.extend(data)
        doc["bufferViews"].append(v)
        return len(doc["bufferViews"]) - 1

    def accessor(a: np.ndarray, kind: str, minmax: bool = False) -> int:
        ct = {np.float32: 5126, np.uint16: 5123, np.uint32: 5125}[a.dtype.type]
        target = 34963 if kind == "SCALAR" else 34962
        acc = {"bufferView": view(a.tobytes(), target), "componentType": ct, "count": len(a),
               "type": kind}
        if minmax:
            acc["min"], acc["max"] = a.min(0).tolist(), a.max(0).tolist()
        doc["accessors"].append(acc)
        return len(doc["accessors"]) - 1

    for name, fn, seed in MATERIALS:
        colour, normal = fn(np.random.default_rng(seed))
        for img in (colour, normal):
            doc["images"].append({"bufferView": view(png(img)), "mimeType": "image/png"})
            doc["textures"].append({"sampler": 0, "source": len(doc["images"]) - 1})
        k = len(doc["textures"])
        doc["materials"].append({"name": name, "pbrMetallicRoughness": {
            "baseColorTexture": {"index": k - 2}, "metallicFactor": 0.0, "roughnessFactor": 1.0},
            "normalTexture": {"index": k - 1}})
    for name, (mesh, mat) in build().items():
        p, n, uv, f = mesh.arrays()
        t = tangents(p, n, uv, f)
        attrs = {"POSITION": accessor(p.astype(np.float32), "VEC3", True),
                 "NORMAL": accessor(n.astype(np.float32), "VEC3"),
                 "TANGENT": accessor(t.astype(np.float32), "VEC4"),
                 "TEXCOORD_0": accessor(uv.astype(np.float32), "VEC2")}
        ind = accessor(f.reshape(-1).astype(np.uint16 if len(p) < 65536 else np.uint32),
                       "SCALAR")
        doc["meshes"].append({"name": name, "primitives": [
            {"attributes": attrs, "indices": ind, "material": mat, "mode": 4}]})
        doc["nodes"].append({"name": name, "mesh": len(doc["meshes"]) - 1})
        doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)
    blob.extend(b"\0" * (-len(blob) % 4))
    doc["buffers"] = [{"byteLength": len(blob)}]
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    total = 12 + 8 + len(js) + 8 + len(blob)
    return (struct.pack("<III", 0x46546C67, 2, total) + struct.pack("<II", len(js), 0x4E4F534A)
            + js + struct.pack("<II", len(blob), 0x004E4942) + bytes(blob))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--output", type=Path, default=TARGET)
    a = ap.parse_args()
    data = make()
    a.output.parent.mkdir(parents=True, exist_ok=True)
    a.output.write_bytes(data)
    print(f"wrote {a.output} ({len(data)} bytes)")


if __name__ == "__main__":
    main()
