"""Procedural environments (the built-in default data of shprobe demo)."""

from __future__ import annotations
