"""Settings of the lighting-design commands (``shprobe edit``, ``window``, ``export``): the
one defaults table their options read."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["EditSettings", "ExportSettings", "WindowSettings"]


def _as_dict(settings: Any) -> dict[str, Any]:
    return {f: getattr(settings, f) for f in settings.__dataclass_fields__}


@dataclass(frozen=True)
class EditSettings:
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

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values.

        Returns
        -------
        dict
            Each field.
        """
        return _as_dict(self)


@dataclass(frozen=True)
class WindowSettings:
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

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values.

        Returns
        -------
        dict
            Each field.
        """
        return _as_dict(self)


@dataclass(frozen=True)
class ExportSettings:
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

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values.

        Returns
        -------
        dict
            Each field.
        """
        return _as_dict(self)
