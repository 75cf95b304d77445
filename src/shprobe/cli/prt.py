"""CLI commands: ``shprobe prt bake`` and ``shprobe prt render`` (precomputed radiance transfer,
Lisle & Huang 2007 §4; library: [`shprobe.prt`][shprobe.prt]). They parse, build the settings
([`shprobe.prt.PrtSettings`][shprobe.prt.PrtSettings], `shprobe.prt.view.PrtRenderSettings`, whose
defaults the options read), call the library's entry and print."""

from __future__ import annotations

import click

from ..errors import ShprobeError
from ..prt.settings import PrtSettings
from ..prt.view import PrtRenderSettings
from .common import (
    ROTATE_HELP,
    clamp_option,
    force_option,
    layout_option,
    parse_albedo,
    parse_exposure,
    parse_floats,
    parse_rotation,
    parse_size,
    parse_vector,
    setting_default,
)
from .sources import PRESET_NAMES

MODES = ["unshadowed", "shadowed", "interreflected"]


def _bake_default(name: str):
    return setting_default(PrtSettings, name)


def _render_default(name: str):
    return setting_default(PrtRenderSettings, name)


def lighting(probe: str | None, preset: str | None, cone: str | None, lmax: int,
             coeffs_file: str | None = None, layout: str = "auto", clamp: bool = False):
    """Lighting coefficients (K, 3) from exactly one source: a probe (projected to ``lmax``),
    an R&H preset or a coefficient file (their own degree), or ``--cone DX,DY,DZ:APERTURE``,
    the LH §3.2 circular window (LH normalisation, total power 4π)."""
    import math

    from .sources import resolve_coeffs

    cone_arg = None
    if cone is not None:
        axis, sep, ap = cone.partition(":")
        if not sep:
            raise ShprobeError(f"--cone {cone!r}: expected DX,DY,DZ:APERTURE_DEG, e.g. 0,1,0:30")
        aperture = parse_floats(ap, 1, "cone aperture")[0]
        if not math.isfinite(aperture):
            raise ShprobeError(f"--cone {cone!r} must be finite numbers")
        cone_arg = (parse_vector(axis, "cone axis"), aperture)
    return resolve_coeffs(probe, preset, coeffs_file, layout=layout, clamp=clamp,
                          lmax=lmax if (probe or cone) else None, cone=cone_arg).coeffs


@click.group("prt")
def prt_group() -> None:
    """Precomputed radiance transfer (Lisle & Huang 2007 §4): bake transfer vectors per vertex
    once, relight under any SH lighting, rotation or degree without re-baking."""


@prt_group.command("bake")
@click.argument("scene", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--mode", type=click.Choice(MODES), default=_bake_default("mode"),
              show_default=True, help="Transfer model.")
@click.option("--lmax", type=int, default=_bake_default("lmax"), show_default=True,
              help="SH degree baked (a quick interreflected bunny on a ground: about 1½ min "
                   "at the default; docs/prt.md).")
@click.option("--samples", type=int, default=_bake_default("samples"), show_default=True,
              help="Ray directions per vertex (whole sphere; about half are traced).")
@click.option("--bounces", type=click.IntRange(min=0), default=_bake_default("bounces"),
              show_default=True,
              help="Interreflection bounces (interreflected only); render can use fewer.")
@click.option("--ground", is_flag=True, help="Add a ground plane under the meshes.")
@click.option("--albedo", multiple=True, metavar="RHO|R,G,B",
              help="Diffuse albedo: once for every mesh (and the ground), or once per mesh "
                   "in the order of SCENE. Default: a mesh's own vertex colours (sRGB "
                   "decoded), else 0.8.")
@click.option("--ground-albedo", default=None, metavar="RHO|R,G,B",
              help="Albedo of the ground plane (default: a single --albedo, else 0.8).")
@click.option("--seed", type=click.IntRange(min=0), default=_bake_default("seed"),
              show_default=True, help="Seed (>= 0) of the direction set's random rotation.")
@click.option("--threads", type=click.IntRange(min=1), default=_bake_default("threads"),
              help="Worker threads (default: all cores) for the Embree ray queries, the "
                   "numba ray-set/visibility kernels and the sparse bounce products. The "
                   "bake does no BLAS work of note; only Embree's BVH build (milliseconds) "
                   "uses Embree's own threads.")
@click.option("--refine/--no-refine", default=_bake_default("refine"),
              help="Subdivide the scene where the transfer varies fast (contacts, "
                   "occluders) and re-bake there; default: on for shadowed and "
                   "interreflected bakes with --ground.")
@click.option("--accurate-contact", is_flag=True,
              help="Refine the contact harder (implies --refine): the contact traced on "
                   "an adaptive grid of 32x --samples, the vertices its bounces lean on "
                   "too, a post-pass split and 256 rotated direction sets. On the bunny "
                   "the contact's worst error falls from 2.4-17x to 1.2-2.8x the open "
                   "vertices' noise, at about 10x the bake time (docs/prt.md).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Transfer file (.npz).")
@force_option
def bake_cmd(scene, mode, lmax, samples, bounces, ground, albedo, ground_albedo, seed,
             threads, refine, accurate_contact, output, force):
    """Bake per-vertex transfer vectors for SCENE (one or more OBJ/PLY/glTF meshes).

    One bake serves every model up to --mode: a shadowed bake can also be rendered
    unshadowed; an interreflected one also shadowed or with fewer bounces
    (`shprobe prt render --mode ... --bounces ...`)."""
    from ..files import check_output_path
    from ..prt import ACCURATE, bake, estimate_bake, load_scene
    from ..prt.geometry import albedo_keywords
    from .output import detail, estimate, limits, progress, wrote

    check_output_path(output, force)
    if accurate_contact and refine is False:
        raise ShprobeError("--accurate-contact refines; it cannot go with --no-refine")
    if refine and mode == "unshadowed":
        raise ShprobeError("--refine needs a traced bake (--mode shadowed or interreflected)")
    settings = PrtSettings(mode=mode, lmax=lmax, samples=samples, bounces=bounces, seed=seed,
                           threads=threads, refine=ACCURATE if accurate_contact else refine,
                           limits=limits())
    # the bake adds the ground (to the scene built here): its default refinement, said
    settings = settings.but(refine=settings.refinement(ground) or False)
    sc = load_scene(list(scene), ground=ground,
                    ground_albedo=None if ground_albedo is None else parse_albedo(ground_albedo),
                    **albedo_keywords([parse_albedo(a) for a in albedo], len(scene)))
    estimate(estimate_bake(sc, settings),
             f"{mode} bake of {sc.n_vertices:,} vertices at lmax {lmax}")
    t = bake(sc, settings, progress())
    t.save(output, overwrite=force)
    summary = t.as_dict()
    for r in summary["metadata"].get("refine", {}).get("rounds", []):
        detail(f"bake of {r['vertices']:,} vertices: {r['seconds']:.1f} s, {r['split']:,} "
               "edges split after it")
    models = ", ".join(summary["models"]) + (f" (<= {bounces} bounces)"
                                             if mode == "interreflected" else "")
    wrote(output, f"{mode} transfer, lmax {lmax}, {summary['vertices']:,} vertices"
          + (f", {samples} samples" if settings.traced else "") + f"; models: {models}")


@prt_group.command("render")
@click.argument("transfer", type=click.Path(dir_okay=False))
@click.argument("probe", required=False, type=click.Path(dir_okay=False))
@click.option("--preset", type=click.Choice(PRESET_NAMES), default=None,
              help="Use an R&H 2001 Fig. 2 table instead of a probe.")
@click.option("--coeffs", "coeffs_file", default=None, type=click.Path(dir_okay=False),
              help="Read lighting coefficients from a file in any `--format` that "
                   "`shprobe prefilter` writes.")
@click.option("--cone", default=None, metavar="DX,DY,DZ:APERTURE",
              help="Light by the LH §3.2 circular window (a disc light) about the axis, "
                   "aperture in degrees, total power 4π.")
@click.option("--rotate", default=None,
              help="Turn the scene relative to the lighting. " + ROTATE_HELP)
@click.option("--lmax", type=int, default=_render_default("lmax"),
              help="SH degree used (default: the transfer's; no re-bake).")
@click.option("--mode", type=click.Choice(MODES), default=_render_default("mode"),
              help="Model, picked at run time (default: the baked one): "
              "unshadowed from any bake, shadowed from a shadowed or interreflected bake, "
              "interreflected from an interreflected bake.")
@click.option("--bounces", type=click.IntRange(min=0), default=_render_default("bounces"),
              metavar="K",
              help="Interreflection bounces used (at most the baked number; default all).")
@click.option("--size", default="{}x{}".format(*_render_default("size")), show_default=True,
              help="Image size WxH.")
@click.option("--azimuth", type=float, default=_render_default("azimuth"), show_default=True,
              help="Camera azimuth (degrees).")
@click.option("--elevation", type=float, default=_render_default("elevation"),
              show_default=True, help="Camera elevation (degrees).")
@click.option("--exposure", default="auto", show_default=True, metavar="auto|STOPS",
              help="PNG exposure in stops; auto puts the 99th percentile of the vertex "
                   "radiance (over all frames) at 80 % of white. Linear formats ignore it.")
@click.option("--turntable", type=int, default=_render_default("turntable"), metavar="N",
              help="Write N frames (OUT_000.png …) of the lighting turning around +Y.")
@click.option("--scene", "scene_check", multiple=True, type=click.Path(dir_okay=False),
              help="Refuse the transfer unless it was baked for this mesh (repeat for "
                   "the several meshes of a scene; the baked ground plane is implied).")
@layout_option
@clamp_option
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Image: .png (tone-mapped) or .exr .hdr .pfm .tif (linear).")
@force_option
def render_cmd(transfer, probe, preset, coeffs_file, cone, rotate, lmax, mode, bounces,
               size, azimuth, elevation, exposure, turntable, scene_check, layout, clamp,
               output, force):
    """Relight TRANSFER under PROBE (or --preset / --coeffs / --cone) and render it."""
    from ..probes.images import check_image_output
    from ..prt import load_transfer
    from ..prt.view import render
    from .output import progress, wrote

    # the name as given (frames get _000 … suffixes; the render checks each before any work)
    check_image_output(output, force or turntable is not None)
    settings = PrtRenderSettings(
        lmax=lmax, mode=mode, bounces=bounces,
        rotation=None if rotate is None else parse_rotation(rotate), size=parse_size(size),
        azimuth=azimuth, elevation=elevation, exposure=parse_exposure(exposure),
        turntable=turntable)
    t = load_transfer(transfer, scene=list(scene_check) or None)
    try:
        use = settings.check(t)
    except ShprobeError as e:
        raise ShprobeError(e.message, transfer) from None
    coeffs = lighting(probe, preset, cone, use, coeffs_file, layout, clamp)
    result = render(t, coeffs, output, settings, progress(), overwrite=force)
    if turntable is None:
        wrote(output, "PRT frame")
    else:
        # every frame named, so the line reads "36 files in frames/: f_000.png … f_035.png"
        wrote(list(result.paths), "turntable frames")


def register(group: click.Group) -> None:
    """Add the ``prt`` group (bake, render)."""
    group.add_command(prt_group)
