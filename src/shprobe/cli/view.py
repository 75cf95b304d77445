"""CLI command: view (the browser viewer, [`shprobe.viewer`][shprobe.viewer])."""

from __future__ import annotations

import click

from ..errors import ShprobeError


@click.command("view")
@click.argument("probe", required=False, type=click.Path(dir_okay=False))
@click.option("--layout", default="auto", show_default=True,
              help="Layout of PROBE (latlong, angular, mirrorball, cube, auto).")
@click.option("--preset", default=None, help="Start from an R&H preset instead of a probe.")
@click.option("--mesh", type=click.Path(dir_okay=False),
              help="Mesh (OBJ/PLY/glTF); default the Stanford bunny shipped with shprobe "
                   "('bunny').")
@click.option("--transfer", type=click.Path(dir_okay=False),
              help="A `shprobe prt bake` output: relight it per vertex in the page.")
@click.option("--grid", "grid", type=click.Path(dir_okay=False),
              help="A `shprobe grid bake` output: show its probes and move --mesh through "
                   "the volume, lit by interpolation (leak control on/off).")
@click.option("--scene", type=click.Path(dir_okay=False),
              help="With --grid: the scene the grid was baked from, drawn for context "
                   "(a mesh file, or `room` / `bunny-on-ground`, the reference scenes).")
@click.option("--hbasis", type=click.Path(dir_okay=False),
              help="A `shprobe hbasis bake` output for the mesh shown: its H-basis view.")
@click.option("--lightmap", type=click.Path(dir_okay=False),
              help="A `shprobe lightmap bake` output (.glb): the scene with its normal maps "
                   "and lightmap, encodings switchable, Fig. 1 / Fig. 5 panels.")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to bind (0.0.0.0 exposes the viewer to the network).")
@click.option("--port", default=0, show_default=True, type=click.IntRange(0, 65535),
              help="Port (0: a free one).")
@click.option("--no-browser", is_flag=True, help="Do not open a browser; print the URL.")
def view_cmd(probe, layout, preset, mesh, transfer, grid, scene, hbasis, lightmap, host,
             port, no_browser):
    """Interactive lighting design in the browser (R&H 2001 §3.3, LH 2007 §4): the probe,
    a mesh lit per pixel by shprobe's GLSL, compare SH / exact / error, drag to rotate,
    edit coefficients, add lights, window, export; PRT relighting with --transfer. Prints
    the URL with its access token once the files are read (a bad file, port or preset:
    one line, no URL); Ctrl-C stops it."""
    import os
    import time

    from .extras import require

    t_cli = time.time()
    require("viewer", "view")
    if probe and preset:
        raise ShprobeError("give either PROBE or --preset, not both")
    from ..scene.mesh import mesh_file

    if lightmap:  # the lightmap page (viewer.lightmap): cli.view_lightmap
        from .view_lightmap import view_lightmap

        return view_lightmap(lightmap, (probe, preset, mesh, transfer, grid, scene, hbasis),
                             host, port, no_browser)
    if grid or scene:  # the grid page (viewer.grid): cli.view_grid
        from .view_grid import view_grid

        return view_grid(grid, mesh_file(mesh) if mesh else None, scene,
                         (probe, preset, transfer, hbasis), host, port, no_browser)
    # the files start loading first (viewer.loader), in a fork that shares what both
    # sides need — numpy, the viewer's model, the lighting layer — imported once, here;
    # viewer.serve then builds the server while they load and prints the URL only once
    # they are read (a start-up failure is one line and no URL)
    from .. import lighting  # noqa: F401
    from ..viewer import serve
    from ..viewer.session import Session
    from .serve import LOCAL_HOSTS, announce

    # the loading stages' times, for bench/bench_viewer.py (served by /api/init)
    stamps = {"cli": t_cli} if os.environ.get("SHPROBE_VIEW_STAMPS") else None
    session = Session(probe, preset, mesh_file(mesh) if mesh else None, transfer, layout,
                      load=False, stamps=stamps, hbasis=hbasis)
    serve(session, host, port, lambda url: announce(url, host, no_browser),
          check_host=host in LOCAL_HOSTS)


def register(group: click.Group) -> None:
    """Add ``view`` to the top-level group."""
    group.add_command(view_cmd)
