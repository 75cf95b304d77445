"""Triangle meshes: the one loader, materials and albedo, textures, the test sphere, the hash,
the packaged bunny.

Loading policy (one for every caller: render, PRT, H-basis): ``trimesh.load(path,
process=True)`` — duplicate vertices are merged (trimesh keeps vertices with different UVs or
normals apart), so smooth vertex normals are shared across what the file stored as separate
copies; a multi-part file (glTF scene) is flattened with its graph transforms and concatenated.
Meshes given as objects are used as they are (only flattened when they are a scene).

The packaged bunny ([`bunny_path`][shprobe.scene.bunny_path],
[`packaged_bunny`][shprobe.scene.packaged_bunny]): a 4,968-face copy of the Stanford bunny in the
package data (``scene/data/bunny.obj``, made by tools/make_bunny.py; its terms in
``bunny-LICENSE.txt`` beside it). The name `BUNNY` (``"bunny"``) stands for it wherever a mesh path
is taken ([`load_mesh`][shprobe.scene.load_mesh], hence ``--mesh bunny``) unless a file of that name
exists: a mesh file always has an extension, which names its format.

Colours: 8-bit vertex / face colours and texture images are sRGB and are decoded to linear
reflectance; material colours (glTF ``baseColorFactor``, OBJ ``Kd``) are already linear.
"""

from __future__ import annotations

import hashlib
import os
import warnings
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..probes.layouts.base import bilinear
from ..probes.tonemap import srgb_to_linear

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

__all__ = [
    "BUNNY",
    "as_mesh",
    "bounding_sphere",
    "bunny_path",
    "load_mesh",
    "mesh_file",
    "mesh_hash",
    "mesh_texture",
    "mesh_uvs",
    "mesh_vertex_albedo",
    "packaged_bunny",
    "sample_texture",
    "sphere_mesh",
]


# ----------------------------------------------------------------------------- the bunny

#: The name that stands for the packaged bunny wherever a mesh path is taken.
BUNNY = "bunny"


def bunny_path() -> Path:
    """The packaged Stanford bunny (OBJ, 2,503 vertices, 4,968 faces, +Y up, metres; terms in
    ``bunny-LICENSE.txt`` beside it).

    Returns
    -------
    Path
        The packaged bunny's OBJ file.
    """
    return Path(str(resources.files("shprobe.scene") / "data" / "bunny.obj"))


def packaged_bunny() -> trimesh.Trimesh:
    """The packaged Stanford bunny, loaded by [`load_mesh`][shprobe.scene.load_mesh].

    Returns
    -------
    trimesh.Trimesh
        The 4,968-face Stanford bunny of the package data.
    """
    return load_mesh(bunny_path())


def mesh_file(path: str | os.PathLike[str]) -> str:
    """The file a mesh argument names: [`bunny_path`][shprobe.scene.bunny_path] for `BUNNY` (when no
    file of that name exists), else the path itself."""
    p = os.fspath(path)
    return str(bunny_path()) if p == BUNNY and not os.path.exists(p) else p


# ----------------------------------------------------------------------------- loading


def load_mesh(path: str | os.PathLike[str]) -> trimesh.Trimesh:
    """Load OBJ / PLY / glTF / GLB (anything trimesh reads) as one triangle mesh; ``"bunny"``
    is the packaged bunny (`mesh_file`).

    A scene is flattened (its graph transforms applied) and concatenated. Bad or empty files
    raise a one-line [`ShprobeError`][shprobe.errors.ShprobeError] naming the file.

    Parameters
    ----------
    path
        An OBJ, PLY, glTF or GLB file, or "bunny" for the packaged bunny.

    Returns
    -------
    trimesh.Trimesh
        One triangle mesh (a scene flattened and concatenated).
    """
    import trimesh

    from ..files import regular_file

    p = mesh_file(path)
    regular_file(p, "mesh file")  # missing: "no such mesh file"; a FIFO or device: refused
    try:
        # trimesh computes normals of whatever it is given: overflow there is our check's job
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)
            loaded = trimesh.load(p, process=False)
            parts = (loaded.geometry.values() if isinstance(loaded, trimesh.Scene)
                     else [loaded])
            for g in parts:
                if isinstance(g, trimesh.Trimesh):
                    _process(g, p)
            obj = _flatten(loaded, p)
    except ShprobeError:
        raise
    except Exception as e:  # trimesh raises many types on bad input
        raise ShprobeError(f"cannot read mesh: {str(e).splitlines()[0] if str(e) else e!r}",
                           p) from None
    with np.errstate(all="ignore"):
        extent = np.ptp(np.asarray(obj.vertices, dtype=np.float64), axis=0).max()
    if not extent < MAX_EXTENT:
        raise ShprobeError(f"mesh coordinates are too large (extent {extent:.3g}, limit "
                           f"{MAX_EXTENT:g}): rescale it", p)
    if not extent > 0:
        raise ShprobeError("mesh has zero extent (all vertices coincide)", p)
    if not obj.area > 0:
        raise ShprobeError("mesh has no triangle of non-zero area (no normals)", p)
    return obj


#: Largest extent of a mesh accepted: squared lengths and cross products stay finite.
MAX_EXTENT = 1e100


def _process(mesh: trimesh.Trimesh, where: Any) -> None:
    """Check a loaded part's vertices (a NaN or infinite one is refused, not dropped as
    trimesh's processing would) and merge duplicate vertices where trimesh can: it rounds to
    8 decimals in int64, which overflows from about 1e11 and merged every vertex into one."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise ShprobeError(f"mesh has non-finite vertex coordinates (vertex "
                           f"{int(np.argmax(bad)) + 1} of {len(v)})", where)
    if v.size and float(np.abs(v).max()) < 1e10:
        mesh.process()  # trimesh's own (8 decimals)
    # else the file's vertices are kept as they are: any one rounding for the whole mesh
    # would merge its small features near the origin once one vertex is far away


def _flatten(obj: Any, where: Any = None) -> trimesh.Trimesh:
    """One Trimesh from a Trimesh or a Scene (graph transforms applied, parts concatenated)."""
    import trimesh

    empty = "mesh file holds no triangles" if where is not None else "mesh has no triangles"
    if isinstance(obj, trimesh.Scene):
        geoms = [g for g in obj.dump() if isinstance(g, trimesh.Trimesh)]
        if not geoms:
            raise ShprobeError(empty, where)
        obj = geoms[0] if len(geoms) == 1 else trimesh.util.concatenate(geoms)
    if not isinstance(obj, trimesh.Trimesh) or len(obj.faces) == 0:
        raise ShprobeError(empty, where)
    return obj


def as_mesh(item: Any) -> trimesh.Trimesh:
    """A Trimesh from a path ([`load_mesh`][shprobe.scene.load_mesh]) or a trimesh object (scenes
    flattened).

    Parameters
    ----------
    item
        A mesh path or a trimesh object.

    Returns
    -------
    trimesh.Trimesh
        One triangle mesh.
    """
    import trimesh

    if isinstance(item, str | os.PathLike):
        return load_mesh(item)
    if isinstance(item, trimesh.Scene | trimesh.Trimesh):
        mesh = _flatten(item)
        if not np.all(np.isfinite(np.asarray(mesh.vertices, dtype=np.float64))):
            raise ShprobeError("mesh has non-finite vertex coordinates")
        return mesh
    raise ShprobeError(f"cannot use {type(item).__name__} as a mesh (path or trimesh object)")


def sphere_mesh(subdivisions: int = 5, radius: float = 1.0) -> trimesh.Trimesh:
    """A finely tessellated sphere (icosphere) with exact vertex normals.

    Parameters
    ----------
    subdivisions
        Icosphere subdivisions.
    radius
        The sphere's radius.

    Returns
    -------
    trimesh.Trimesh
        The sphere with exact vertex normals.
    """
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    n = m.vertices / np.linalg.norm(m.vertices, axis=1, keepdims=True)
    return trimesh.Trimesh(m.vertices, m.faces, vertex_normals=n, process=False)


def bounding_sphere(mesh: trimesh.Trimesh | None) -> tuple[NDArray[np.float64], float]:
    """(centre of the bounding box, radius of the sphere about it holding every vertex); the
    unit sphere for None.

    Parameters
    ----------
    mesh
        A mesh, or None for the unit sphere.

    Returns
    -------
    tuple
        (centre (3,), radius).
    """
    if mesh is None:
        return np.zeros(3), 1.0
    v = np.asarray(mesh.vertices, dtype=np.float64)
    c = 0.5 * (v.min(axis=0) + v.max(axis=0))
    r = float(np.sqrt(((v - c) ** 2).sum(axis=1).max()))
    if not r > 0:
        raise ShprobeError("mesh has zero extent (all vertices coincide)")
    return c, r


def mesh_hash(vertices: ArrayLike, faces: ArrayLike) -> str:
    """SHA-256 (hex) of the vertices (as float32) and the faces (as int64), little-endian.

    float32 so that the hash ignores float64 noise below what a mesh file stores; any moved
    vertex or changed face gives another hash. Baked files (PRT transfer, H-basis bakes) keep
    it so that they are never used with another mesh.

    Parameters
    ----------
    vertices
        (V, 3) positions.
    faces
        (F, 3) vertex indices.

    Returns
    -------
    str
        The SHA-256, hex.
    """
    h = hashlib.sha256()
    v = np.ascontiguousarray(np.asarray(vertices, dtype="<f4"))
    f = np.ascontiguousarray(np.asarray(faces, dtype="<i8"))
    h.update(str(v.shape).encode())
    h.update(v.tobytes())
    h.update(str(f.shape).encode())
    h.update(f.tobytes())
    return h.hexdigest()


# ----------------------------------------------------------------------------- materials


def mesh_uvs(mesh: trimesh.Trimesh) -> NDArray[np.float64] | None:
    """Per-vertex texture coordinates (V, 2), or None when the mesh has none (or not one per
    vertex).

    Parameters
    ----------
    mesh
        The mesh.

    Returns
    -------
    ndarray of shape (V, 2), or None
        Its per-vertex texture coordinates.
    """
    uv = getattr(getattr(mesh, "visual", None), "uv", None)
    if uv is None or len(uv) != len(mesh.vertices):
        return None
    return np.asarray(uv, dtype=np.float64)


def mesh_texture(mesh: trimesh.Trimesh) -> tuple[NDArray, NDArray] | None:
    """(uv (V, 2), linear texture (h, w, 3)) of a textured mesh, else None. A glTF texture is
    multiplied by its ``baseColorFactor`` (glTF 2.0 §3.9.2)."""
    vis = getattr(mesh, "visual", None)
    if vis is None or getattr(vis, "kind", None) != "texture":
        return None
    uv = getattr(vis, "uv", None)
    mat = getattr(vis, "material", None)
    img = None
    for attr in ("baseColorTexture", "image"):
        img = getattr(mat, attr, None) if mat is not None else None
        if img is not None:
            break
    if uv is None or img is None:
        return None
    tex = srgb_to_linear(np.asarray(img.convert("RGB"), dtype=np.float32) / 255.0)
    factor = getattr(mat, "baseColorFactor", None)
    if factor is not None:
        tex = tex * (np.asarray(factor, np.float32)[:3] / 255.0)
    return np.asarray(uv, dtype=np.float64), tex


def mesh_vertex_colors(mesh: trimesh.Trimesh) -> NDArray | None:
    """Per-vertex colours (8-bit sRGB) in linear RGB (V, 3), else None."""
    vis = getattr(mesh, "visual", None)
    if vis is None or getattr(vis, "kind", None) != "vertex":
        return None
    return srgb_to_linear(np.asarray(vis.vertex_colors)[:, :3] / 255.0)


def mesh_face_colors(mesh: trimesh.Trimesh) -> NDArray | None:
    """Per-face colours (PLY face colours; 8-bit sRGB, like vertex colours) in linear RGB."""
    vis = getattr(mesh, "visual", None)
    if vis is None or getattr(vis, "kind", None) != "face":
        return None
    return srgb_to_linear(np.asarray(vis.face_colors)[:, :3] / 255.0)


def mesh_material_color(mesh: trimesh.Trimesh) -> NDArray | None:
    """The constant colour of an untextured material: glTF ``baseColorFactor`` or OBJ ``Kd``
    (both linear reflectances), else None."""
    mat = getattr(getattr(mesh, "visual", None), "material", None)
    for attr in ("baseColorFactor", "diffuse"):
        v = getattr(mat, attr, None) if mat is not None else None
        if v is not None:
            return np.asarray(v, np.float32)[:3] / 255.0
    return None


def mesh_vertex_albedo(mesh: trimesh.Trimesh) -> NDArray[np.float64] | None:
    """A mesh's own albedo per vertex (V, 3), linear, for per-vertex shading (PRT): its
    texture sampled at the vertex UVs (× glTF ``baseColorFactor``), else its vertex colours,
    else its face colours averaged over each vertex's faces, else its material colour (glTF
    ``baseColorFactor`` / OBJ ``Kd``); None when it has none of them.

    Parameters
    ----------
    mesh
        The mesh.

    Returns
    -------
    ndarray of shape (V, 3), or None
        Its own linear albedo per vertex.
    """
    nv = len(mesh.vertices)
    tex = mesh_texture(mesh)
    if tex is not None and len(tex[0]) == nv:
        return sample_texture(tex[1], tex[0])[:, :3].astype(np.float64)
    vc = mesh_vertex_colors(mesh)
    if vc is not None and len(vc) == nv:
        return np.asarray(vc, np.float64)
    fc = mesh_face_colors(mesh)
    if fc is not None:
        faces = np.asarray(mesh.faces)
        acc = np.zeros((nv, 3))
        np.add.at(acc, faces.reshape(-1), np.repeat(fc.astype(np.float64), 3, axis=0))
        cnt = np.bincount(faces.reshape(-1), minlength=nv)[:, None]
        return np.where(cnt > 0, acc / np.maximum(cnt, 1), 1.0)
    mc = mesh_material_color(mesh)
    return None if mc is None else np.broadcast_to(mc.astype(np.float64), (nv, 3)).copy()


def sample_texture(tex: ArrayLike, uv: ArrayLike) -> NDArray[np.floating]:
    """Bilinear lookup (H, W, C) at uv (..., 2): u wraps around, v (0 at the bottom row of the
    image) is clamped to the edge texels. The layouts' bilinear lookup at pixel coordinates
    (u mod 1)·W, (1 − v mod 1)·H; float32 out (float64 for a float64 texture).

    Parameters
    ----------
    tex
        (H, W, C) texture.
    uv
        (..., 2) texture coordinates.

    Returns
    -------
    ndarray of shape (..., C)
        The bilinear lookups.
    """
    t = np.asarray(tex)
    uv = np.asarray(uv, dtype=np.float64)
    h, w = t.shape[:2]
    return bilinear(t, (uv[..., 0] % 1.0) * w, (1.0 - uv[..., 1] % 1.0) * h, wrap_x=True)
