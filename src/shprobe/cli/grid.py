"""CLI commands: the ``shprobe grid`` group and ``shprobe grid bake`` (irradiance volumes;
library: [`shprobe.grids`][shprobe.grids]); ``grid export`` lives in `shprobe.cli.grid_export`."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import ShprobeError
from ..grids.settings import GridSettings
from .common import (
    clamp_option,
    force_option,
    layout_option,
    parse_albedo,
    parse_floats,
    setting_default,
)
from .sources import PRESET_NAMES


def _default(name: str):
    return setting_default(GridSettings, name)


@click.group("grid")
def grid() -> None:
    """Irradiance volumes: bake a grid of SH probes that does not leak through walls, for
    engines (three.js LightProbeGrid, Unity, Godot)."""


def parse_resolution(text: str) -> tuple[int, int, int]:
    """'NX,NY,NZ' (or one N for all three) → three integers, one line otherwise."""
    parts = [t for t in text.replace(" ", "").replace("x", ",").split(",") if t]
    try:
        vals = [int(t) for t in parts]
    except ValueError:
        raise ShprobeError(f"--resolution {text!r}: expected three integers NX,NY,NZ") from None
    if len(vals) == 1:
        vals *= 3
    if len(vals) != 3:
        raise ShprobeError(f"--resolution {text!r}: expected three integers NX,NY,NZ")
    return vals[0], vals[1], vals[2]


def parse_bounds(text: str):
    """'X0,Y0,Z0,X1,Y1,Z1' → (2, 3) checked bounds."""
    from ..grids.settings import check_bounds

    return check_bounds(parse_floats(text, 6, "--bounds"))


@grid.command("bake")
@click.argument("scene", nargs=-1, required=True, type=click.Path(dir_okay=False),
                metavar="SCENE...")
@click.option("--lighting", "probe", default=None, type=click.Path(dir_okay=False),
              metavar="PROBE", help="Probe image lighting the scene (its pixels are looked "
                                    "up directly by the rays that leave the scene).")
@click.option("--preset", type=click.Choice(PRESET_NAMES), default=None,
              help="Light by an R&H 2001 Fig. 2 table instead of a probe.")
@click.option("--coeffs", "coeffs_file", default=None, type=click.Path(dir_okay=False),
              help="Light by SH coefficients from a file in any `shprobe prefilter` format.")
@layout_option
@clamp_option
@click.option("--resolution", required=True, metavar="NX,NY,NZ",
              help="Probes along X, Y, Z (one per cell, at the cell centres).")
@click.option("--bounds", default=None, metavar="X0,Y0,Z0,X1,Y1,Z1",
              help="Volume of the grid (default: the scene's bounding box).")
@click.option("--albedo", multiple=True, metavar="RHO|R,G,B",
              help="Diffuse albedo: once for every mesh, or once per mesh in the order of "
                   "SCENE. Default: a mesh's own colours and materials, else 0.8.")
@click.option("--bounces", type=int, default=_default("bounces"), show_default=True,
              help="Diffuse interreflection bounces (0: the environment past the scene only).")
@click.option("--lmax", type=click.Choice(["1", "2"]), default=str(_default("lmax")),
              show_default=True, help="SH degree of each probe (L1: 4 coefficients, L2: 9).")
@click.option("--samples", type=int, default=_default("samples"), show_default=True,
              help="Rays per probe: the accuracy option (docs/grids.md gives its cost and "
                   "gain).")
@click.option("--gather", type=int, default=_default("gather"), show_default=True,
              help="Rays from each surface a probe ray meets, gathering that surface's own "
                   "light (0: read it from the grid, faster, up to 13 % high beside walls).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Grid file (.npz), read by shprobe.load_grid.")
@force_option
def bake_cmd(scene, probe, preset, coeffs_file, layout, clamp, resolution, bounds, albedo,
             bounces, lmax, samples, gather, output, force):
    """Bake an irradiance volume of SCENE (one or more OBJ/PLY/glTF meshes, or a reference
    scene by name: `room`, a closed room on an open ground, or `bunny-on-ground`, each with
    its own default --bounds) under a probe or preset: per probe, the environment seen past
    the scene plus the scene's diffuse light to --bounces bounces, probes inside geometry
    moved out, and depth maps that keep the interpolation from leaking through walls."""
    from ..files import check_output_path
    from ..grids import GridSettings, bake_grid, estimate_grid_bake
    from ..grids.bake import grid_scene
    from ..grids.io import save_grid
    from .output import detail, estimate, limits, progress, wrote
    from .sources import resolve_coeffs

    check_output_path(output, force)
    if Path(output).suffix.lower() != ".npz":  # save_grid's rule, said before the bake
        raise ShprobeError("an .npz output must be named *.npz", output)
    settings = GridSettings(resolution=parse_resolution(resolution),
                            bounds=None if bounds is None else parse_bounds(bounds),
                            lmax=int(lmax), bounces=bounces, samples=samples,
                            gather=gather, limits=limits())
    light = resolve_coeffs(probe, preset, coeffs_file, layout=layout, clamp=clamp,
                           lmax=8 if probe else None, need_env=False,
                           probe_flag="--lighting PROBE")
    sc, settings = grid_scene(scene, settings, [parse_albedo(a) for a in albedo])
    nx, ny, nz = settings.resolution
    estimate(estimate_grid_bake(len(sc.faces), settings, sc),
             f"bake of a {nx}x{ny}x{nz} grid, {samples} rays per probe")
    g = bake_grid(sc, light, settings, progress=progress())
    save_grid(output, g, overwrite=force)
    meta = g.as_dict()["meta"]
    detail(f"{meta['moved']} probes moved out of geometry, {meta['invalid']} invalid "
           f"(filled from neighbours); bake {meta['seconds']:.1f} s")
    wrote(output, f"{nx}x{ny}x{nz} grid, lmax {lmax}, {bounces} bounces")


def register(group: click.Group) -> None:
    """Add the ``grid`` group, with ``grid export`` (`shprobe.cli.grid_export`)."""
    from .grid_export import export

    grid.add_command(export)
    group.add_command(grid)
