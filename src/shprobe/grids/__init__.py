"""SH probe grids (irradiance volumes): baked from a scene under a probe's lighting with
leak control, interpolated as engines do, exported to three.js, Unity and Godot."""

from .bake import bake_grid, estimate_grid_bake
from .grid import GRID_FORMAT, GRID_VERSION, ProbeGrid, cell_centres, plain_weights
from .io import load_grid, save_grid
from .settings import GridSettings

__all__ = ["GRID_FORMAT", "GRID_VERSION", "GridSettings", "ProbeGrid", "bake_grid",
           "cell_centres", "estimate_grid_bake", "load_grid", "plain_weights", "save_grid"]
