"""Per-vertex tangent frames of a triangle mesh, and world SH turned into a frame (Habel & Wimmer
2010 §4.1).

A frame is a rotation matrix F (3×3) whose columns are (t, b, n) — tangent, bitangent, normal —
in world coordinates, right-handed (b = n × t, det F = +1). A tangent-space direction v has world
direction F v; z = v·(0,0,1) is the normal.

* With UVs: t is the per-vertex average of the triangle tangents ∂p/∂u (area weighted, the
  usual Lengyel construction), Gram–Schmidt orthogonalised against the vertex normal; b = n × t.
  ``handedness`` = sign((n × t) · ∂p/∂v) is returned so a mirrored normal map can flip its
  green channel; the irradiance frame itself is always right-handed.
* Without UVs (or where ∂p/∂u degenerates): the branchless frame of Duff et al. 2017
  ("Building an orthonormal basis, revisited") from the normal alone — continuous except at
  n = (0, 0, −1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh.rotation import frame_from_normal, rotate, unit_vectors

__all__ = ["Frames", "tangent_frames", "to_tangent_sh"]


@dataclass
class Frames:
    """Per-vertex tangent frames: ``matrix`` (V, 3, 3) columns (t, b, n); ``handedness`` (V,)
    is +1, or −1 where the UV chart is mirrored (0 where no UV tangent was available)."""

    matrix: NDArray[np.float64]
    handedness: NDArray[np.float64]


def tangent_frames(vertices: ArrayLike, faces: ArrayLike, normals: ArrayLike | None = None,
                   uvs: ArrayLike | None = None) -> Frames:
    """Per-vertex tangent frames of a triangle mesh (see the module docstring)."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise ShprobeError(f"need vertices (V, 3) and faces (F, 3), got {v.shape}, {f.shape}")
    p0, p1, p2 = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    if normals is None:
        fn = np.cross(p1 - p0, p2 - p0)  # area-weighted face normals
        nrm = np.zeros_like(v)
        for i in range(3):
            np.add.at(nrm, f[:, i], fn)
        normals = nrm
    n = unit_vectors(normals, "normals", zero="keep")
    frames = frame_from_normal(n)
    hand = np.zeros(len(v))
    if uvs is None:
        return Frames(frames, hand)
    uv = np.asarray(uvs, dtype=np.float64)
    e1, e2 = p1 - p0, p2 - p0
    d1, d2 = uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    # tangent ∂p/∂u and bitangent ∂p/∂v times det (keeps the area weight, no division)
    tu = e1 * d2[:, 1:2] - e2 * d1[:, 1:2]
    tv = e2 * d1[:, 0:1] - e1 * d2[:, 0:1]
    sgn = np.sign(det)[:, None]
    tu, tv = tu * sgn, tv * sgn
    at, ab = np.zeros_like(v), np.zeros_like(v)
    for i in range(3):
        np.add.at(at, f[:, i], tu)
        np.add.at(ab, f[:, i], tv)
    t = at - np.sum(at * n, axis=-1, keepdims=True) * n
    tn = np.linalg.norm(t, axis=-1)
    ok = tn > 1e-12 * np.maximum(1.0, np.linalg.norm(at, axis=-1))
    t = t / np.where(ok, tn, 1.0)[:, None]
    b = np.cross(n, t)
    uvf = np.stack([t, b, n], axis=-1)
    frames[ok] = uvf[ok]
    hand[ok] = np.where(np.sum(b * ab, axis=-1)[ok] < 0, -1.0, 1.0)
    return Frames(frames, hand)


def to_tangent_sh(sh_coeffs: ArrayLike, frames: ArrayLike) -> NDArray[np.float64]:
    """SH coefficients (..., K, C) of v ↦ E(F v) for world SH coefficients (K, C) and frames
    (..., 3, 3): ``rotate(e, Fᵀ)``."""
    e = np.asarray(sh_coeffs, dtype=np.float64)
    if e.ndim == 1:
        e = e[:, None]
    fr = np.asarray(frames, dtype=np.float64)
    return rotate(e, np.swapaxes(fr, -1, -2))
