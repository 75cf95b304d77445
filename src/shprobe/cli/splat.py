"""CLI commands ``shprobe splat transform`` and ``shprobe splat info`` (a shell over
[`shprobe.splats`][shprobe.splats])."""

from __future__ import annotations

import json

import click

from ..errors import ShprobeError
from .common import ROTATE_HELP, force_option, parse_floats, parse_rotation


def _similarity(frame: str | None, matrix: str | None, mirrors: tuple[str, ...],
                rotations: tuple[str, ...], scale: float | None, translate: str | None):
    """The options, composed in the order the help states."""
    from ..splats import transform as tf

    sim = tf.Similarity.identity()
    if frame:
        src, sep, dst = frame.partition(":")
        if not sep:
            raise ShprobeError(f"--frame {frame!r}: expected FROM:TO, e.g. colmap:gltf")
        sim = sim.then(tf.frame(src, dst))
    if matrix is not None:  # "" is an empty matrix, refused, not no matrix
        sim = sim.then(tf.Similarity.from_matrix(parse_floats(matrix, None, "--matrix")))
    for axis in mirrors:
        sim = sim.then(tf.mirror(axis))
    for text in rotations:
        sim = sim.then(tf.rotation(parse_rotation(text)))
    if scale is not None:
        sim = sim.then(tf.uniform_scale(scale))
    if translate:
        sim = sim.then(tf.translation(parse_floats(translate, 3, "--translate")))
    return sim



@click.group("splat")
def splat() -> None:
    """Gaussian-splat scenes (3DGS / 2DGS .ply, Niantic .spz, glTF .glb with
    KHR_gaussian_splatting): transform them with every SH band, summarise them."""

@splat.command("transform")
@click.argument("src", metavar="IN", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="The file to write: .ply, .spz or .glb (any input to any output).")
@click.option("--frame", metavar="FROM:TO",
              help="Re-express the scene in another frame: colmap/opencv (RDF), "
                   "opengl/usd/three (RUB), gltf (LUF), blender (RFU), unity (RUF), or "
                   "three axis letters, e.g. colmap:gltf.")
@click.option("--matrix", metavar="M00,…,M33",
              help="A 4×4 similarity, 16 numbers row by row (x' = M x); shear and "
                   "non-uniform scale are refused.")
@click.option("--mirror", "mirrors", multiple=True, type=click.Choice(["x", "y", "z"]),
              help="Reflect through the plane normal to this axis (repeatable).")
@click.option("--rotate", "rotations", multiple=True, metavar="ROT",
              help=ROTATE_HELP + " Repeatable.")
@click.option("--scale", type=float, help="Uniform scale factor (> 0).")
@click.option("--translate", metavar="X,Y,Z", help="Translation, after the rest.")
@click.option("--sh-degree", type=click.IntRange(0, 3),
              help="Keep SH bands up to this degree (drop the others).")
@force_option
def transform_cmd(src, output, frame, matrix, mirrors, rotations, scale, translate,
                  sh_degree, force):
    """Move every splat of IN — position, covariance, opacity and every SH band — and
    write OUTPUT. The options apply in this order: --frame, --matrix, --mirror,
    --rotate, --scale, --translate. A PLY to PLY transform is streamed (its memory does
    not grow with the file)."""
    from ..splats import TransformSettings, transform_file
    from .output import detail, progress, wrote

    sim = _similarity(frame, matrix, mirrors, rotations, scale, translate)
    detail(f"similarity: {sim!r}")
    res = transform_file(src, output, TransformSettings(sim, sh_degree, force),
                         progress=progress())
    deg = (f"SH degree {res.degree_out}" if res.degree_in == res.degree_out
           else f"SH degree {res.degree_in} → {res.degree_out}")
    wrote(output, f"{res.count} splats, {deg}")

@splat.command("info")
@click.argument("src", metavar="IN", type=click.Path(dir_okay=False))
@click.option("--format", "fmt", type=click.Choice(["table", "json"]), default="table",
              show_default=True)
def info_cmd(src, fmt):
    """Count, SH degree, bounds and per-band SH energy of a splat file (band energy: mean
    over splats of the sum of squared coefficients of the band, RGB together; band 0 is
    f_dc)."""
    from ..splats import info
    from .output import progress

    res = info(src, progress=progress())
    if fmt == "json":
        click.echo(json.dumps(res.as_dict(), indent=1))
        return
    lo = ", ".join(f"{v:.6g}" for v in res.bounds_min)
    hi = ", ".join(f"{v:.6g}" for v in res.bounds_max)
    click.echo(f"{res.path}: {res.count} {res.kind} splats ({res.format}), "
               f"SH degree {res.degree}")
    click.echo(f"bounds: min ({lo})  max ({hi})")
    click.echo("band energy: " + "  ".join(f"l={l}: {e:.4g}"
                                             for l, e in enumerate(res.band_energy)))


def register(group: click.Group) -> None:
    """Add the ``splat`` group to the top-level group."""
    group.add_command(splat)
