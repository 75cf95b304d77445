"""``shprobe grid``: SH probe grids (irradiance volumes)."""

from __future__ import annotations

import click

from .grid_export import export


@click.group("grid")
def grid() -> None:
    """SH probe grids (irradiance volumes): bake, export."""


grid.add_command(export)


def register(group: click.Group) -> None:
    """Add the grid group to the top-level group."""
    group.add_command(grid)
