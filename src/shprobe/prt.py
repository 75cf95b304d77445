"""Precomputed radiance transfer (Lisle & Huang 2007 §4): unshadowed, shadowed and interreflected
diffuse transfer.
"""

from __future__ import annotations
