"""Precomputed radiance transfer (Lisle & Huang 2007 §4): unshadowed, shadowed and
interreflected diffuse transfer, baked per vertex and relit at run time with any SH lighting.

Modules, in the order a bake runs them:

- `shprobe.prt.geometry`: the flattened scene a bake works on (meshes, ground plane, albedo, hash);
- `shprobe.prt.directions`: the seeded direction sets and the ray origins;
- `shprobe.prt.hemisphere`: the adaptive hemisphere quadrature of the contact's vertices;
- `shprobe.prt.trace`: one traced bake (visibility, the bounce gather, the bounces);
- `shprobe.prt.criteria`: where a baked transfer needs more vertices or directions;
- `shprobe.prt.subdivide`: splitting marked edges, conforming;
- `shprobe.prt.settings`: [`PrtSettings`][shprobe.prt.PrtSettings] (a bake's settings, the CLI's
  defaults) and [`Refinement`][shprobe.prt.Refinement] with its named instances, QUICK (default) and
  ACCURATE;
- `shprobe.prt.refine`: the refined bake, a driver of named stages over the three above;
- `shprobe.prt.baking`: the public [`bake`][shprobe.prt.bake] and its time/memory estimate;
- `shprobe.prt.transfer`: the [`Transfer`][shprobe.prt.Transfer] result, .npz I/O, radiance scale;
- `shprobe.prt.relighting`: rotation of the lighting and the per-vertex dot product;
- `shprobe.prt.view`: pictures and turntables of relit transfer.

One bake serves every model up to the one baked; the model, degree and lighting are picked at
run time.
"""

from __future__ import annotations

from .baking import BakeEstimate, bake, estimate_bake
from .directions import sample_directions
from .geometry import BakeScene, ground_plane, load_scene, mesh_hash
from .relighting import relight, scene_lighting
from .settings import ACCURATE, DEFAULT_LMAX, QUICK, REFINEMENTS, PrtSettings, Refinement
from .transfer import MODES, Transfer, load_transfer, unshadowed_transfer

__all__ = [
    "ACCURATE",
    "DEFAULT_LMAX",
    "MODES",
    "QUICK",
    "REFINEMENTS",
    "BakeEstimate",
    "BakeScene",
    "PrtSettings",
    "Refinement",
    "Transfer",
    "bake",
    "estimate_bake",
    "ground_plane",
    "load_scene",
    "load_transfer",
    "mesh_hash",
    "relight",
    "sample_directions",
    "scene_lighting",
    "unshadowed_transfer",
]
