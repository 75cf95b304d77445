"""CLI command ``report``: one self-contained HTML page about a probe (``shprobe.report``)."""

from __future__ import annotations

import os

import click

from ..errors import ShprobeError
from ..report.probe import ReportSettings
from .common import clamp_option, force_option, layout_option, setting_default


@click.command("report")
@click.argument("probe", nargs=-1, required=True, metavar="PROBE...",
                type=click.Path(dir_okay=False))
@layout_option
@clamp_option
@click.option("--mesh", type=click.Path(dir_okay=False),
              help="Mesh for the basis images and the render (default: the unit sphere).")
@click.option("--render-size", type=click.IntRange(16, 2048),
              default=setting_default(ReportSettings, "render_size"),
              show_default=True, help="Side of the basis images and the render, pixels.")
@click.option("--map-size", type=click.IntRange(2, 256),
              default=setting_default(ReportSettings, "map_height"), show_default=True,
              help="N: the irradiance maps are 2N×N lat-long; the exact map and the error "
                   "table use the same 2N² normals (32: the normals of `shprobe error`).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="The page to write (.html).")
@force_option
def report_cmd(probe, layout, clamp, mesh, render_size, map_size, output, force):
    """One self-contained HTML page about PROBE (images inlined, no network): the probe,
    its irradiance map from 9 coefficients and the exact one, the error map and table,
    the coefficient table (R&H 2001 Fig. 2 layout), M (eq. 11-12), the non-negativity
    certificate and the window `auto` chooses, the nine basis images of the mesh and a
    render of it. PROBE is one image, or six cube faces (+X -X +Y -Y +Z -Z)."""
    from ..files import check_output_path
    from ..lighting.reference import MAP_CHUNK, reference_cost
    from ..report import probe_report, write_report
    from .output import estimate, progress, wrote
    from .sources import resolve_coeffs

    if len(probe) not in (1, 6):
        raise ShprobeError(f"give one probe image, or six cube faces in the order "
                           f"+X -X +Y -Y +Z -Z (got {len(probe)} files)")
    if not output.lower().endswith((".html", ".htm")):
        raise ShprobeError("a report is written as .html", output)
    check_output_path(output, force)  # refuse before the work
    _check_cost(probe, map_size)
    src = resolve_coeffs(probe[0] if len(probe) == 1 else list(probe), layout=layout,
                         lmax=2, clamp=clamp, need_env=True)
    geo, name = None, "the unit sphere"
    if mesh:
        from ..scene import load_mesh

        geo, name = load_mesh(mesh), os.path.basename(mesh)
    estimate(reference_cost(src.env, 2 * map_size * map_size, chunk=MAP_CHUNK),
             f"the report's exact irradiance at {2 * map_size * map_size} normals")
    rep = probe_report(src.env, geo, name,
                       ReportSettings(map_height=map_size, render_size=render_size),
                       progress())
    write_report(output, rep, force)
    wrote(output, f"{len(rep.figures)} figures; window auto: {rep.window.kind}")


def register(group: click.Group) -> None:
    """Add ``report`` to the top-level group."""
    group.add_command(report_cmd)


def _check_cost(probe, map_size: int) -> None:
    """The exact map's cost from the image headers, before the probe is read (a file that is
    not an image is left to the reader's own one-line error)."""
    from ..probes.streaming import image_size
    from ..report.probe import check_map_cost

    try:
        pixels = sum(float(w) * h for w, h in (image_size(p) for p in probe))
    except (ValueError, OSError):  # ShprobeError is a ValueError
        return
    check_map_cost(pixels, map_size, probe[0])
