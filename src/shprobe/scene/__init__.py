"""Layer 4, scene: camera, meshes and materials, the one ray caster, and diffuse rendering.

* `shprobe.scene.camera` — [`Camera`][shprobe.scene.Camera] (orbiting pinhole / orthographic camera,
  primary rays).
* `shprobe.scene.mesh` — [`load_mesh`][shprobe.scene.load_mesh] (the one loader and its ``process=``
  policy), albedo from materials and textures, [`sphere_mesh`][shprobe.scene.sphere_mesh],
  [`mesh_hash`][shprobe.prt.mesh_hash], the packaged Stanford bunny
  ([`packaged_bunny`][shprobe.scene.packaged_bunny], [`bunny_path`][shprobe.scene.bunny_path];
  ``"bunny"`` wherever a mesh path is taken).
* `shprobe.scene.raycast` — [`RayCaster`][shprobe.scene.RayCaster] (Embree via embreex: first hits
  and occlusion).
* `shprobe.scene.render` — [`render`][shprobe.scene.render.render],
  [`render_vertex_colors`][shprobe.scene.render_vertex_colors],
  [`RenderResult`][shprobe.scene.RenderResult], [`basis_images`][shprobe.scene.basis_images].
* `shprobe.scene.primary` — [`trace`][shprobe.scene.trace]: the primary rays' first hits.
* `shprobe.scene.images` — [`relight`][shprobe.scene.relight],
  [`basis_visual`][shprobe.scene.basis_visual], [`save_image`][shprobe.scene.save_image].
"""

from __future__ import annotations

from .camera import Camera
from .images import basis_visual, relight, save_image
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
from .primary import Hits, trace
from .raycast import RayCaster
from .render import RenderResult, basis_images, render, render_result, render_vertex_colors

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
