"""CLI commands: the ``shprobe lightmap`` group and ``shprobe lightmap bake`` (directional
lightmaps, H&W 2010 §4.2–4.3; library: [`shprobe.lightmaps`][shprobe.lightmaps]). Other modules add
their commands to `lightmap` (``from shprobe.cli.lightmap import lightmap``)."""

from __future__ import annotations

import warnings

import click

from ..errors import ShprobeError
from .common import force_option
from .sources import PRESET_NAMES

__all__ = ["bake_cmd", "lightmap", "register"]


@click.group("lightmap")
def lightmap() -> None:
    """Directional lightmaps: bake a glTF/OBJ scene's irradiance into H-basis (or SH, HL2,
    plain) coefficient textures on a second UV set, with global illumination, for normal
    mapping (Habel & Wimmer 2010)."""


def _albedo(text: str | None) -> float | tuple[float, float, float] | None:
    if text is None:
        return None
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        v = []
    if len(v) == 1:
        return v[0]
    if len(v) == 3:
        return v[0], v[1], v[2]
    raise ShprobeError(f"--albedo takes RHO or R,G,B, got {text!r}")


@lightmap.command("bake")
@click.argument("scene", type=click.Path(dir_okay=False))
@click.option("--lighting", "probe", default=None, type=click.Path(dir_okay=False),
              metavar="PROBE", help="Probe image of the distant environment (its SH, lmax 2).")
@click.option("--preset", type=click.Choice(PRESET_NAMES), default=None,
              help="Light by an R&H 2001 Fig. 2 table instead of a probe.")
@click.option("--coeffs", "coeffs_file", default=None, type=click.Path(dir_okay=False),
              help="Light by SH coefficients from a file in any `shprobe prefilter` format.")
@click.option("--sun", default=None, metavar="DX,DY,DZ,R,G,B",
              help="A sun: direction towards it and its RGB irradiance (shadow rays).")
@click.option("--basis", type=click.Choice(["h6", "h4", "sh9", "sh4", "hl2", "plain"]),
              default="h6", show_default=True, help="The encoding written to the .glb.")
@click.option("--albedo", default=None, metavar="RHO|R,G,B",
              help="Albedo of every surface for the bounces (default: the materials').")
@click.option("--texels-per-unit", type=float, default=None,
              help="Lightmap density (texels per scene unit) instead of --size.")
@click.option("--size", type=int, default=256, show_default=True,
              help="Lightmap side in texels.")
@click.option("--bounces", type=int, default=1, show_default=True,
              help="Diffuse bounces inside the scene.")
@click.option("--samples", type=int, default=64, show_default=True,
              help="Hemisphere rays per texel: the accuracy option.")
@click.option("--denoise", is_flag=True,
              help="Run Intel Open Image Denoise (RTLightmap) on the coefficient maps.")
@click.option("--transfer", is_flag=True,
              help="Relightable: also store per texel the matrix from the sky's SH (lmax 2) "
                   "to the coefficients, shadows and bounces included.")
@click.option("--scheduler", default=None, metavar="tcp://HOST:PORT",
              help="Trace the texels' tiles on this Dask scheduler (as `shprobe batch`); "
                   "the result equals the local bake.")
@click.option("--seed", type=int, default=0, show_default=True, help="Sample pattern seed.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="The scene with TEXCOORD_1 and the SHPROBE_lightmap textures (.glb).")
@force_option
def bake_cmd(scene, probe, preset, coeffs_file, sun, basis, albedo, texels_per_unit, size,
             bounces, samples, denoise, transfer, scheduler, seed, output, force):
    """Bake SCENE (.glb, .gltf or .obj; its materials' base colour and normal maps) under
    a probe, preset or coefficient file (and an optional --sun) into a directional lightmap
    in the normal map's tangent frame; all six encodings are computed, --basis is written."""
    from ..files import check_output_path
    from ..lightmaps import LightmapSettings, bake_lightmap, load_scene, parse_sun
    from ..lightmaps.checks import check_scene
    from ..lightmaps.result import Lightmap
    from .output import detail, progress, wrote
    from .sources import resolve_coeffs

    check_output_path(output, force)
    if not str(output).lower().endswith(".glb"):
        raise ShprobeError("the output must be a .glb", output)
    given = [n for n, v in (("--lighting", probe), ("--preset", preset),
                            ("--coeffs", coeffs_file)) if v]
    if len(given) != 1:
        raise ShprobeError("give exactly one lighting source: --lighting PROBE, --preset NAME "
                           f"or --coeffs FILE (got {', '.join(given) or 'none'})")
    settings = LightmapSettings(basis=basis, albedo=_albedo(albedo),
                                texels_per_unit=texels_per_unit, size=size, bounces=bounces,
                                samples=samples, denoise=denoise,
                                sun=None if sun is None else parse_sun(sun), seed=seed,
                                transfer=transfer)
    from .extras import require

    require("lightmaps", "lightmap bake")
    light = resolve_coeffs(probe, preset, coeffs_file, lmax=2)
    sc = load_scene(scene)
    check_scene(sc)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        lm: Lightmap = bake_lightmap(sc, light, settings, progress=progress(),
                                     scheduler=scheduler)
    for w in caught:
        click.echo(f"warning: {scene}: {w.message}", err=True)
    lm.save(output, overwrite=force)
    d = lm.as_dict()
    detail(f"{d['texels_baked']} texels ({d['texels_invalid']} inside geometry, dilated), "
           f"{d['rays']} rays, noise ≈ {100 * d['noise_rel_rms']:.1f} %, "
           f"{d['seconds']:.1f} s")
    wrote(output, f"{lm.width}x{lm.height} {basis} lightmap, {bounces} bounces")


def register(group: click.Group) -> None:
    """Add the ``lightmap`` group."""
    group.add_command(lightmap)
