"""``shprobe grid export GRID --format three|unity|godot -o FILE``: a baked grid in an engine's
format (`shprobe.grids.exports`; docs/grid-exports.md shows how each is loaded)."""

from __future__ import annotations

import os

import click

from .common import force_option
from .output import detail, wrote

# listed here so `--help` imports no numpy; equal to shprobe.grids.exports' (tested)
FORMATS = ("three", "unity", "godot")
SUFFIX = {"three": ".three.json", "unity": ".unity.json", "godot": ".tres"}
_WHAT = {"three": "three.js LightProbeGridWebGL", "unity": "Unity SphericalHarmonicsL2 probes",
         "godot": "Godot 4 resource"}


@click.command("export")
@click.argument("grid_file", metavar="GRID", type=click.Path(dir_okay=False))
@click.option("--format", "fmt", type=click.Choice(FORMATS), required=True,
              help="three: JSON for three.js's LightProbeGridWebGL (loader in the docs); "
                   "unity: JSON of SphericalHarmonicsL2 probes in Unity's left-handed frame; "
                   "godot: a .tres resource (LightmapGIData's probe SH).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output file (suggested suffixes: " + ", ".join(
                  f"{k} {v}" for k, v in SUFFIX.items()) + ").")
@force_option
def export(grid_file: str, fmt: str, output: str, force: bool) -> None:
    """Write the probe grid GRID (from `shprobe grid bake`) in an engine's format."""
    from ..files import check_output_path
    from ..grids.exports import export_grid
    from ..grids.io import load_grid

    check_output_path(output, force, inputs=(grid_file,))
    grid = load_grid(grid_file)
    export_grid(grid, fmt, output, overwrite=force, source=os.path.basename(grid_file))
    nx, ny, nz = grid.resolution
    if grid.depth is not None:
        detail("engines blend the probes trilinearly: the grid's visibility weights stay in "
               "shprobe; its leak control reaches them through the probe values")
    wrote(output, f"{_WHAT[fmt]}, {nx}x{ny}x{nz} probes")
