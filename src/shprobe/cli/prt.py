"""CLI commands: ``shprobe prt bake`` and ``shprobe prt render`` (precomputed radiance transfer,
Lisle & Huang 2007 §4; library: [`shprobe.prt`][shprobe.prt])."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import ShprobeError
from .common import (
    ROTATE_HELP,
    clamp_option,
    force_option,
    layout_option,
    parse_exposure,
    parse_floats,
    parse_rotation,
    parse_size,
    parse_vector,
)
from .sources import PRESET_NAMES

#: The most frames of ``prt render --turntable`` (0.1 degree apart).
MAX_TURNTABLE = 3600
#: Frames (angles spread over the turn) the automatic exposure of a turntable reads.
EXPOSURE_FRAMES = 72


def _albedo_value(text: str):
    """One ``--albedo`` value: a grey number or r,g,b."""
    v = parse_floats(text, what="albedo")
    if len(v) not in (1, 3):
        raise ShprobeError(f"albedo {text!r} must be one number or r,g,b")
    return v[0] if len(v) == 1 else tuple(v)


def albedo_arguments(values: tuple[str, ...], n_meshes: int) -> dict:
    """``--albedo`` given 0 times (defaults: vertex colours, else 0.8), once (every mesh and
    the ground) or once per mesh in order → the ``albedo`` / ``mesh_albedo`` bake arguments."""
    if not values:
        return {}
    parsed = [_albedo_value(v) for v in values]
    if len(parsed) == 1:
        return {"albedo": parsed[0]}
    if len(parsed) != n_meshes:
        raise ShprobeError(f"--albedo given {len(parsed)} times for {n_meshes} meshes: give it "
                           "once (every mesh) or once per mesh, in order")
    return {"mesh_albedo": parsed}


def _finite(values: list[float], what: str, text: str) -> list[float]:
    import math

    if not all(math.isfinite(v) for v in values):
        raise ShprobeError(f"{what} {text!r} must be finite numbers")
    return values


def lighting(probe: str | None, preset: str | None, cone: str | None, lmax: int,
             coeffs_file: str | None = None, layout: str = "auto", clamp: bool = False):
    """Lighting coefficients (K, 3) from exactly one source: a probe (projected to ``lmax``),
    an R&H preset or a coefficient file (their own degree), or ``--cone DX,DY,DZ:APERTURE``,
    the LH §3.2 circular window (LH normalisation, total power 4π)."""
    from .sources import resolve_coeffs

    cone_arg = None
    if cone is not None:
        axis, sep, ap = cone.partition(":")
        if not sep:
            raise ShprobeError(f"--cone {cone!r}: expected DX,DY,DZ:APERTURE_DEG, e.g. 0,1,0:30")
        cone_arg = (parse_vector(axis, "cone axis"),
                    _finite(parse_floats(ap, 1, "cone aperture"), "--cone", cone)[0])
    return resolve_coeffs(probe, preset, coeffs_file, layout=layout, clamp=clamp,
                          lmax=lmax if (probe or cone) else None, cone=cone_arg).coeffs


def register(group: click.Group) -> None:
    """Add the ``prt`` group (bake, render)."""

    @group.group("prt")
    def prt() -> None:
        """Precomputed radiance transfer (Lisle & Huang 2007 §4): bake transfer vectors per vertex
        once, relight under any SH lighting, rotation or degree without re-baking."""

    @prt.command("bake")
    @click.argument("scene", nargs=-1, required=True, type=click.Path(dir_okay=False))
    @click.option("--mode", type=click.Choice(["unshadowed", "shadowed", "interreflected"]),
                  default="shadowed", show_default=True, help="Transfer model.")
    @click.option("--lmax", type=int, default=10, show_default=True, help="SH degree baked.")
    @click.option("--samples", type=int, default=1024, show_default=True,
                  help="Ray directions per vertex (whole sphere; about half are traced).")
    @click.option("--bounces", type=click.IntRange(min=0), default=2, show_default=True,
                  help="Interreflection bounces (interreflected only); render can use fewer.")
    @click.option("--ground", is_flag=True, help="Add a ground plane under the meshes.")
    @click.option("--albedo", multiple=True, metavar="RHO|R,G,B",
                  help="Diffuse albedo: once for every mesh (and the ground), or once per mesh "
                       "in the order of SCENE. Default: a mesh's own vertex colours (sRGB "
                       "decoded), else 0.8.")
    @click.option("--ground-albedo", default=None, metavar="RHO|R,G,B",
                  help="Albedo of the ground plane (default: a single --albedo, else 0.8).")
    @click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
                  help="Seed (>= 0) of the direction set's random rotation.")
    @click.option("--threads", type=click.IntRange(min=1), default=None,
                  help="Worker threads (default: all cores) for the Embree ray queries, the "
                       "numba ray-set/visibility kernels and the sparse bounce products. The "
                       "bake does no BLAS work of note; only Embree's BVH build (milliseconds) "
                       "uses Embree's own threads.")
    @click.option("--refine/--no-refine", default=None,
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
        from ..prt import ACCURATE, QUICK, bake, estimate_bake, load_scene
        from .output import detail, estimate, progress, wrote

        check_output_path(output, force)
        if accurate_contact and refine is False:
            raise ShprobeError("--accurate-contact refines; it cannot go with --no-refine")
        sc = load_scene(list(scene), ground=ground,
                        ground_albedo=None if ground_albedo is None
                        else _albedo_value(ground_albedo),
                        **albedo_arguments(albedo, len(scene)))
        traced = mode != "unshadowed"
        settings = (ACCURATE if accurate_contact else QUICK if refine or (
            refine is None and traced and ground) else None)
        if settings is not None and not traced:
            raise ShprobeError("--refine needs a traced bake (--mode shadowed or interreflected)")
        est = estimate_bake(sc, mode, lmax, samples if traced else 16, bounces, settings,
                            threads)
        estimate(est, f"{mode} bake of {sc.n_vertices:,} vertices at lmax {lmax}")
        t = bake(sc, mode=mode, lmax=lmax, samples=samples, bounces=bounces, seed=seed,
                 threads=threads, progress=progress(),
                 refine=settings if settings is not None else False)
        t.save(output, overwrite=force)
        for r in t.metadata.get("refine", {}).get("rounds", []):
            detail(f"bake of {r['vertices']:,} vertices: {r['seconds']:.1f} s, {r['split']:,} "
                   "edges split after it")
        models = ", ".join(t.modes) + (f" (<= {bounces} bounces)" if mode == "interreflected"
                                       else "")
        wrote(output, f"{mode} transfer, lmax {lmax}, {t.n_vertices:,} vertices"
              + (f", {samples} samples" if traced else "") + f"; models: {models}")

    @prt.command("render")
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
    @click.option("--lmax", type=int, default=None,
                  help="SH degree used (default: the transfer's; no re-bake).")
    @click.option("--mode", type=click.Choice(["unshadowed", "shadowed", "interreflected"]),
                  default=None, help="Model, picked at run time (default: the baked one): "
                  "unshadowed from any bake, shadowed from a shadowed or interreflected bake, "
                  "interreflected from an interreflected bake.")
    @click.option("--bounces", type=click.IntRange(min=0), default=None, metavar="K",
                  help="Interreflection bounces used (at most the baked number; default all).")
    @click.option("--size", default="512x512", show_default=True, help="Image size WxH.")
    @click.option("--azimuth", type=float, default=0.0, show_default=True,
                  help="Camera azimuth (degrees).")
    @click.option("--elevation", type=float, default=20.0, show_default=True,
                  help="Camera elevation (degrees).")
    @click.option("--exposure", default="auto", show_default=True, metavar="auto|STOPS",
                  help="PNG exposure in stops; auto puts the 99th percentile of the vertex "
                       "radiance (over all frames) at 80 % of white. Linear formats ignore it.")
    @click.option("--turntable", type=int, default=None, metavar="N",
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
        from ..probes.tonemap import auto_exposure
        from ..prt import load_transfer
        from ..prt.view import frame_radiance, render_frame
        from ..sh.rotation import from_axis_angle

        # the name as given (frames get _000 … suffixes; their existence is checked below)
        check_image_output(output, force or turntable is not None)
        stops = parse_exposure(exposure)
        t = load_transfer(transfer, scene=list(scene_check) or None)
        use = t.lmax if lmax is None else lmax
        if use > t.lmax:
            raise ShprobeError(f"transfer was baked to lmax={t.lmax}, cannot render at {use}",
                               transfer)
        try:  # the model must be in the file: refuse before any work
            t.select(mode, bounces, use)
        except ShprobeError as e:
            raise ShprobeError(e.message, transfer) from None
        for value, name in ((azimuth, "--azimuth"), (elevation, "--elevation")):
            _finite([value], name, str(value))
        rot = None if rotate is None else parse_rotation(rotate)
        coeffs = lighting(probe, preset, cone, use, coeffs_file, layout, clamp)
        from ..progress import track
        from ..prt.view import turntable as turntable_frames
        from ..scene.camera import Camera
        from .output import progress, wrote

        if turntable is not None and not 1 <= turntable <= MAX_TURNTABLE:
            raise ShprobeError(f"--turntable needs 1 to {MAX_TURNTABLE} frames (0.1 degree "
                               f"apart), got {turntable}")
        w, h = parse_size(size)
        cam = Camera(width=w, height=h, azimuth=azimuth, elevation=elevation)
        model = {"mode": mode, "bounces": bounces}
        if turntable is None:
            if stops is None:
                stops = auto_exposure(frame_radiance(t, coeffs, rot, lmax=lmax, **model))
            render_frame(t, coeffs, rot, lmax=lmax, camera=cam, **model).save(output, stops,
                                                                              force)
            wrote(output, "PRT frame")
            return
        out = Path(output)

        def name(i: int) -> Path:
            return out.with_name(f"{out.stem}_{i:03d}{out.suffix}")

        for i in range(turntable):
            check_image_output(name(i), force)
        if stops is None:  # one exposure for all frames: the light turning must show
            # (from at most EXPOSURE_FRAMES angles spread over the turn: memory stays bounded)
            picked = sorted({i * turntable // EXPOSURE_FRAMES for i in range(EXPOSURE_FRAMES)}
                            if turntable > EXPOSURE_FRAMES else range(turntable))
            stops = auto_exposure([frame_radiance(
                t, coeffs, rot, from_axis_angle([0.0, 1.0, 0.0], 360.0 * i / turntable), lmax,
                **model) for i in picked])
        frames = turntable_frames(t, coeffs, turntable, rot, lmax=lmax, camera=cam, **model)
        for i, frame in enumerate(track(frames, progress(), "1/1: turntable frames",
                                        turntable)):
            frame.save(name(i), stops, force)  # one frame at a time: nothing accumulates
        # every frame named, so the line reads "36 files in frames/: f_000.png … f_035.png"
        wrote([name(i) for i in range(turntable)], "turntable frames")
