"""Rotation of SH coefficients by real-basis Wigner matrices (Lisle & Huang 2007 §2.2)."""

from __future__ import annotations
