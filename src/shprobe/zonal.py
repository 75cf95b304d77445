"""Zonal (circularly symmetric) functions: clamped cosine Â_l, Proposition 3.2, circular window,
Funk–Hecke convolution (LH 2007 §3; R&H 2001 eq. 5–9).
"""

from __future__ import annotations
