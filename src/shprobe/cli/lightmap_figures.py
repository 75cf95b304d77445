"""CLI command: ``shprobe lightmap figures OUT.glb -o DIR`` — Habel & Wimmer 2010's Fig. 1 and
Fig. 5 for a baked scene, and an error-per-encoding heat map (library:
`shprobe.lightmaps.figures.lightmap_figures`). It joins the ``lightmap`` group of
`shprobe.cli.lightmap`; `register` adds that group with this command and ``shader``
(`shprobe.cli.lightmap_shader`) in it."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import ShprobeError
from .common import force_option
from .lightmap import lightmap
from .lightmap import register as _register_group

__all__ = ["figures_cmd", "register"]

FILES = ("fig1.png", "fig5.png", "errors.png")


@lightmap.command("figures")
@click.argument("lightmap_file", metavar="OUT.glb", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(file_okay=False),
              help="Folder for fig1.png, fig5.png and errors.png.")
@click.option("--size", default="480x320", show_default=True, metavar="WxH",
              help="Pixels of one panel.")
@click.option("--eye", default=None, metavar="X,Y,Z", help="Camera position (world frame).")
@click.option("--target", default=None, metavar="X,Y,Z", help="Point the camera looks at.")
@click.option("--fov", type=float, default=60.0, show_default=True,
              help="Vertical field of view, degrees.")
@force_option
def figures_cmd(lightmap_file, output, size, eye, target, fov, force):
    """Pictures of a baked lightmap as Habel and Wimmer 2010 show theirs: fig1.png (plain
    lightmap, H6 without albedo, H6 with albedo) and fig5.png (H4 beside H6) for the scene of
    OUT.glb seen from one camera by ray casting, one exposure for all panels (none clips), and
    errors.png: each encoding the file implies against the richest (bake with --basis sh9 for
    all six)."""
    from ..lightmaps.figures import FigureSettings, lightmap_figures
    from .common import parse_floats
    from .output import detail, progress, wrote

    try:
        w, h = (int(x) for x in size.lower().split("x"))
    except ValueError:
        raise ShprobeError(f"--size {size!r}: expected WxH, e.g. 480x320") from None
    settings = FigureSettings(
        width=w, height=h, fov=fov,
        eye=None if eye is None else tuple(parse_floats(eye, 3, "--eye")),
        target=None if target is None else tuple(parse_floats(target, 3, "--target")))
    out = Path(output)
    taken = [str(out / f) for f in FILES if (out / f).exists()]
    if taken and not force:
        raise ShprobeError(f"{taken[0]} exists (use --force to replace the figures)")
    res = lightmap_figures(lightmap_file, out, settings, progress=progress())
    for e, v in res.errors.items():
        detail(f"{e}: mean {100 * v['mean']:.2f} %, p95 {100 * v['p95']:.2f} % "
               f"against {res.reference}")
    wrote(list(res.paths.values()), f"exposure {res.exposure:.2f} stops")


def register(group: click.Group) -> None:
    """Add the ``lightmap`` group (with ``figures`` in it).

    Parameters
    ----------
    group : click.Group
        The top-level group.
    """
    from . import lightmap_shader  # noqa: F401  (adds ``lightmap shader`` to the group)

    _register_group(group)
