"""CLI commands: render, basis-images, edit, window, export (see ``shprobe.scene.render``,
``shprobe.lighting.design``, ``shprobe.lighting.export``)."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

import click

from ..errors import ShprobeError
from .common import (
    ROTATE_HELP,
    force_option,
    parse_exposure,
    parse_floats,
    parse_rotation,
    parse_size,
)
from .sources import coeff_source_options, resolve_coeffs

FORMATS = ("glsl", "hlsl", "wgsl", "json", "three", "gltf", "cmgen", "cs-phase")
WINDOW_HELP = ("Window the lighting: 'auto' (mildest window giving E >= 0), or KIND:STRENGTH "
               "with KIND one of hann, lanczos, gaussian, laplacian.")


# ----------------------------------------------------------------------------- helpers


def source_options(fn):
    """[PROBE] | --preset NAME | --coeffs FILE (+ --layout, --clamp): cli.sources."""
    return coeff_source_options(fn)


def load_source(probe, preset, coeffs_file, layout="auto", clamp=False, lmax=2,
                required=True) -> tuple[Any, str, Any]:
    """(coefficients (K, C), name, Env or None) from the source options
    (:func:`shprobe.cli.sources.resolve_coeffs`)."""
    if not required and not (probe or preset or coeffs_file):
        return None, "", None
    src = resolve_coeffs(probe, preset, coeffs_file, layout=layout, lmax=lmax, clamp=clamp)
    return src.coeffs, src.source, src.env


def parse_window(text: str | None):
    """None | 'auto' | (kind, strength)."""
    if not text:
        return None
    if text.strip().lower() == "auto":
        return "auto"
    kind, _, s = text.partition(":")
    from ..lighting.windows import WINDOWS

    if kind not in WINDOWS or not s:
        raise ShprobeError(f"window {text!r}: expected 'auto' or KIND:STRENGTH with KIND one "
                           f"of {', '.join(WINDOWS)}")
    return kind, parse_floats(s, 1, "window strength")[0]


def edit(coeffs, lmax: int, window: str | None = None, rotations=(), weight: float = 1.0,
         **edits):
    """:func:`shprobe.lighting.design.edit_lighting` with the CLI's rotation and window
    strings parsed; returns (coeffs, description of the window step or None)."""
    from ..lighting.design import Edits, edit_lighting

    res = edit_lighting(coeffs, Edits(rotations=[parse_rotation(r) for r in rotations],
                                      window=parse_window(window), **edits), lmax, weight)
    return res.coeffs, res.window


def camera_options(fn):
    opts = [
        click.option("--size", default="512x512", show_default=True, help="Image size WxH."),
        click.option("--azimuth", default=0.0, show_default=True,
                     help="Orbit angle about +Y in degrees (0: camera on +Z looking along -Z)."),
        click.option("--elevation", default=0.0, show_default=True,
                     help="Orbit elevation in degrees."),
        click.option("--fov", default=40.0, show_default=True,
                     help="Vertical field of view in degrees (perspective)."),
        click.option("--ortho", is_flag=True, help="Orthographic camera."),
        click.option("--mode", type=click.Choice(["pixel", "vertex"]), default="pixel",
                     show_default=True,
                     help="Shade per pixel, or per vertex and interpolate (R&H procedural)."),
    ]
    for o in reversed(opts):
        fn = o(fn)
    return fn


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


def _lm(text: str) -> tuple[int, int]:
    v = parse_floats(text, 2, "coefficient 'l,m'")
    return int(v[0]), int(v[1])


def _band(text: str) -> int:
    return int(parse_floats(text, 1, "band l")[0])


# ----------------------------------------------------------------------------- commands


def register(group: click.Group) -> None:
    """Add render, basis-images, edit, window and export to the top-level group."""

    @group.command("render")
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
        from ..scene.render import render

        t0 = time.perf_counter()
        check_image_output(output, force)
        stops = parse_exposure(exposure)  # a bad value is refused before the work
        if exr:
            check_image_output(exr, force)
        coeffs, name, env = load_source(probe, preset, coeffs_file, layout, clamp, lmax)
        coeffs, wdesc = edit(coeffs, lmax, window, rotate)
        geo = load_geometry(mesh, sphere)
        cam = make_camera(size, azimuth, elevation, fov, ortho)
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
        alb = parse_floats(albedo, 3, "albedo") if albedo else None
        res = render(geo, coeffs, cam, mode=mode, albedo=alb, background=bg)
        if stops is None:
            from ..probes.tonemap import auto_exposure

            stops = auto_exposure(res.image[res.mask] if res.mask.any() else res.image, 1.0)
            if output.lower().endswith((".png", ".jpg", ".jpeg")):
                click.echo(f"exposure {stops:+.2f} stops (auto)")
        from ..files import transaction

        with transaction():  # the image and its EXR: both or neither
            res.save(output, exposure=stops, overwrite=force)
            if exr:
                res.save(exr, overwrite=force)
        dt = time.perf_counter() - t0
        if wdesc:
            click.echo(wdesc)
        click.echo(f"{output}: {cam.width}x{cam.height} {mode} shading of "
                   f"{'sphere' if geo is None else os.path.basename(mesh)} under {name}, "
                   f"{100 * res.mask.mean():.1f}% object pixels, {dt:.2f} s")

    @group.command("basis-images")
    @click.argument("mesh", required=False, type=click.Path(dir_okay=False))
    @click.option("--sphere", is_flag=True, help="Use the unit sphere instead of a mesh.")
    @camera_options
    @click.option("--lmax", default=2, show_default=True)
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
        res = basis_images(geo, cam, lmax=lmax, mode=mode)
        B = res.image
        scale = float(np.abs(B).max())
        from ..files import transaction

        with transaction():  # every basis image and the sheet, or none of them
            tiles = []
            for k, stem in enumerate(stems):
                write_image(stem.with_suffix(".exr"), B[..., k], overwrite=force)
                vis = basis_visual(B[..., k], scale)
                write_image(stem.with_suffix(".png"), vis, overwrite=force)
                tiles.append(vis)
            # labelled pyramid sheet: band l on row l, centred; one colour bar, sign legend
            from ..probes.figures import Panel, write_figure

            rows = [[None] * (2 * lmax + 1) for _ in range(lmax + 1)]
            for k in range(len(stems)):
                l, m = sh_lm(k)
                rows[l][lmax + m] = Panel(B[..., k], f"(l, m) = ({l}, {m:+d})", "signed",
                                          units="Â_l y_lm(n) / π", scale=scale)
            write_figure(out / "basis.png", rows, overwrite=force, shared_colorbar=True,
                         title=f"irradiance basis images of "
                               f"{'the unit sphere' if geo is None else os.path.basename(mesh)} "
                               "(R&H 2001 Fig. 4): the object under L = e_lm",
                         display_width=min(B.shape[1], 192))
        click.echo(f"{out}: {B.shape[-1]} basis images (PNG + EXR) and basis.png; common "
                   f"scale {scale:.4g}")

    @group.command("edit")
    @source_options
    @click.option("--lmax", type=click.IntRange(0, 64), default=2, show_default=True,
                  help="Degree of the result (a probe is projected to it, at least 2; "
                       "presets and coefficient files are cut or zero-padded; edits above it "
                       "are refused).")
    @click.option("--blend", "blends", multiple=True,
                  help="Add another lighting FILE:WEIGHT (a probe image, projected, or "
                       "coefficients in any export format) or preset:NAME:WEIGHT. "
                       "Repeatable.")
    @click.option("--weight", default=1.0, show_default=True,
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
    @click.option("--window", "window", default=None, help=WINDOW_HELP)
    @click.option("--format", "fmt", type=click.Choice(FORMATS), default="json",
                  show_default=True, help="Output format (see `shprobe export`).")
    @click.option("-o", "--output", required=True, type=click.Path(dir_okay=False))
    @force_option
    def edit_cmd(probe, layout, clamp, preset, coeffs_file, lmax, blends, weight, directional,
                 cone, sky, sets, scales, negates, set_band, scale_band, negate_band,
                 rotations, window, fmt, output, force):
        """Lighting design (R&H 2001 §3.3): start from a source (or from darkness), then, in
        this order: blend, add lights, set/scale/negate coefficients and bands, rotate,
        window; write the coefficients."""

        from ..files import check_output_path, write_text
        from ..lighting.export import export_coeffs
        from ..probes.images import READ_EXTENSIONS
        from ..sh import lmax_of

        check_output_path(output, force)
        # a probe is projected to the result's degree (as a blended probe is), at least 2;
        # presets and coefficient files keep theirs (cut or zero-padded below)
        base, name, _ = load_source(probe, preset, coeffs_file, layout, clamp,
                                    max(lmax, 2) if probe else None, required=False)
        mixes = []
        for b in blends:
            head, _, w = b.rpartition(":")
            if not head:
                raise ShprobeError(f"--blend {b!r}: expected FILE:WEIGHT or preset:NAME:WEIGHT")
            if head.startswith("preset:"):
                c, _, _ = load_source(None, head[7:], None, lmax=None)
            elif Path(head).suffix.lower() in READ_EXTENSIONS:  # a probe image
                c, _, _ = load_source(head, None, None, layout, clamp, lmax)
            else:
                c, _, _ = load_source(None, None, head, lmax=None)
            mixes.append((c, parse_floats(w, 1, "blend weight")[0]))

        def colour(text: str, what: str):
            return parse_floats(text or "1", None, what)

        cones = []
        for c in cone:
            parts = c.split(":")
            if len(parts) != 3:
                raise ShprobeError(f"--cone {c!r}: expected DX,DY,DZ:APERTURE_DEG:R,G,B")
            cones.append((parse_floats(parts[0], 3, "cone direction"),
                           parse_floats(parts[1], 1, "aperture")[0], colour(parts[2], "colour")))
        sky_edit = None
        if sky:
            parts = sky.split(":")
            sky_edit = (colour(parts[0], "sky colour"),
                        colour(parts[1], "ground colour") if len(parts) > 1 else 0.0,
                        parse_floats(parts[2], 3, "up") if len(parts) > 2 else (0.0, 1.0, 0.0))

        def kv(text: str, what: str, value: str) -> tuple[Any, list[float]]:
            k, sep, v = text.partition("=")
            if not sep:
                raise ShprobeError(f"{what} {text!r}: expected KEY=VALUE")
            return k, parse_floats(v, None, value)

        L, wdesc = edit(base, lmax, window, rotations, weight=weight, blends=mixes,
                        directional=[(parse_floats(d.partition(":")[0], 3, "direction"),
                                      colour(d.partition(":")[2], "colour"))
                                     for d in directional],
                        cones=cones, sky=sky_edit,
                        sets=[(_lm(k), v) for k, v in (kv(s, "--set", "value") for s in sets)],
                        scales=[(_lm(k), v) for k, v in (kv(s, "--scale", "factor")
                                                          for s in scales)],
                        negates=[_lm(s) for s in negates],
                        set_bands=[(_band(k), v) for k, v in (kv(s, "--set-band", "value")
                                                              for s in set_band)],
                        scale_bands=[(_band(k), v) for k, v in (kv(s, "--scale-band", "factor")
                                                                for s in scale_band)],
                        negate_bands=list(negate_band))
        write_text(output, export_coeffs(L, fmt, source=name or "shprobe edit"),
                   overwrite=force)
        if wdesc:
            click.echo(wdesc)
        click.echo(f"{output}: {fmt}, lmax {lmax_of(L.shape[0])}, "
                   f"from {name or 'darkness'}")

    @group.command("window")
    @source_options
    @click.option("--lmax", default=2, show_default=True)
    @click.option("--window", "window", default="auto", show_default=True, help=WINDOW_HELP)
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
            kind, s = spec
            f = window_factors(kind, lmax, s)
            after = min_irradiance(apply_window(coeffs, f))
            click.echo(f"window {kind} strength {s:g}, bias {100 * window_bias(coeffs, f):.3f}%")
        click.echo("factors: " + ", ".join(f"{x:.4f}" for x in f))
        show("after", after)
        if output:
            write_text(output, export_coeffs(apply_window(coeffs, f), "json", source=name),
                       overwrite=force)

    @group.command("export")
    @source_options
    @click.option("--lmax", default=2, show_default=True)
    @click.option("--format", "fmt", type=click.Choice(FORMATS), required=True,
                  help="glsl/hlsl/wgsl (E(n), eq. 11 and 13), json, three, gltf, cmgen, "
                       "cs-phase; each states its convention.")
    @click.option("--window", "window", default=None, help=WINDOW_HELP)
    @click.option("-o", "--output", type=click.Path(dir_okay=False),
                  help="Output file (default: print).")
    @force_option
    def export_cmd(probe, layout, clamp, preset, coeffs_file, lmax, fmt, window, output, force):
        """Export lighting coefficients for shaders and engines (`--coeffs` reads every
        format back)."""
        from ..files import write_text
        from ..lighting.export import export_coeffs

        coeffs, name, _ = load_source(probe, preset, coeffs_file, layout, clamp, lmax)
        coeffs, wdesc = edit(coeffs, lmax, window)
        text = export_coeffs(coeffs, fmt, source=name)
        if output:
            write_text(output, text, overwrite=force)
            click.echo(f"{output}: {fmt}" + (f"; {wdesc}" if wdesc else ""))
        else:
            click.echo(text, nl=False)
