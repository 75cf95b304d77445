"""The H-basis and rival hemispherical bases (Habel & Wimmer 2010)."""

from __future__ import annotations
