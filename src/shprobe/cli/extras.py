"""The optional parts of shprobe (pyproject.toml's extras) and the one line a command gives when
the extra it needs is not installed: ``pip install 'shprobe[batch]'``, no traceback.

The check finds the modules without importing them, so a command pays for its imports only
where it used to (``shprobe view`` imports its server after its loaders have forked).
"""

from __future__ import annotations

import importlib.util

from ..errors import ShprobeError

#: extra → the modules it installs that shprobe imports
EXTRAS: dict[str, tuple[str, ...]] = {
    "viewer": ("starlette", "uvicorn"),
    "batch": ("dask", "distributed", "pyarrow", "xxhash"),
    "lightmaps": ("xatlas", "pyoidn"),
}


def missing(extra: str) -> list[str]:
    """The modules of ``extra`` that cannot be imported here."""
    out = []
    for name in EXTRAS[extra]:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):  # a broken or blocked package counts as missing
            found = False
        if not found:
            out.append(name)
    return out


def require(extra: str, command: str) -> None:
    """Raise a one-line [`ShprobeError`][shprobe.errors.ShprobeError] naming the extra when its
    modules are missing."""
    gone = missing(extra)
    if gone:
        raise ShprobeError(f"shprobe {command} needs the optional packages of shprobe[{extra}] "
                           f"({', '.join(gone)} missing): pip install 'shprobe[{extra}]'")
