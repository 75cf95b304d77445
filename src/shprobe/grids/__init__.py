"""SH probe grids (irradiance volumes): baked from a scene under a probe's lighting with
leak control, interpolated as engines do, exported to three.js, Unity and Godot."""

from typing import TYPE_CHECKING, Any

from .grid import GRID_FORMAT, GRID_VERSION, ProbeGrid, cell_centres, plain_weights
from .io import load_grid, save_grid
from .settings import GridSettings

if TYPE_CHECKING:  # pragma: no cover
    from .bake import bake_grid, estimate_grid_bake

__all__ = ["GRID_FORMAT", "GRID_VERSION", "GridSettings", "ProbeGrid", "bake_grid",
           "cell_centres", "estimate_grid_bake", "load_grid", "plain_weights", "save_grid"]


def __getattr__(name: str) -> Any:
    """The bake on first use: reading and interpolating a grid (the viewer, the exports)
    does not import the PRT scene and the ray caster."""
    if name in ("bake_grid", "estimate_grid_bake"):
        from . import bake

        return getattr(bake, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
