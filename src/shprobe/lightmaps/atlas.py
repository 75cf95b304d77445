"""The lightmap's UV set and its texels: TEXCOORD_1 where the scene has one, else an xatlas
atlas with padding between charts; every triangle rasterised to texels; per texel a surface
point and the tangent frame of the normal map (H&W 2010 §4.3).

Rasterisation (the definition the numba kernel implements): texel (r, c) has its centre at
u = (c + ½)/W, v = (r + ½)/H. A texel whose centre lies inside a triangle samples that point;
a texel whose centre lies outside every triangle but within 0.75 texels of one (conservative
coverage: small triangles and chart borders) samples the closest point of the closest such
triangle. Every sample point is then pulled into its triangle's interior (each barycentric
coordinate at least `EDGE_PULL`): a point exactly on an edge may lie on another surface
(a floor's edge under a wall) and see nothing but that surface. Texels no triangle reaches are
filled later by dilation.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from .scene import LightmapScene, Primitive
from .settings import MAX_SIZE, LightmapSettings
from .tangents import arbitrary_tangents, frames_from, vertex_normals, vertex_tangents

__all__ = ["Atlas", "Texels", "build_atlas", "rasterize", "uv_overlap"]


#: smallest barycentric coordinate of a sample point (module docstring: points on edges move in)
EDGE_PULL = 0.02


class OverlapWarning(UserWarning):
    """The scene's own TEXCOORD_1 has overlapping triangles."""


@dataclass(eq=False)
class Atlas:
    """The primitives as baked (after any xatlas vertex split) with their lightmap UVs.

    Parameters
    ----------
    primitives : list of Primitive
        With ``normals``, ``tangents`` and ``uv1`` filled.
    vmaps : list of ndarray or None
        Per primitive, the source vertex of each vertex (xatlas splits seams), or None.
    width, height : int
        Lightmap size in texels.
    made : bool
        True when xatlas made the UVs.
    overlap : float
        Fraction of covered texels claimed by two triangles (given UVs).
    """

    primitives: list[Primitive]
    vmaps: list[NDArray | None] = field(repr=False)
    width: int
    height: int
    made: bool
    overlap: float = 0.0


@dataclass(eq=False)
class Texels:
    """The covered texels of an atlas, flat.

    Parameters
    ----------
    rc : ndarray (P, 2)
        Row and column.
    prim, face : ndarray (P,)
        Primitive and face (global index into the concatenated faces).
    bary : ndarray (P, 3)
        Barycentrics of the sample point.
    points : ndarray (P, 3)
        World-space sample points.
    frames : ndarray (P, 3, 3)
        Rows x, y, z (= the interpolated normal) of the tangent frame.
    uv0 : ndarray (P, 2), optional
        TEXCOORD_0 at the points (NaN where a primitive has none).
    inside : ndarray (P,) bool
        The centre lies inside its triangle (not a conservative border texel).
    """

    rc: NDArray[np.int64]
    prim: NDArray[np.int64]
    face: NDArray[np.int64]
    bary: NDArray[np.float64]
    points: NDArray[np.float64]
    frames: NDArray[np.float64] = field(repr=False)
    uv0: NDArray[np.float64] = field(repr=False)
    inside: NDArray[np.bool_] = field(repr=False)

    @property
    def count(self) -> int:
        """Number of covered texels."""
        return len(self.rc)


def _area(p: NDArray, f: NDArray) -> float:
    t = p[f]
    if t.shape[-1] == 2:
        e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
        return float(0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum())
    return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]),
                                      axis=1).sum())


def _complete(p: Primitive) -> Primitive:
    """Normals and tangents filled in (MikkTSpace-style of TEXCOORD_0 where it exists)."""
    if p.normals is None:
        p.normals = vertex_normals(p.positions, p.faces)
    if p.tangents is None:
        p.tangents = (vertex_tangents(p.positions, p.normals, p.uv0, p.faces)
                      if p.uv0 is not None else arbitrary_tangents(p.normals))
    return p


def _size(total_world: float, total_uv: float, settings: LightmapSettings) -> int:
    if settings.texels_per_unit is None:
        return int(settings.size)
    side = math.sqrt(max(total_world, 1e-30) * settings.texels_per_unit**2
                     / max(total_uv, 1e-30))
    side = int(math.ceil(side / 4.0) * 4)
    if side > MAX_SIZE:
        raise ShprobeError(f"--texels-per-unit {settings.texels_per_unit:g} makes a "
                           f"{side}² lightmap, over {MAX_SIZE}²: lower it")
    return max(side, 4)


def uv_overlap(primitives: list[Primitive], width: int, height: int) -> float:
    """Fraction of covered texel centres that two or more triangles cover strictly.

    Parameters
    ----------
    primitives : list of Primitive
        With ``uv1``.
    width, height : int
        Lightmap size.

    Returns
    -------
    float
        0 for a proper atlas.
    """
    return rasterize(primitives, width, height)[1]


def rasterize(primitives: list[Primitive], width: int, height: int
              ) -> tuple[tuple[NDArray, NDArray, NDArray, NDArray], float]:
    """The texel → (face, barycentrics) map of all primitives' ``uv1`` (module docstring).

    Parameters
    ----------
    primitives : list of Primitive
        With ``uv1``.
    width, height : int
        Lightmap size.

    Returns
    -------
    tuple
        ((face (H, W) global index or −1, bary (H, W, 3), dist (H, W), count (H, W)),
        overlap fraction).
    """
    from ._kernels import raster

    tri = np.concatenate([p.uv1[p.faces] for p in primitives]) * [width, height] - 0.5
    face = np.full((height, width), -1, np.int64)
    bary = np.zeros((height, width, 3))
    dist = np.full((height, width), np.inf)
    count = np.zeros((height, width), np.int32)
    raster(np.ascontiguousarray(tri, dtype=np.float64), width, height, face, bary, dist, count)
    covered = int((count >= 1).sum())
    overlap = float((count >= 2).sum()) / covered if covered else 0.0
    return (face, bary, dist, count), overlap


def build_atlas(scene: LightmapScene, settings: LightmapSettings) -> Atlas:
    """The lightmap UVs: the scene's TEXCOORD_1 when every primitive has one, else xatlas.

    Parameters
    ----------
    scene : LightmapScene
        The scene (checked).
    settings : LightmapSettings
        Size or density, padding.

    Returns
    -------
    Atlas
        Primitives with uv1, normals and tangents; the size.
    """
    prims = [_complete(p) for p in scene.primitives]
    world = sum(_area(p.positions, p.faces) for p in prims)
    if all(p.uv1 is not None for p in prims):
        size = _size(world, sum(_area(p.uv1, p.faces) for p in prims), settings)
        _, overlap = rasterize(prims, size, size)
        if overlap > 0.001:
            warnings.warn(f"the scene's TEXCOORD_1 overlaps itself on {100 * overlap:.1f} % of "
                          "its texels: they share one lighting value", OverlapWarning,
                          stacklevel=2)
        return Atlas(prims, [None] * len(prims), size, size, False, overlap)
    import xatlas

    atlas = xatlas.Atlas()
    for p in prims:
        atlas.add_mesh(p.positions.astype(np.float32), p.faces.astype(np.uint32),
                       p.normals.astype(np.float32))
    def generate(tpu: float | None) -> None:
        pack = xatlas.PackOptions()
        pack.padding = int(settings.padding)
        pack.bilinear = True
        if tpu is not None:
            pack.texels_per_unit = float(tpu)
        else:
            pack.resolution = int(settings.size)
        atlas.generate(pack_options=pack)

    generate(settings.texels_per_unit)
    if settings.texels_per_unit is None:
        # xatlas may overshoot the resolution asked for: shrink the density until it fits
        for _ in range(16):
            if max(atlas.width, atlas.height) <= settings.size and atlas.atlas_count == 1:
                break
            generate(atlas.texels_per_unit * settings.size
                     / max(atlas.width, atlas.height) * 0.9)
        w = h = int(settings.size)
    else:
        w, h = int(atlas.width), int(atlas.height)
    if max(atlas.width, atlas.height) > max(w, h) or atlas.atlas_count != 1:
        raise ShprobeError(f"xatlas could not pack the scene into {w}×{h} texels: raise --size")
    if max(w, h) > MAX_SIZE:
        raise ShprobeError(f"the atlas would be {w}×{h} texels, over {MAX_SIZE}: lower "
                           "--texels-per-unit")
    out, vmaps = [], []
    for i, p in enumerate(prims):
        vm, idx, uv = atlas[i]
        vm = np.asarray(vm, dtype=np.int64)
        q = Primitive(p.positions[vm], np.asarray(idx, dtype=np.int64), p.normals[vm],
                      None if p.uv0 is None else p.uv0[vm], None, p.tangents[vm],
                      p.base_color, p.base_texture, p.normal_texture, p.normal_scale, p.source)
        # xatlas's v grows with the image rows, as glTF's does
        q.uv1 = np.asarray(uv, dtype=np.float64) * [atlas.width / w, atlas.height / h]
        out.append(q)
        vmaps.append(vm)
    return Atlas(out, vmaps, w, h, True)


def texels(atlas: Atlas) -> Texels:
    """The covered texels of an atlas with their sample points and tangent frames.

    Parameters
    ----------
    atlas : Atlas
        From `build_atlas`.

    Returns
    -------
    Texels
        Flat per-texel data.
    """
    (face, bary, dist, _), _ = rasterize(atlas.primitives, atlas.width, atlas.height)
    rr, cc = np.nonzero(face >= 0)
    gf = face[rr, cc]
    # a point on a triangle's edge may lie on another surface (a floor's edge under a wall):
    # every sample is pulled a little into its triangle's interior
    b = np.maximum(bary[rr, cc], EDGE_PULL)
    b /= b.sum(1, keepdims=True)
    starts = np.cumsum([0] + [len(p.faces) for p in atlas.primitives])
    prim = np.searchsorted(starts, gf, side="right") - 1
    pts = np.empty((len(gf), 3))
    nrm = np.empty((len(gf), 3))
    tan = np.empty((len(gf), 4))
    uv0 = np.full((len(gf), 2), np.nan)
    for i, p in enumerate(atlas.primitives):
        sel = np.flatnonzero(prim == i)
        if not len(sel):
            continue
        f = p.faces[gf[sel] - starts[i]]
        w = b[sel][:, :, None]
        pts[sel] = (p.positions[f] * w).sum(1)
        nrm[sel] = (p.normals[f] * w).sum(1)
        tan[sel] = (p.tangents[f] * w).sum(1)
        tan[sel, 3] = np.where(p.tangents[f][:, 0, 3] < 0, -1.0, 1.0)
        if p.uv0 is not None:
            uv0[sel] = (p.uv0[f] * w).sum(1)
    return Texels(np.stack([rr, cc], 1), prim, gf, b, pts, frames_from(nrm, tan), uv0,
                  dist[rr, cc] == 0)
