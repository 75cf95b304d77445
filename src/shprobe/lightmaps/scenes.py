"""The game scene shipped with shprobe for the lightmap bake.

``courtyard.glb`` (made by tools/make_game_scene.py): a walled courtyard with an arcade of
stone arches, columns and wooden crates, about 2,800 triangles, four materials with
base-colour textures and tangent-space normal maps, TEXCOORD_0 and TANGENT on every primitive
and no TEXCOORD_1 (the bake makes the lightmap atlas).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

GAME_SCENE = "courtyard.glb"


def game_scene_path() -> Path:
    """The path of the packaged game scene.

    Returns
    -------
    Path
        ``courtyard.glb`` inside the installed package (+Y up, metres).
    """
    return Path(str(resources.files("shprobe.lightmaps") / "data" / GAME_SCENE))
