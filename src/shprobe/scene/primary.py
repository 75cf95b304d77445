"""Primary rays: the camera's rays cast through the one ray caster (or onto the analytic unit
sphere), their first hits with barycentrics, positions and camera-facing normals (`Hits`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .camera import Camera
from .mesh import bounding_sphere
from .raycast import RayCaster

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

__all__ = ["Hits", "trace"]


@dataclass
class Hits:
    """First hits of the primary rays (flat over pixels; miss → face −1).

    Attributes
    ----------
    face
        (P,) triangle index, −1 for a miss.
    bary
        (P, 3) barycentric weights.
    position
        (P, 3) hit points.
    geo_normal
        (P, 3) the triangles' normals.
    normal
        (P, 3) interpolated shading normals.
    directions
        (P, 3) the rays' directions.
    """

    face: NDArray[np.int64]  # (P,) triangle index, -1 where the ray misses
    bary: NDArray[np.float32]  # (P, 3) barycentric weights of the face's 3 vertices
    position: NDArray[np.float64]  # (P, 3) hit point (0 where missed)
    geo_normal: NDArray[np.float64]  # (P, 3) geometric normal facing the camera
    normal: NDArray[np.float32]  # (P, 3) smooth shading normal (unit; 0 where missed)
    directions: NDArray[np.float64]  # (P, 3) ray directions


def trace(mesh: trimesh.Trimesh | None, camera: Camera, caster: RayCaster | None = None,
          frame: tuple[ArrayLike, float] | None = None) -> Hits:
    """Cast the camera's primary rays through [`RayCaster`][shprobe.scene.RayCaster] (built here
    unless ``caster``, one over this mesh, is given) on a mesh, or the analytic unit sphere at the
    origin when ``mesh`` is None. The camera frames ``frame`` = (centre, radius) — by default
    the mesh's bounding sphere.

    Parameters
    ----------
    mesh
        A mesh, or None for the analytic unit sphere.
    camera
        The camera.
    caster
        A ray caster already built over this mesh.
    frame
        (centre, radius) the camera frames (default: the mesh's bounding sphere).

    Returns
    -------
    Hits
        Per pixel: hit or not, face, barycentrics, position and normal.
    """
    center, radius = bounding_sphere(mesh) if frame is None else frame
    origins, dirs = camera.rays(center, radius)
    P = origins.shape[0]
    if mesh is None:
        return _trace_sphere(origins, dirs)
    caster = caster or RayCaster.from_mesh(mesh)
    prim, u, v = caster.first_hit(origins, dirs)
    face = prim.astype(np.int64)
    hit = face >= 0
    fh = face[hit]
    u, v = u[hit], v[hit]
    bary = np.zeros((P, 3), np.float32)
    bary[hit] = np.stack([1.0 - u - v, u, v], axis=-1)  # Embree: p = (1-u-v)v0 + u v1 + v v2
    tri = np.asarray(mesh.faces)[fh]
    V = np.asarray(mesh.vertices, dtype=np.float64)
    b = bary[hit].astype(np.float64)
    pos = np.zeros((P, 3))
    pos[hit] = np.einsum("pk,pkj->pj", b, V[tri])
    vn = np.asarray(mesh.vertex_normals, dtype=np.float32)
    n = np.einsum("pk,pkj->pj", bary[hit], vn[tri])
    fnorm = np.asarray(mesh.face_normals, dtype=np.float64)[fh]
    # face the camera: flip both normals on back faces
    back = np.einsum("pj,pj->p", fnorm, dirs[hit]) > 0.0
    fnorm[back] *= -1.0
    n[back] *= -1.0
    ln = np.linalg.norm(n, axis=-1, keepdims=True)
    bad = ln[:, 0] < 1e-12
    n = np.where(bad[:, None], fnorm.astype(np.float32), n / np.maximum(ln, 1e-30))
    normal = np.zeros((P, 3), np.float32)
    normal[hit] = n
    geo = np.zeros((P, 3))
    geo[hit] = fnorm
    return Hits(face, bary, pos, geo, normal, dirs)


def _trace_sphere(origins: NDArray, dirs: NDArray) -> Hits:
    # |o + t d|² = 1 with |d| = 1: t = −o·d − √((o·d)² − |o|² + 1)
    od = np.einsum("pj,pj->p", origins, dirs)
    disc = od * od - np.einsum("pj,pj->p", origins, origins) + 1.0
    hit = disc >= 0.0
    t = -od - np.sqrt(np.maximum(disc, 0.0))
    pos = np.where(hit[:, None], origins + t[:, None] * dirs, 0.0)
    n = pos / np.maximum(np.linalg.norm(pos, axis=-1, keepdims=True), 1e-30)
    face = np.where(hit, 0, -1).astype(np.int64)
    P = origins.shape[0]
    return Hits(face, np.zeros((P, 3), np.float32), pos, n, n.astype(np.float32), dirs)
