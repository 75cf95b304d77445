"""The one ray caster: an Embree BVH (embreex) over a triangle mesh, built once, queried in
batches — first hits for cameras and PRT interreflection, occlusion for PRT shadows.

Precision: Embree works in float32. The mesh is stored in a local frame — translated to its
bounding-box centre and scaled to unit extent — so that float32 resolves the same fraction of
the mesh wherever it sits and whatever its units (a mesh at x = 10⁶ keeps its detail).
[`RayCaster.local`][shprobe.scene.RayCaster.local] maps world points into that frame; directions
only change length, and hits are reported as (face, u, v), which the frame does not change.

Ray origins ([`RayCaster.offset_points`][shprobe.scene.RayCaster.offset_points]): rays leave a
surface point from a copy moved a small distance along its normal, so that they do not hit the
surface they leave. Where that step crosses *another* surface — a mesh vertex touching the ground,
whose downward normal would put the origin under the ground, where it sees the open sky — the origin
is put back on the point's side of the surface crossed, a hundredth of the step from it. The bake
(`shprobe.prt.directions`) and the independent reference of the tests use this one rule.

Threads: the BVH is committed in the constructor, so that concurrent queries only read it;
embreex releases the GIL while Embree traces, so worker threads run queries in parallel.
"""

from __future__ import annotations

from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh.rotation import unit_vectors

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

__all__ = ["RayCaster"]


class RayCaster:
    """Embree scene over one triangle mesh: ``vertices`` (V, 3), ``faces`` (F, 3) indices.

    Queries take world-space ray origins and directions (N, 3); the ``*_local`` variants take
    float32 origins already mapped by [`local`][shprobe.scene.RayCaster.local] (hot loops map their
    points once and reuse them for many rays).

    Parameters
    ----------
    vertices
        (V, 3) positions.
    faces
        (F, 3) vertex indices.
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
        self._vertices = v
        self._faces = np.ascontiguousarray(f, dtype=np.int32)
        self._local_vertices = self.local(v)
        self._other_scenes: dict[int, Any] = {}
        self._other_ids: dict[int, NDArray[np.int64]] = {}
        self._scene = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(self._scene, self._local_vertices, self._faces)
        # commit (build the BVH) now: worker threads must never race the lazy first commit
        one = np.zeros((1, 3), np.float32)
        self._scene.run(one, one + np.float32(1.0), query="OCCLUDED")

    @classmethod
    def from_mesh(cls, mesh: trimesh.Trimesh) -> RayCaster:
        """A caster over a trimesh mesh's vertices and faces.

        Parameters
        ----------
        mesh
            A trimesh mesh.

        Returns
        -------
        RayCaster
            The caster.
        """
        return cls(mesh.vertices, mesh.faces)

    def local(self, points: ArrayLike) -> NDArray[np.float32]:
        """World points (..., 3) → the caster's frame, float32 (N, 3) C-contiguous.

        Parameters
        ----------
        points
            (..., 3) world points.

        Returns
        -------
        ndarray of shape (N, 3), float32
            The points in the caster's frame.
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return np.ascontiguousarray((p - self.center) * self.scale, dtype=np.float32)

    def offset_points(self, points: ArrayLike, normals: ArrayLike, offset: float,
                      faces: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Ray origins for surface points (N, 3) with unit normals (N, 3), each lying on the
        face ``faces[i]`` (for a vertex: any face that uses it; −1: on none): p + offset·n,
        except where the step from p crosses, or starts on, a surface of *another* connected
        part of the mesh (module doc): there, the point where it crosses, moved offset/100
        along that surface's normal back to p's side. Returns the world-space origins (N, 3)
        float64 and which of them were put back.

        The point's own part is left out of the test (its own surface passes through p, and a
        ray cast towards p cannot tell it from another surface through p, as at a vertex
        touching the ground); parts are the connected components of the faces' vertices.

        Parameters
        ----------
        points
            (N, 3) surface points.
        normals
            (N, 3) unit normals there.
        offset
            The step along the normal.
        faces
            (N,) a face each point lies on (−1: none).

        Returns
        -------
        tuple of ndarray
            The ray origins (N, 3) and which of them were put back (N,).
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        on = np.asarray(faces, dtype=np.int64).reshape(-1)
        off = float(offset)
        o = p + off * n
        crossed = np.zeros(len(p), dtype=bool)
        if len(p) == 0 or off <= 0:
            return o, crossed
        if on.shape != (len(p),) or on.max(initial=-1) >= self.n_faces:
            raise ShprobeError(f"offset_points needs one face index per point (< "
                               f"{self.n_faces}), got shape {on.shape}")
        part = np.where(on >= 0, self._parts[np.maximum(on, 0)], -1)
        for c in np.unique(part):
            i = np.flatnonzero(part == c)
            scene, ids = self._near_others(int(c), o[i], p[i], off)
            if scene is None:
                continue
            # from the offset origin back to p and a hair beyond (a surface through p counts)
            reach = np.full(len(i), 1.001 * off * self.scale, dtype=np.float32)
            r = scene.run(self.local(o[i]), self._dirs(-n[i]), dists=reach, output=1)
            hit = r["primID"] >= 0
            if not hit.any():
                continue
            i, prim = i[hit], ids[r["primID"][hit]]
            t = r["tfar"][hit].astype(np.float64) / self.scale  # world distance back from o
            x = o[i] - t[:, None] * n[i]
            fn = self.face_normals[prim]
            side = np.where(np.einsum("ij,ij->i", -n[i], fn) >= 0, 1.0, -1.0)
            o[i] = x + (0.01 * off * side)[:, None] * fn
            crossed[i] = True
        return o, crossed

    @cached_property
    def face_normals(self) -> NDArray[np.float64]:
        """Unit geometric normals (F, 3) of the faces (counter-clockwise winding = front);
        zero for degenerate faces (made on first use:
        [`offset_points`][shprobe.scene.RayCaster.offset_points], where an origin crossed another
        surface, and the grid bake's probe tracer)."""
        fv = self._vertices[self._faces]
        return unit_vectors(np.cross(fv[:, 1] - fv[:, 0], fv[:, 2] - fv[:, 0]), zero="keep")

    @cached_property
    def _parts(self) -> NDArray[np.int64]:
        """Connected part of each face (faces sharing a vertex are connected)."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        f = self._faces
        nv = int(f.max()) + 1
        rows = np.concatenate([f[:, 0], f[:, 1]])
        cols = np.concatenate([f[:, 1], f[:, 2]])
        g = coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(nv, nv))
        _, label = connected_components(g, directed=False)
        return label[f[:, 0]].astype(np.int64)

    @cached_property
    def _face_boxes(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        fv = self._vertices[self._faces]
        return fv.min(axis=1), fv.max(axis=1)

    def _near_others(self, part: int, o: NDArray, p: NDArray, off: float
                     ) -> tuple[Any, NDArray[np.int64] | None]:
        """An Embree scene of the faces not in ``part`` whose bounding boxes meet the box of
        the steps from ``p`` to ``o`` (only they can be crossed: the same hits as the scene of
        all other faces, without building it per part), and the faces' indices; (None, None)
        if there are none."""
        pad = 2.0 * off + 1e-5 / self.scale
        lo = np.minimum(o.min(axis=0), p.min(axis=0)) - pad
        hi = np.maximum(o.max(axis=0), p.max(axis=0)) + pad
        flo, fhi = self._face_boxes
        near = (self._parts != part) & np.all((fhi >= lo) & (flo <= hi), axis=1)
        if not near.any():
            return None, None
        if near.sum() == (self._parts != part).sum():  # every other face: the cached scene
            return self._others(part), self._other_ids[part]
        from embreex import mesh_construction, rtcore_scene

        keep = np.flatnonzero(near)
        scene = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(scene, self._local_vertices,
                                       np.ascontiguousarray(self._faces[keep]))
        return scene, keep

    def _others(self, part: int) -> Any:
        """An Embree scene of every face not in ``part`` (−1: all faces); None if none, cached."""
        if part not in self._other_scenes:
            from embreex import mesh_construction, rtcore_scene

            keep = np.flatnonzero(self._parts != part)
            scene = None
            if len(keep):
                scene = rtcore_scene.EmbreeScene()
                mesh_construction.TriangleMesh(scene, self._local_vertices,
                                               np.ascontiguousarray(self._faces[keep]))
                one = np.zeros((1, 3), np.float32)
                scene.run(one, one + np.float32(1.0), query="OCCLUDED")  # commit now
            self._other_scenes[part] = scene
            self._other_ids[part] = keep
        return self._other_scenes[part]

    @staticmethod
    def _dirs(dirs: ArrayLike) -> NDArray[np.float32]:
        return np.ascontiguousarray(np.asarray(dirs).reshape(-1, 3), dtype=np.float32)

    def first_hit(self, origins: ArrayLike, dirs: ArrayLike
                  ) -> tuple[NDArray[np.int32], NDArray[np.float32], NDArray[np.float32]]:
        """Closest hit of each ray: (face index or −1, u, v), hit = (1−u−v)p0 + u p1 + v p2.

        Parameters
        ----------
        origins, dirs
            (N, 3) world-space rays.

        Returns
        -------
        tuple of ndarray
            Face index (−1 for a miss), u, v, each (N,).
        """
        return self.first_hit_local(self.local(origins), self._dirs(dirs))

    def occluded(self, origins: ArrayLike, dirs: ArrayLike) -> NDArray[np.bool_]:
        """True where the ray hits anything (any-hit query).

        Parameters
        ----------
        origins, dirs
            (N, 3) world-space rays.

        Returns
        -------
        ndarray of bool, shape (N,)
            Whether each ray hits anything.
        """
        return self.occluded_local(self.local(origins), self._dirs(dirs))

    def first_hit_local(self, origins: NDArray[np.float32], dirs: NDArray[np.float32]
                        ) -> tuple[NDArray[np.int32], NDArray[np.float32], NDArray[np.float32]]:
        """[`first_hit`][shprobe.scene.RayCaster.first_hit] for float32 (N, 3) origins in the local
        frame.

        Parameters
        ----------
        origins, dirs
            (N, 3) float32 rays, origins in the local frame.

        Returns
        -------
        tuple of ndarray
            Face index (−1 for a miss), u, v, each (N,).
        """
        if len(origins) == 0:
            return np.empty(0, np.int32), np.empty(0, np.float32), np.empty(0, np.float32)
        r = self._scene.run(origins, dirs, output=1)
        return r["primID"], r["u"], r["v"]

    def occluded_local(self, origins: NDArray[np.float32], dirs: NDArray[np.float32]
                       ) -> NDArray[np.bool_]:
        """[`occluded`][shprobe.scene.RayCaster.occluded] for float32 (N, 3) origins in the local
        frame.

        Parameters
        ----------
        origins, dirs
            (N, 3) float32 rays, origins in the local frame.

        Returns
        -------
        ndarray of bool, shape (N,)
            Whether each ray hits anything.
        """
        if len(origins) == 0:
            return np.empty(0, bool)
        return self._scene.run(origins, dirs, query="OCCLUDED") != -1

    def __repr__(self) -> str:
        return f"RayCaster({self.n_faces} triangles)"
