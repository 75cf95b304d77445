"""Layer 4, scene: camera, meshes and materials, the one ray caster, and diffuse rendering.

* :mod:`.camera` — :class:`Camera` (orbiting pinhole / orthographic camera, primary rays).
* :mod:`.mesh` — :func:`load_mesh` (the one loader and its ``process=`` policy), albedo from
  materials and textures, :func:`sphere_mesh`, :func:`mesh_hash`, the packaged Stanford bunny
  (:func:`packaged_bunny`, :func:`bunny_path`; ``"bunny"`` wherever a mesh path is taken).
* :mod:`.raycast` — :class:`RayCaster` (Embree via embreex: first hits and occlusion).
* :mod:`.render` — :func:`render`, :func:`render_vertex_colors`, :class:`RenderResult`,
  :func:`basis_images`.
"""

from __future__ import annotations

from .camera import Camera
from .mesh import (
    as_mesh,
    bounding_sphere,
    bunny_path,
    load_mesh,
    mesh_hash,
    mesh_uvs,
    mesh_vertex_albedo,
    packaged_bunny,
    sample_texture,
    sphere_mesh,
)
from .raycast import RayCaster
from .render import (
    Hits,
    RenderResult,
    basis_images,
    basis_visual,
    relight,
    render,
    render_result,
    render_vertex_colors,
    save_image,
    trace,
)

__all__ = [
    "Camera",
    "Hits",
    "RayCaster",
    "RenderResult",
    "as_mesh",
    "basis_images",
    "basis_visual",
    "bounding_sphere",
    "bunny_path",
    "load_mesh",
    "mesh_hash",
    "mesh_uvs",
    "mesh_vertex_albedo",
    "packaged_bunny",
    "relight",
    "render",
    "render_result",
    "render_vertex_colors",
    "sample_texture",
    "save_image",
    "sphere_mesh",
    "trace",
]
