"""Grid files: a ``.npz`` with the arrays of [`ProbeGrid`][shprobe.grids.ProbeGrid] and its
bake settings as JSON, read back with every array checked before use."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ..errors import ShprobeError
from ..files import load_npz, npz_headers, save_npz
from .grid import GRID_FORMAT, GRID_VERSION, ProbeGrid

__all__ = ["load_grid", "save_grid"]

_OPTIONAL = ("positions", "validity", "depth")


def save_grid(path: str | os.PathLike[str], grid: ProbeGrid, overwrite: bool = False) -> Path:
    """Write ``grid`` to ``path`` (``*.npz``) atomically; non-finite values are refused.

    Parameters
    ----------
    path
        The output file (``*.npz``).
    grid
        The grid.
    overwrite
        Replace an existing file.

    Returns
    -------
    Path
        The file written.
    """
    arrays = {"coeffs": np.asarray(grid.coeffs, dtype=np.float32),
              "bounds": np.asarray(grid.bounds, dtype=np.float64)}
    for name in _OPTIONAL:
        a = getattr(grid, name)
        if a is not None:
            arrays[name] = np.asarray(a, dtype=np.float64 if name == "positions" else np.float32)
    head = {"format": GRID_FORMAT, "version": GRID_VERSION, **dict(grid.meta)}
    arrays["meta"] = np.frombuffer(json.dumps(head).encode(), dtype=np.uint8)
    return save_npz(path, overwrite=overwrite, **arrays)


def load_grid(path: str | os.PathLike[str]) -> ProbeGrid:
    """Read a grid written by [`save_grid`][shprobe.grids.save_grid] (``shprobe grid bake``); one
    line naming the file on anything else.

    Parameters
    ----------
    path
        A grid file (``*.npz``) written by ``save_grid``.

    Returns
    -------
    ProbeGrid
        The grid.
    """
    p = os.fspath(path)
    heads = npz_headers(p, "shprobe grid file")
    if "meta" not in heads or "coeffs" not in heads or "bounds" not in heads:
        raise ShprobeError("not a shprobe grid file (no meta/coeffs/bounds arrays)", p)
    d = load_npz(p, ["meta", "coeffs", "bounds", *_OPTIONAL], "shprobe grid file")
    try:
        meta = json.loads(d["meta"].astype(np.uint8).tobytes().decode())
    except (ValueError, UnicodeDecodeError):
        raise ShprobeError("grid file's meta is not JSON", p) from None
    if not isinstance(meta, dict) or meta.get("format") != GRID_FORMAT:
        raise ShprobeError("not a shprobe grid file", p)
    if int(meta.get("version", 0)) > GRID_VERSION:
        raise ShprobeError(f"grid file version {meta.get('version')} is newer than this "
                           f"shprobe reads ({GRID_VERSION})", p)
    for k, a in d.items():
        if k != "meta" and (a.dtype.kind not in "fiu" or not np.all(np.isfinite(a))):
            raise ShprobeError(f"grid array {k!r} is not finite numbers", p)
    try:
        return ProbeGrid(coeffs=d["coeffs"].astype(np.float32), bounds=d["bounds"],
                         positions=d.get("positions"), validity=d.get("validity"),
                         depth=d.get("depth"),
                         meta={k: v for k, v in meta.items() if k not in ("format", "version")})
    except ShprobeError as e:
        raise ShprobeError(e.message, p) from None
