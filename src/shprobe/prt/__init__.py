"""Precomputed radiance transfer (Lisle & Huang 2007 §4): unshadowed, shadowed and
interreflected diffuse transfer, baked per vertex and relit at run time with any SH lighting.

Modules: :mod:`.scene` (meshes, ground plane, albedo, hash), :mod:`.bake` (transfer vectors by
Embree ray casting), :mod:`.transfer` (the :class:`Transfer` result, .npz I/O, radiance scale),
:mod:`.relight` (rotation of the lighting and the per-vertex dot product). One bake serves every
model up to the one baked; the model, degree and lighting are picked at run time.
"""

from __future__ import annotations

from .bake import bake, sample_directions
from .relight import relight, scene_lighting
from .scene import Scene, ground_plane, load_scene, mesh_hash
from .transfer import MODES, Transfer, load_transfer, unshadowed_transfer

__all__ = [
    "MODES",
    "Scene",
    "Transfer",
    "bake",
    "ground_plane",
    "load_scene",
    "load_transfer",
    "mesh_hash",
    "relight",
    "sample_directions",
    "scene_lighting",
    "unshadowed_transfer",
]
