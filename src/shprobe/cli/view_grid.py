"""CLI: ``shprobe view --grid GRID [--mesh OBJECT] [--scene SCENE]``, the grid page of the
viewer (`shprobe.viewer.grid`): its files are read before the URL is printed, so a bad
one is one line and a non-zero exit, with no server started."""

from __future__ import annotations

from ..errors import ShprobeError


def view_grid(grid: str | None, mesh: str | None, scene: str | None,
              others: tuple[str | None, ...], host: str, port: int, no_browser: bool) -> None:
    """Serve the grid page for ``grid`` until Ctrl-C. ``others``: PROBE, --preset,
    --transfer and --hbasis, which a grid's own lighting leaves no place for."""
    if grid is None:
        raise ShprobeError("--scene goes with --grid GRID")
    if any(others):
        raise ShprobeError("--grid shows the grid's own lighting: give no PROBE, --preset, "
                           "--transfer or --hbasis with it")
    from ..viewer import serve
    from ..viewer.grid import load_grid_view
    from .serve import LOCAL_HOSTS, announce

    view = load_grid_view(grid, mesh, scene)
    serve(view, host, port, lambda url: announce(url, host, no_browser),
          check_host=host in LOCAL_HOSTS)
