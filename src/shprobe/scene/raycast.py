"""The one ray caster: an Embree BVH (embreex) over a triangle mesh, built once, queried in
batches — first hits for cameras and PRT interreflection, occlusion for PRT shadows.

Precision: Embree works in float32. The mesh is stored in a local frame — translated to its
bounding-box centre and scaled to unit extent — so that float32 resolves the same fraction of
the mesh wherever it sits and whatever its units (a mesh at x = 10⁶ keeps its detail).
:meth:`RayCaster.local` maps world points into that frame; directions only change length,
and hits are reported as (face, u, v), which the frame does not change.

Threads: the BVH is committed in the constructor, so that concurrent queries only read it;
embreex releases the GIL while Embree traces, so worker threads run queries in parallel.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

__all__ = ["RayCaster"]


class RayCaster:
    """Embree scene over one triangle mesh: ``vertices`` (V, 3), ``faces`` (F, 3) indices.

    Queries take world-space ray origins and directions (N, 3); the ``*_local`` variants take
    float32 origins already mapped by :meth:`local` (hot loops map their points once and reuse
    them for many rays).
    """

    def __init__(self, vertices: ArrayLike, faces: ArrayLike) -> None:
        from embreex import mesh_construction, rtcore_scene

        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
            raise ShprobeError(f"ray casting needs vertices (V, 3) and faces (F, 3), got "
                               f"{v.shape} and {f.shape}")
        if len(f) == 0:
            raise ShprobeError("mesh has no triangles")
        if not np.all(np.isfinite(v)):
            raise ShprobeError("mesh has non-finite vertex coordinates")
        if f.min() < 0 or f.max() >= len(v):
            raise ShprobeError(f"faces index vertices outside 0..{len(v) - 1}")
        lo, hi = v.min(axis=0), v.max(axis=0)
        ext = float((hi - lo).max())
        self.center = 0.5 * (lo + hi)
        self.scale = 1.0 / ext if ext > 0 else 1.0
        self.n_faces = len(f)
        self._scene = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(self._scene, self.local(v),
                                       np.ascontiguousarray(f, dtype=np.int32))
        # commit (build the BVH) now: worker threads must never race the lazy first commit
        one = np.zeros((1, 3), np.float32)
        self._scene.run(one, one + np.float32(1.0), query="OCCLUDED")

    @classmethod
    def from_mesh(cls, mesh: trimesh.Trimesh) -> RayCaster:
        """A caster over a trimesh mesh's vertices and faces."""
        return cls(mesh.vertices, mesh.faces)

    def local(self, points: ArrayLike) -> NDArray[np.float32]:
        """World points (..., 3) → the caster's frame, float32 (N, 3) C-contiguous."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return np.ascontiguousarray((p - self.center) * self.scale, dtype=np.float32)

    @staticmethod
    def _dirs(dirs: ArrayLike) -> NDArray[np.float32]:
        return np.ascontiguousarray(np.asarray(dirs).reshape(-1, 3), dtype=np.float32)

    def first_hit(self, origins: ArrayLike, dirs: ArrayLike
                  ) -> tuple[NDArray[np.int32], NDArray[np.float32], NDArray[np.float32]]:
        """Closest hit of each ray: (face index or −1, u, v), hit = (1−u−v)p0 + u p1 + v p2."""
        return self.first_hit_local(self.local(origins), self._dirs(dirs))

    def occluded(self, origins: ArrayLike, dirs: ArrayLike) -> NDArray[np.bool_]:
        """True where the ray hits anything (any-hit query)."""
        return self.occluded_local(self.local(origins), self._dirs(dirs))

    def first_hit_local(self, origins: NDArray[np.float32], dirs: NDArray[np.float32]
                        ) -> tuple[NDArray[np.int32], NDArray[np.float32], NDArray[np.float32]]:
        """:meth:`first_hit` for float32 (N, 3) origins in the local frame."""
        if len(origins) == 0:
            return np.empty(0, np.int32), np.empty(0, np.float32), np.empty(0, np.float32)
        r = self._scene.run(origins, dirs, output=1)
        return r["primID"], r["u"], r["v"]

    def occluded_local(self, origins: NDArray[np.float32], dirs: NDArray[np.float32]
                       ) -> NDArray[np.bool_]:
        """:meth:`occluded` for float32 (N, 3) origins in the local frame."""
        if len(origins) == 0:
            return np.empty(0, bool)
        return self._scene.run(origins, dirs, query="OCCLUDED") != -1

    def __repr__(self) -> str:
        return f"RayCaster({self.n_faces} triangles)"
