"""Subdivision of a PRT scene: split marked edges at their midpoints, conforming.

A triangle with two marked edges gets its third marked as well, repeated to closure; then 3
marked → 4 triangles, 1 marked → 2. The input vertices keep their indices (new vertices are
appended), so per-vertex data of the input lines up with the first vertices of the result. New
vertices get the mean of their endpoints' albedo and the input surface's shading normal there:
the barycentric interpolation of the input triangle's vertex normals, normalised, as a renderer
shades the input mesh, kept exact through the rounds by carrying the unnormalised interpolants
(the mean of the ends' *unit* normals, normalised, drifts by a degree or more after a few
levels, enough to move the light under an object lit through a thin slot at grazing angles).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .geometry import BakeScene, mesh_hash

__all__ = ["closed_edges", "edge_table", "split_closed", "split_edges"]


def edge_table(faces: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Unique undirected edges (E, 2) and, per face, the index of its edges (F, 3) in the order
    (v0v1, v1v2, v2v0)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e.sort(axis=1)
    uniq, inv = np.unique(e, axis=0, return_inverse=True)
    return uniq, inv.reshape(3, -1).T


def split_edges(scene: BakeScene, marked: NDArray[np.bool_], edges: NDArray[np.int64],
                face_edges: NDArray[np.int64]) -> BakeScene:
    """Split the ``marked`` edges (closure: a face with 2 marked edges gets its 3rd marked) at
    their midpoints; faces with 3 marked → 4, with 1 → 2 (module doc)."""
    return split_closed(scene, closed_edges(marked, face_edges), edges, face_edges)[0]


def split_closed(scene: BakeScene, sel: NDArray[np.int64], edges: NDArray[np.int64],
           face_edges: NDArray[np.int64], raw: NDArray[np.float64] | None = None
           ) -> tuple[BakeScene, NDArray[np.float64]]:
    """`split_edges` of the closed edge set ``sel`` (`closed_edges`), and the
    unnormalised normals of the result: ``raw`` (default: the scene's normals) holds, for
    every vertex, the barycentric interpolation of its input triangle's vertex normals (an
    input vertex: its own), so a midpoint's is the mean of its ends' and the scene's normal
    is that normalised (module doc)."""
    nv = scene.n_vertices
    mid = np.full(len(edges), -1, dtype=np.int64)
    mid[sel] = nv + np.arange(len(sel))
    a, b = edges[sel, 0], edges[sel, 1]
    v = np.concatenate([scene.vertices, 0.5 * (scene.vertices[a] + scene.vertices[b])])
    raw = scene.normals if raw is None else raw
    rn = 0.5 * (raw[a] + raw[b])
    ln = np.linalg.norm(rn, axis=1, keepdims=True)
    n = np.where(ln > 1e-12, rn / np.where(ln > 1e-12, ln, 1.0), scene.normals[a])
    nrm = np.concatenate([scene.normals, n])
    alb = np.concatenate([scene.albedo, 0.5 * (scene.albedo[a] + scene.albedo[b])])
    f = scene.faces
    m = mid[face_edges]  # (F, 3): midpoint of (v0v1, v1v2, v2v0) or −1
    cnt = (m >= 0).sum(1)
    out = [f[cnt == 0]]
    full = cnt == 3
    if full.any():
        ff, mm = f[full], m[full]
        out += [np.stack([ff[:, 0], mm[:, 0], mm[:, 2]], 1),
                np.stack([mm[:, 0], ff[:, 1], mm[:, 1]], 1),
                np.stack([mm[:, 2], mm[:, 1], ff[:, 2]], 1),
                np.stack([mm[:, 0], mm[:, 1], mm[:, 2]], 1)]
    one = cnt == 1
    if one.any():
        ff, mm = f[one], m[one]
        k = np.argmax(mm >= 0, axis=1)  # which edge: (v_k, v_{k+1}) split at its midpoint
        r = np.arange(len(ff))
        p0, p1, p2 = ff[r, k], ff[r, (k + 1) % 3], ff[r, (k + 2) % 3]
        q = mm[r, k]
        out += [np.stack([p0, q, p2], 1), np.stack([q, p1, p2], 1)]
    faces = np.concatenate(out).astype(np.int64)
    return BakeScene(v, nrm, faces, alb, mesh_hash(v, faces)), np.concatenate([raw, rn])


def closed_edges(marked: NDArray[np.bool_], face_edges: NDArray[np.int64]) -> NDArray:
    """The edge indices `split_edges` splits (marked, closed), in its order."""
    m = marked.copy()
    while True:
        cnt = m[face_edges].sum(1)
        two = cnt == 2
        if not two.any():
            break
        m[face_edges[two].ravel()] = True
    return np.flatnonzero(m)

