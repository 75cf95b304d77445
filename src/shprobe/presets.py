"""Lighting presets: the R&H 2001 Fig. 2 coefficient tables."""

from __future__ import annotations
