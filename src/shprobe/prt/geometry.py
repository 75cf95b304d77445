"""The geometry a PRT bake works on: one or more meshes, an optional ground plane, diffuse
albedo per vertex.

A [`BakeScene`][shprobe.prt.BakeScene] is that geometry flattened: every mesh's vertices, normals
and faces concatenated (the ground plane's last), the albedo ρ per vertex (RGB), and a hash of the
geometry so that a bake is never reused for another mesh (Lisle & Huang 2007 §4: scene
switchable at run time). (The ``shprobe.scene`` layer holds meshes, cameras and the renderer.)
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..scene.mesh import as_mesh, mesh_hash, mesh_vertex_albedo
from ..sh.rotation import unit_vectors

__all__ = ["DEFAULT_ALBEDO", "BakeScene", "albedo_keywords", "ground_plane", "load_scene",
           "mesh_hash"]

#: Albedo used where none is given.
DEFAULT_ALBEDO = 0.8


@dataclass(frozen=True)
class BakeScene:
    """Flattened scene geometry.

    vertices (V, 3), normals (V, 3) unit, faces (F, 3) int64 into vertices, albedo (V, 3) diffuse
    reflectance ρ per vertex, mesh_hash: SHA-256 of vertices and faces (see `mesh_hash`),
    n_ground: how many of the last vertices are the ground plane's (0: no ground).
    """

    vertices: NDArray[np.float64]
    normals: NDArray[np.float64]
    faces: NDArray[np.int64]
    albedo: NDArray[np.float64]
    mesh_hash: str
    n_ground: int = 0

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def coloured(self) -> bool:
        """True when some vertex has a non-grey albedo (transfer then has 3 channels)."""
        a = self.albedo
        return bool(np.any(a[:, 1:] != a[:, :1]))

    def face_normals(self) -> NDArray[np.float64]:
        """Unit geometric normals (F, 3) from the winding (counter-clockwise = front)."""
        v = self.vertices[self.faces]
        return unit_vectors(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), zero="keep")



def ground_plane(center_xz: ArrayLike, size: float, y: float, resolution: int = 64):
    """A square grid (``resolution`` cells a side) in the plane y = ``y``, normal +Y.

    Tessellated so that per-vertex transfer can show shadows on it.
    """
    import trimesh

    n = int(resolution)
    if n < 1 or size <= 0:
        raise ShprobeError("ground plane needs resolution >= 1 and size > 0")
    cx, cz = (float(c) for c in np.asarray(center_xz, dtype=np.float64))
    t = np.linspace(-0.5 * size, 0.5 * size, n + 1)
    gx, gz = np.meshgrid(cx + t, cz + t, indexing="ij")
    verts = np.stack([gx.ravel(), np.full(gx.size, float(y)), gz.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    b, c, d = a + (n + 1), a + 1, a + n + 2
    # counter-clockwise seen from +Y: (a, c, b) and (c, d, b)
    faces = np.concatenate([np.stack([a, c, b], 1), np.stack([c, d, b], 1)])
    normals = np.tile([0.0, 1.0, 0.0], (len(verts), 1))
    return trimesh.Trimesh(verts, faces, vertex_normals=normals, process=False)


def _albedo_rows(spec: Any, n: int, what: str) -> NDArray[np.float64]:
    """(n, 3) albedo from a number, an RGB triple (3,), or per-vertex values (n,), (n, 1) or
    (n, 3). A 1-D array of length 3 is always RGB (a 3-vertex mesh's grey values: (3, 1))."""
    try:
        a = np.asarray(spec, dtype=np.float64)
    except (TypeError, ValueError):
        raise ShprobeError(f"albedo for {what} must be numbers, got {spec!r}") from None
    if a.ndim == 0:
        a = np.full((n, 3), float(a))
    elif a.shape == (3,):
        a = np.tile(a, (n, 1))
    elif a.shape in ((n,), (n, 1)):
        a = np.repeat(a.reshape(n, 1), 3, axis=1)
    elif a.shape != (n, 3):
        raise ShprobeError(f"albedo for {what} must be a number, r,g,b, or per-vertex ({n},) / "
                           f"({n}, 3); got shape {a.shape}")
    if not np.all(np.isfinite(a)) or np.any(a < 0) or np.any(a > 1):
        raise ShprobeError(f"albedo for {what} must lie in [0, 1]")
    return a


def _one_value(albedo: Any, what: str) -> Any:
    """Check that ``albedo`` is one value for every mesh: a number or an RGB triple."""
    if albedo is None:
        return None
    try:
        shape = np.shape(albedo)
    except ValueError:
        shape = None
    if shape not in ((), (3,)):
        raise ShprobeError(f"{what} is one value for every mesh, a number or r,g,b (got "
                           f"{'shape ' + str(shape) if shape else 'a ragged list'}); give "
                           "per-mesh or per-vertex albedo as mesh_albedo=[one entry per mesh]")
    return albedo


def albedo_keywords(values: Sequence[Any], n_meshes: int) -> dict[str, Any]:
    """Albedo values as given for a scene of ``n_meshes`` meshes → the
    [`load_scene`][shprobe.prt.load_scene] keywords: none (the defaults), one (``albedo``: every
    mesh and the ground) or one per mesh in order (``mesh_albedo``).

    Parameters
    ----------
    values
        The albedo values: numbers or r,g,b triples.
    n_meshes
        The meshes of the scene.

    Returns
    -------
    dict
        {}, {"albedo": value} or {"mesh_albedo": [values]}.
    """
    values = list(values)
    if not values:
        return {}
    if len(values) == 1:
        return {"albedo": values[0]}
    if len(values) != n_meshes:
        raise ShprobeError(f"albedo given {len(values)} times for {n_meshes} meshes: give it "
                           "once (every mesh) or once per mesh, in order")
    return {"mesh_albedo": values}


def load_scene(scene: Any, albedo: Any = None, ground: bool = False,
               ground_albedo: Any = None, ground_size: float = 3.0,
               ground_resolution: int = 64, mesh_albedo: Sequence[Any] | None = None) -> BakeScene:
    """Build a [`BakeScene`][shprobe.prt.BakeScene] from a mesh path, a trimesh object, a BakeScene,
    or a list of them.

    Albedo (diffuse reflectance ρ in [0, 1]), two unambiguous ways:

    - ``albedo``: one value for every mesh (and the ground): a number, or an RGB triple;
    - ``mesh_albedo``: a sequence with exactly one entry per mesh, in order, each None (that
      mesh's default), a number, an RGB triple (a 1-D array of length 3 is always RGB), or
      per-vertex values (V_i,), (V_i, 1) or (V_i, 3).

    Default (neither, or a None entry): the mesh's own colour when it has one (texture at the
    vertex UVs, vertex, face or material colours:
    [`shprobe.scene.mesh.mesh_vertex_albedo`][shprobe.scene.mesh_vertex_albedo]), else ρ = 0.8.
    ground: add a square plane under the scene (at the lowest y of the meshes, ``ground_size`` times
    the larger horizontal extent, normal +Y) with ``ground_albedo`` (a number or RGB; default
    ``albedo``, else 0.8).
    """
    _one_value(albedo, "albedo")
    _one_value(ground_albedo, "ground_albedo")
    if albedo is not None and mesh_albedo is not None:
        raise ShprobeError("give albedo (one value for every mesh) or mesh_albedo (one entry "
                           "per mesh), not both")
    if isinstance(scene, BakeScene):
        if ground:
            raise ShprobeError("add the ground plane when the scene is built, not to a BakeScene")
        if mesh_albedo is not None:
            if len(mesh_albedo) != 1:
                raise ShprobeError(f"mesh_albedo has {len(mesh_albedo)} entries for a BakeScene "
                                   "(one flattened mesh): give one")
            albedo = mesh_albedo[0]
        if albedo is None:
            return scene
        return _with_albedo(scene, _albedo_rows(albedo, scene.n_vertices, "the scene"))
    items = list(scene) if isinstance(scene, list | tuple) else [scene]
    if not items:
        raise ShprobeError("the scene has no meshes")
    meshes = [as_mesh(it) for it in items]
    if mesh_albedo is not None:
        if isinstance(mesh_albedo, str) or not isinstance(mesh_albedo, Sequence):
            raise ShprobeError("mesh_albedo must be a list with one entry per mesh")
        if len(mesh_albedo) != len(meshes):
            raise ShprobeError(f"mesh_albedo has {len(mesh_albedo)} entries for "
                               f"{len(meshes)} meshes: give one per mesh")
        per_mesh: Sequence[Any] = mesh_albedo
    else:
        per_mesh = [albedo] * len(meshes)
    verts, norms, faces, alb = [], [], [], []
    off = 0
    for k, (m, a) in enumerate(zip(meshes, per_mesh, strict=True)):
        v = np.asarray(m.vertices, dtype=np.float64)
        nrm = np.asarray(m.vertex_normals, dtype=np.float64)
        _check_normals(nrm, np.asarray(m.faces), items[k], k)
        verts.append(v)
        norms.append(nrm)
        faces.append(np.asarray(m.faces, dtype=np.int64) + off)
        if a is None:
            a = mesh_vertex_albedo(m)
        alb.append(_albedo_rows(DEFAULT_ALBEDO if a is None else a, len(v), f"mesh {k}"))
        off += len(v)
    if ground:
        allv = np.concatenate(verts)
        lo, hi = allv.min(0), allv.max(0)
        ext = float(max(hi[0] - lo[0], hi[2] - lo[2], 1e-9))
        g = ground_plane(0.5 * (lo[[0, 2]] + hi[[0, 2]]), ground_size * ext, lo[1],
                         ground_resolution)
        ga = next((x for x in (ground_albedo, albedo) if x is not None), DEFAULT_ALBEDO)
        verts.append(np.asarray(g.vertices))
        norms.append(np.asarray(g.vertex_normals))
        faces.append(np.asarray(g.faces, dtype=np.int64) + off)
        alb.append(_albedo_rows(ga, len(g.vertices), "the ground"))
    v = np.concatenate(verts)
    f = np.concatenate(faces)
    n = np.concatenate(norms)
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    if not np.all(np.isfinite(v)):
        raise ShprobeError("mesh has non-finite vertices")
    n = np.where(ln > 0, n / np.where(ln > 0, ln, 1.0), [0.0, 1.0, 0.0])
    return BakeScene(v, n, f, np.concatenate(alb), mesh_hash(v, f),
                     len(verts[-1]) if ground else 0)


def _check_normals(normals: NDArray[np.float64], faces: NDArray, item: Any, k: int) -> None:
    """Refuse vertices of triangles whose normal is zero or not finite (only degenerate
    triangles around them): their transfer would be meaningless."""
    used = np.zeros(len(normals), dtype=bool)
    used[np.asarray(faces, dtype=np.int64).ravel()] = True
    ln = np.linalg.norm(normals, axis=1)
    bad = used & ~(np.isfinite(ln) & (ln > 1e-12))
    if bad.any():
        where = item if isinstance(item, str | os.PathLike) else None
        raise ShprobeError(f"mesh {k} has {int(bad.sum())} vertices with a zero or non-finite "
                           "normal (degenerate triangles); repair the mesh", where)


def _with_albedo(scene: BakeScene, albedo: NDArray[np.float64]) -> BakeScene:
    return BakeScene(scene.vertices, scene.normals, scene.faces, albedo, scene.mesh_hash,
                     scene.n_ground)
