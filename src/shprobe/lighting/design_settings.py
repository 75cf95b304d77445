"""Settings of the lighting-design commands (``shprobe edit``, ``window``, ``export``): the
one defaults table their options read."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["EditSettings", "ExportSettings", "WindowSettings"]


class _Fields:
    """What the three settings share: their fields as a JSON-able dict."""

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values.

        Returns
        -------
        dict
            Each field.
        """
        return {f: getattr(self, f) for f in self.__dataclass_fields__}


@dataclass(frozen=True)
class EditSettings(_Fields):
    """How lighting is edited and written (``shprobe edit``'s defaults).

    Parameters
    ----------
    lmax
        Degree of the result.
    weight
        Weight of the main source in a blend.
    window
        The window applied last (None: none; 'auto': the mildest that makes E ≥ 0).
    format
        The export format written.
    """

    lmax: int = 2
    weight: float = 1.0
    window: str | None = None
    format: str = "json"


@dataclass(frozen=True)
class WindowSettings(_Fields):
    """How lighting is certified and windowed (``shprobe window``'s defaults).

    Parameters
    ----------
    lmax
        Degree of the lighting.
    window
        'auto' (the mildest window that makes E ≥ 0), 'none', or KIND[:STRENGTH].
    """

    lmax: int = 2
    window: str = "auto"


@dataclass(frozen=True)
class ExportSettings(_Fields):
    """How lighting is exported (``shprobe export``'s defaults; the format is always given).

    Parameters
    ----------
    lmax
        Degree of the lighting exported.
    window
        The window applied before export (None: none).
    """

    lmax: int = 2
    window: str | None = None
