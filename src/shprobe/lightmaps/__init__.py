"""Directional lightmaps (Habel & Wimmer 2010, §4.2–4.3): scenes baked into H-basis and rival
coefficient textures on a second UV set, with global illumination.

* `shprobe.lightmaps.format` — the ``SHPROBE_lightmap`` glTF extension and the reference evaluation.
* `shprobe.lightmaps.scene` — glTF / OBJ scenes with base colour and normal maps.
* `shprobe.lightmaps.tangents` — MikkTSpace-style tangents, texel frames.
* `shprobe.lightmaps.atlas` — TEXCOORD_1 or xatlas, rasterisation to texels.
* `shprobe.lightmaps.gather` — the Embree radiance gather; `shprobe.lightmaps.encode` — bounces, SH,
  encodings.
* `shprobe.lightmaps.bake` — ``bake_lightmap`` and the ``Lightmap`` result; `shprobe.lightmaps.io` —
  .glb out and in.

Manual: docs/lightmaps.md.
"""

from __future__ import annotations

from .bake import bake_lightmap, estimate_lightmap_bake
from .format import ENCODINGS, EXTENSION, N_COEFFS, basis_values, evaluate
from .result import Lightmap, load_lightmap
from .scene import LightmapScene, Primitive, load_scene
from .settings import LightmapSettings, parse_sun

__all__ = ["ENCODINGS", "EXTENSION", "N_COEFFS", "Lightmap", "LightmapScene",
           "LightmapSettings", "Primitive", "bake_lightmap", "basis_values",
           "estimate_lightmap_bake", "evaluate", "load_lightmap", "load_scene", "parse_sun"]
