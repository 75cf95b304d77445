"""Rays from probes: the first surface each direction meets, its distance and whether the
probe sees its back (the one ray caster,
[`shprobe.scene.raycast.RayCaster`][shprobe.scene.RayCaster])."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..scene.raycast import RayCaster

__all__ = ["ProbeHits", "ProbeTracer"]

#: Rays per Embree call (bounds the float32 ray buffers to a few tens of MB).
RAYS_PER_CALL = 1 << 20


@dataclass(frozen=True)
class ProbeHits:
    """First hits of D directions from P probes: face (P, D) int32 (−1: none), u, v (P, D)
    barycentrics, dist (P, D) world distance (inf: none), back (P, D) True where the ray met
    the back of its face."""

    face: NDArray[np.int32]
    u: NDArray[np.float32]
    v: NDArray[np.float32]
    dist: NDArray[np.float32]
    back: NDArray[np.bool_]


class ProbeTracer:
    """A ray caster over a scene's triangles with their geometric (winding) normals."""

    def __init__(self, vertices: NDArray[np.float64], faces: NDArray[np.int64]) -> None:
        self.caster = RayCaster(vertices, faces)
        self.vertices = np.asarray(vertices, dtype=np.float64)
        self.faces = np.asarray(faces, dtype=np.int64)
        self.face_normals = self.caster.face_normals

    def trace(self, origins: NDArray[np.float64], dirs: NDArray[np.float64],
              on_block=None, distances: bool = True) -> ProbeHits:
        """First hits of every direction of ``dirs`` (D, 3) — or of each origin's own
        directions (P, D, 3) — from each origin (P, 3); ``distances=False`` leaves ``dist``
        at inf where there is a hit too (it is the costly part)."""
        o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        d = np.asarray(dirs, dtype=np.float64)
        per = d.shape[-2]
        shared = d.ndim == 2
        face = np.empty((len(o), per), np.int32)
        u = np.empty((len(o), per), np.float32)
        v = np.empty((len(o), per), np.float32)
        step = max(1, RAYS_PER_CALL // per)
        local = self.caster.local(o)
        for a in range(0, len(o), step):
            b = min(len(o), a + step)
            dd = d if shared else d[a:b]
            oo = np.repeat(local[a:b], per, axis=0)
            rd = np.ascontiguousarray(np.broadcast_to(dd, (b - a, per, 3)).reshape(-1, 3),
                                      dtype=np.float32)
            f, uu, vv = self.caster.first_hit_local(oo, rd)
            face[a:b], u[a:b], v[a:b] = (x.reshape(b - a, per) for x in (f, uu, vv))
            if on_block is not None:
                on_block(b - a)
        hit = face >= 0
        fi = np.maximum(face, 0)
        dist = np.full(face.shape, np.inf)
        if distances:
            x = self.points(fi, u, v)
            dist = np.where(hit, np.linalg.norm(x - o[:, None, :], axis=-1), np.inf)
        dfull = np.broadcast_to(d, (len(o), per, 3))
        back = hit & (np.einsum("pdc,pdc->pd", dfull, self.face_normals[fi]) > 0)
        return ProbeHits(face, u, v, dist.astype(np.float32), back)

    def points(self, face: NDArray, u: NDArray, v: NDArray) -> NDArray[np.float64]:
        """Points (..., 3) at barycentrics (u, v) of faces (...)."""
        return self.interpolate(self.vertices, face, u, v)

    def interpolate(self, per_vertex: NDArray, face: NDArray, u: NDArray, v: NDArray
                    ) -> NDArray[np.float64]:
        """Per-vertex values (V, C) at barycentrics (u, v) of faces (...): (..., C)."""
        fv = np.asarray(per_vertex, dtype=np.float64)[self.faces[face]]
        uu, vv = u[..., None].astype(np.float64), v[..., None].astype(np.float64)
        return (1 - uu - vv) * fv[..., 0, :] + uu * fv[..., 1, :] + vv * fv[..., 2, :]
