"""CLI commands: render, basis-images, edit, window, export (see ``shprobe.scene.render``,
``shprobe.lighting.design``, ``shprobe.lighting.export``)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import click

from ..errors import ShprobeError
from ..lighting.design_settings import EditSettings, ExportSettings, WindowSettings
from ..lighting.export import FORMATS
from ..scene.workflow import RENDER_MODES, BasisImagesSettings, RenderSettings
from .common import (
    ROTATE_HELP,
    force_option,
    parse_exposure,
    parse_floats,
    parse_size,
    setting_default,
)
from .output import progress, wrote
from .sources import coeff_source_options, resolve_coeffs


def _default(name: str, settings_type: type = RenderSettings):
    return setting_default(settings_type, name)


WINDOW_HELP = ("Window the lighting: 'auto' (mildest window giving E >= 0), or KIND:STRENGTH "
               "with KIND one of hann, lanczos, gaussian, laplacian.")


# ----------------------------------------------------------------------------- helpers


def source_options(fn):
    """[PROBE] | --preset NAME | --coeffs FILE (+ --layout, --clamp): cli.sources."""
    return coeff_source_options(fn)


def load_source(probe, preset, coeffs_file, layout="auto", clamp=False, lmax=2,
                required=True) -> tuple[Any, str, Any]:
    """(coefficients (K, C), name, Env or None) from the source options
    (`shprobe.cli.sources.resolve_coeffs`)."""
    if not required and not (probe or preset or coeffs_file):
        return None, "", None
    src = resolve_coeffs(probe, preset, coeffs_file, layout=layout, lmax=lmax, clamp=clamp)
    return src.coeffs, src.source, src.env


def edit(coeffs, options: dict[str, Any], layout: str = "auto", clamp: bool = False):
    """The edit options of a command
    ([`shprobe.lighting.edits.EditSpec.from_options`][shprobe.lighting.EditSpec.from_options])
    applied by `shprobe.lighting.design.edit_lighting` (blended probes read in ``layout``); returns
    (coeffs, description of the window step or None)."""
    from ..lighting.design import edit_lighting
    from ..lighting.edits import EditSpec
    from ..lighting.source import blend_lighting

    res = edit_lighting(coeffs, EditSpec.from_options(options),
                        lambda b, lmax: blend_lighting(b, lmax, layout, clamp))
    return res.coeffs, res.window


def export_path(output: str | None, source: str, options: dict[str, Any], fmt: str) -> str:
    """Where an export goes: ``-o FILE`` as given; ``-o FOLDER``, or no ``-o``, the export's
    name in that folder or here (`shprobe.lighting.filenames.export_name`: the name the
    viewer gives the same export's download)."""
    from ..lighting.edits import EditSpec
    from ..lighting.filenames import export_name

    if output and not os.path.isdir(output):
        return output
    name = export_name(source, EditSpec.from_options(options), fmt)
    return os.path.join(output, name) if output else name


def camera_options_of(settings_type: type = RenderSettings):
    """The camera's options, their defaults from ``settings_type``'s fields."""

    def dflt(name: str):
        return _default(name, settings_type)

    opts = [
        click.option("--size", default="{}x{}".format(*dflt("size")), show_default=True,
                     help="Image size WxH."),
        click.option("--azimuth", default=dflt("azimuth"), show_default=True,
                     help="Orbit angle about +Y in degrees (0: camera on +Z looking along -Z)."),
        click.option("--elevation", default=dflt("elevation"), show_default=True,
                     help="Orbit elevation in degrees."),
        click.option("--fov", default=dflt("fov"), show_default=True,
                     help="Vertical field of view in degrees (perspective)."),
        click.option("--ortho", is_flag=True, default=dflt("ortho"),
                     help="Orthographic camera."),
        click.option("--mode", type=click.Choice(list(RENDER_MODES)), default=dflt("mode"),
                     show_default=True,
                     help="Shade per pixel, or per vertex and interpolate (R&H procedural)."),
    ]

    def decorate(fn):
        for o in reversed(opts):
            fn = o(fn)
        return fn

    return decorate


camera_options = camera_options_of(RenderSettings)


def make_camera(size, azimuth, elevation, fov, ortho):
    from ..scene.camera import Camera

    w, h = parse_size(size)
    return Camera(w, h, projection="orthographic" if ortho else "perspective",
                  azimuth=azimuth, elevation=elevation, fov=fov)


def load_geometry(mesh, sphere):
    from ..scene.mesh import load_mesh

    if mesh and sphere:
        raise ShprobeError("give either --mesh MESH or --sphere, not both")
    return None if (sphere or not mesh) else load_mesh(mesh)


def _basis_sheet(B, lmax, scale, out, force, obj):
    """The labelled pyramid sheet: band l on row l, centred; one colour bar, sign
    legend."""
    from ..probes.figures import Panel, write_figure
    from ..sh import sh_lm

    rows = [[None] * (2 * lmax + 1) for _ in range(lmax + 1)]
    for k in range(B.shape[-1]):
        l, m = sh_lm(k)
        rows[l][lmax + m] = Panel(B[..., k], f"(l, m) = ({l}, {m:+d})", "signed",
                                  units="Â_l y_lm(n) / π", scale=scale)
    write_figure(out / "basis.png", rows, overwrite=force, shared_colorbar=True,
                 title=f"irradiance basis images of {obj} (R&H 2001 Fig. 4): the object "
                       "under L = e_lm",
                 display_width=min(B.shape[1], 192))


# ----------------------------------------------------------------------------- commands



@click.command("render")
@source_options
@click.option("--mesh", type=click.Path(dir_okay=False),
              help="Mesh to render (OBJ, PLY, glTF/GLB).")
@click.option("--sphere", is_flag=True, help="Render the analytic unit sphere (default).")
@camera_options
@click.option("--albedo", default=None,
              help="Constant albedo r,g,b (default: the mesh's texture, vertex or face "
                   "colours or material colour, else 1).")
@click.option("--background", default=None,
              help="'env' (the probe itself, default with a probe), 'none', or r,g,b.")
@click.option("--exposure", default="auto", show_default=True, metavar="auto|STOPS",
              help="PNG tone map: x 2^EXPOSURE, clamp, sRGB; auto puts the 99th percentile "
                   "of the object's radiance at white (printed).")
@click.option("--window", "window", default=None, help=WINDOW_HELP)
@click.option("--rotate", multiple=True, help="Turn the lighting. " + ROTATE_HELP
              + " Repeatable.")
@click.option("--lmax", default=2, show_default=True, help="SH degree of the lighting.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output image: .png (tone-mapped) or .exr/.hdr/.pfm (linear).")
@click.option("--exr", type=click.Path(dir_okay=False), help="Also write linear EXR here.")
@force_option
def render_cmd(probe, layout, clamp, preset, coeffs_file, mesh, sphere, size, azimuth,
               elevation, fov, ortho, mode, albedo, background, exposure, window, rotate,
               lmax, output, exr, force):
    """Render a diffuse object lit by SH lighting (R&H 2001 §3.2): radiance =
    albedo * E(n) / pi, E from the coefficients (eq. 7, 11-13). The background shows the
    probe when one is given. PNG tone map: exposure in stops, clamp, sRGB."""
    from ..probes.images import check_image_output
    from ..scene.workflow import render_image

    for path in (output, exr):  # refused before any work (render_image checks them too)
        if path:
            check_image_output(path, force)
    settings = RenderSettings(mode=mode, size=parse_size(size), azimuth=azimuth,
                              elevation=elevation, fov=fov, ortho=ortho,
                              albedo=parse_floats(albedo, 3, "albedo") if albedo else None,
                              exposure=parse_exposure(exposure))  # refused before the work
    coeffs, name, env = load_source(probe, preset, coeffs_file, layout, clamp, lmax)
    coeffs, wdesc = edit(coeffs, {"lmax": lmax, "window": window, "rotate": rotate})
    geo = load_geometry(mesh, sphere)
    if background is None:
        bg = env
    elif background.lower() == "env":
        if env is None:
            raise ShprobeError("--background env needs a probe image as the source")
        bg = env
    elif background.lower() == "none":
        bg = None
    else:
        bg = parse_floats(background, 3, "background colour")
    res = render_image(geo, coeffs, output, settings, progress(), background=bg,
                       linear_copy=exr, overwrite=force)
    stops, auto = res.exposure, res.auto
    ldr = output.lower().endswith((".png", ".jpg", ".jpeg"))
    wrote([output, *([exr] if exr else [])],
          f"{res.width}x{res.height} {mode} shading of "
          f"{'sphere' if geo is None else os.path.basename(mesh)} under {name}, "
          f"{100 * res.object_fraction:.1f}% object pixels"
          + (f", exposure {stops:+.2f} stops{' (auto)' if auto else ''}" if ldr else "")
          + (f"; {wdesc}" if wdesc else ""))

@click.command("basis-images")
@click.argument("mesh", required=False, type=click.Path(dir_okay=False))
@click.option("--sphere", is_flag=True, help="Use the unit sphere instead of a mesh.")
@camera_options_of(BasisImagesSettings)
@click.option("--lmax", default=_default("lmax", BasisImagesSettings), show_default=True)
@click.option("-o", "--output", "outdir", required=True, type=click.Path(file_okay=False),
              help="Output folder (created).")
@force_option
def basis_cmd(mesh, sphere, size, azimuth, elevation, fov, ortho, mode, lmax, outdir,
              force):
    """Render the irradiance basis images of an object (R&H 2001 §3.3, Fig. 4): for each
    (l, m) the object under L = e_lm, i.e. A_l y_lm(n) / pi. PNGs: positive green,
    negative blue, one common linear scale (so l = 2 looks dimmer, as in the paper);
    EXRs: the signed linear values. Any lighting L gives image = sum L_lm * basis_lm."""
    import numpy as np

    from ..files import check_output_path
    from ..probes.images import write_image
    from ..progress import Steps
    from ..scene.render import basis_images, basis_visual
    from ..sh import check_lmax, num_coeffs, sh_lm

    if not mesh and not sphere:
        raise ShprobeError("give a MESH or --sphere")
    out = Path(outdir)
    if out.exists() and not out.is_dir():
        raise ShprobeError("exists and is not a folder", out)
    stems = [out / "basis_l{}_m{:+d}".format(*sh_lm(k))
             for k in range(num_coeffs(check_lmax(lmax)))]
    for p in [*(st.with_suffix(e) for st in stems for e in (".exr", ".png")),
              out / "basis.png"]:  # every output refused before any work
        check_output_path(p, force)
    geo = load_geometry(mesh, sphere)
    cam = make_camera(size, azimuth, elevation, fov, ortho)
    with Steps(progress(), 3) as step:
        step(f"rendering {len(stems)} basis images {cam.width}x{cam.height}")
        res = basis_images(geo, cam, lmax=lmax, mode=mode)
        B = res.image
        scale = float(np.abs(B).max())
        bar = step(f"writing {2 * len(stems)} images (EXR + PNG)", total=2 * len(stems))
        from ..files import transaction

        with transaction():  # every basis image and the sheet, or none of them
            for k, stem in enumerate(stems):
                write_image(stem.with_suffix(".exr"), B[..., k], overwrite=force)
                write_image(stem.with_suffix(".png"), basis_visual(B[..., k], scale),
                            overwrite=force)
                bar.advance(2)
            step("the labelled sheet basis.png")
            _basis_sheet(B, lmax, scale, out, force,
                         "the unit sphere" if geo is None else os.path.basename(mesh))
    wrote([*(st.with_suffix(e) for st in stems for e in (".exr", ".png")),
           out / "basis.png"], f"{B.shape[-1]} basis images, PNG + EXR and the sheet; "
                               f"common scale {scale:.4g}")

@click.command("edit")
@source_options
@click.option("--lmax", type=click.IntRange(0, 64), default=_default("lmax", EditSettings),
              show_default=True,
              help="Degree of the result (a probe is projected to it, at least 2; "
                   "presets and coefficient files are cut or zero-padded; edits above it "
                   "are refused).")
@click.option("--blend", "blends", multiple=True,
              help="Add another lighting FILE:WEIGHT (a probe image, projected, or "
                   "coefficients in any export format) or preset:NAME:WEIGHT. "
                   "Repeatable.")
@click.option("--weight", default=_default("weight", EditSettings), show_default=True,
              help="Weight of the main source in the blend.")
@click.option("--directional", multiple=True,
              help="Add a directional light DX,DY,DZ:R,G,B (direction towards the light; "
                   "irradiance). Repeatable.")
@click.option("--cone", multiple=True,
              help="Add a disc light DX,DY,DZ:APERTURE_DEG:R,G,B (radiance). Repeatable.")
@click.option("--sky", default=None,
              help="Add a hemisphere light SKY_R,G,B[:GROUND_R,G,B[:UX,UY,UZ]].")
@click.option("--set", "sets", multiple=True, help="L,M=R,G,B (or one value).")
@click.option("--scale", "scales", multiple=True, help="L,M=FACTOR.")
@click.option("--negate", "negates", multiple=True, help="L,M.")
@click.option("--set-band", multiple=True, help="L=R,G,B.")
@click.option("--scale-band", multiple=True, help="L=FACTOR (0 removes the band).")
@click.option("--negate-band", multiple=True, type=int, help="L.")
@click.option("--rotate", "rotations", multiple=True,
              help="Turn the lighting. " + ROTATE_HELP + " Repeatable.")
@click.option("--window", "window", default=_default("window", EditSettings), help=WINDOW_HELP)
@click.option("--format", "fmt", type=click.Choice(FORMATS),
              default=_default("format", EditSettings), show_default=True,
              help="Output format (see `shprobe export`).")
@click.option("-o", "--output", type=click.Path(),
              help="Output file, or a folder for the default name (default: "
                   "<source>-<edit>-lmax<N>.<ext> here, the viewer's download name).")
@force_option
def edit_cmd(probe, layout, clamp, preset, coeffs_file, lmax, blends, weight, directional,
             cone, sky, sets, scales, negates, set_band, scale_band, negate_band,
             rotations, window, fmt, output, force):
    """Lighting design (R&H 2001 §3.3): start from a source (or from darkness), then, in
    this order: blend, add lights, set/scale/negate coefficients and bands, rotate,
    window; write the coefficients."""

    from ..files import check_output_path, write_text
    from ..lighting.export import export_coeffs
    from ..sh import lmax_of

    if output and not os.path.isdir(output):
        check_output_path(output, force)
    # a probe is projected to the result's degree (as a blended probe is), at least 2;
    # presets and coefficient files keep theirs (cut or zero-padded below)
    base, name, _ = load_source(probe, preset, coeffs_file, layout, clamp,
                                max(lmax, 2) if probe else None, required=False)
    options = {
        "lmax": lmax, "weight": weight, "blend": blends, "directional": directional,
        "cone": cone, "sky": sky, "set": sets, "scale": scales, "negate": negates,
        "set_band": set_band, "scale_band": scale_band, "negate_band": negate_band,
        "rotate": rotations, "window": window}
    output = export_path(output, name, options, fmt)
    check_output_path(output, force)
    L, wdesc = edit(base, options, layout, clamp)
    write_text(output, export_coeffs(L, fmt, source=name or "shprobe edit"),
               overwrite=force)
    wrote(output, f"{fmt}, lmax {lmax_of(L.shape[0])}, from {name or 'darkness'}"
          + (f"; {wdesc}" if wdesc else ""))

@click.command("window")
@source_options
@click.option("--lmax", default=_default("lmax", WindowSettings), show_default=True)
@click.option("--window", "window", default=_default("window", WindowSettings),
              show_default=True, help=WINDOW_HELP)
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="Write the windowed coefficients (JSON).")
@force_option
def window_cmd(probe, layout, clamp, preset, coeffs_file, lmax, window, output, force):
    """Certify min E(n) over the sphere (exact for lmax <= 2: trust-region dual of
    n^T M n, R&H eq. 11; numerical above) and window the lighting until E >= 0
    ('auto': the mildest of hann, lanczos, gaussian, laplacian by the L2 bias of E)."""
    from ..files import write_text
    from ..lighting.export import export_coeffs
    from ..lighting.windows import (
        WINDOWS,
        apply_window,
        auto_window,
        min_irradiance,
        parse_window,
        window_bias,
        window_factors,
    )

    coeffs, name, _ = load_source(probe, preset, coeffs_file, layout, clamp, lmax)
    spec = parse_window(window)
    before = min_irradiance(coeffs)

    def show(tag, cert):
        kind = "certified" if cert.exact else "numerical"
        vals = ", ".join(f"{v:.5g}" for v in cert.minimum)
        click.echo(f"{tag}: min E = ({vals}) [{kind}, {cert.method}]")

    click.echo(f"{name}: lmax {lmax}")
    show("before", before)
    if spec == "auto":
        ch = auto_window(coeffs)
        for k in WINDOWS:
            if k in ch.candidates:
                s, b = ch.candidates[k]
                click.echo(f"  {k:9s} strength {s:.5g}  bias {100 * b:.3f}%")
        f, after = ch.factors, ch.after
        click.echo(f"chosen: {ch.kind}" + (f" strength {ch.strength:.5g}, bias "
                                            f"{100 * ch.bias:.3f}% (relative L2 change of E)"
                                            if ch.kind != "none" else
                                            " (already non-negative)"))
    else:
        kind, s = spec or ("hann", 0.0)  # 'none': strength 0 is no window
        f = window_factors(kind, lmax, s)
        after = min_irradiance(apply_window(coeffs, f))
        click.echo(f"window {kind} strength {s:g}, bias {100 * window_bias(coeffs, f):.3f}%")
    click.echo("factors: " + ", ".join(f"{x:.4f}" for x in f))
    show("after", after)
    if output:
        write_text(output, export_coeffs(apply_window(coeffs, f), "json", source=name),
                   overwrite=force)
        wrote(output, f"json, lmax {lmax}, windowed")

@click.command("export")
@source_options
@click.option("--lmax", default=_default("lmax", ExportSettings), show_default=True)
@click.option("--format", "fmt", type=click.Choice(FORMATS), required=True,
              help="glsl/hlsl/wgsl (E(n), eq. 11 and 13), json, three, gltf, cmgen, "
                   "cs-phase; each states its convention.")
@click.option("--window", "window", default=_default("window", ExportSettings),
              help=WINDOW_HELP)
@click.option("-o", "--output", type=click.Path(),
              help="Output file, or a folder for the name <source>-<edit>-lmax<N>.<ext> "
                   "(the viewer's download name; default: print).")
@force_option
def export_cmd(probe, layout, clamp, preset, coeffs_file, lmax, fmt, window, output, force):
    """Export lighting coefficients for shaders and engines (`--coeffs` reads every
    format back)."""
    from ..files import write_text
    from ..lighting.export import export_coeffs

    coeffs, name, _ = load_source(probe, preset, coeffs_file, layout, clamp, lmax)
    coeffs, wdesc = edit(coeffs, {"lmax": lmax, "window": window})
    text = export_coeffs(coeffs, fmt, source=name)
    if output:
        output = export_path(output, name, {"lmax": lmax, "window": window}, fmt)
        write_text(output, text, overwrite=force)
        wrote(output, fmt + (f"; {wdesc}" if wdesc else ""))
    else:
        click.echo(text, nl=False)


def register(group: click.Group) -> None:
    """Add render, basis-images, edit, window and export to the top-level group."""
    group.add_command(render_cmd)
    group.add_command(basis_cmd)
    group.add_command(edit_cmd)
    group.add_command(window_cmd)
    group.add_command(export_cmd)
