"""Rendering diffuse objects from SH lighting (R&H 2001 §3.2): cameras, Embree primary rays, per-
pixel and per-vertex shading.
"""

from __future__ import annotations
