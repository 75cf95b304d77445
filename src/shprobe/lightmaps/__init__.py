"""Directional lightmaps (Habel & Wimmer 2010, §4.2–4.3): scenes baked into H-basis and rival
coefficient textures on a second UV set, with global illumination.

* :mod:`.format` — the ``SHPROBE_lightmap`` glTF extension and the reference evaluation.

Manual: docs/lightmaps.md.
"""

from __future__ import annotations

from .format import ENCODINGS, EXTENSION, N_COEFFS, basis_values, evaluate

__all__ = ["ENCODINGS", "EXTENSION", "N_COEFFS", "basis_values", "evaluate"]
