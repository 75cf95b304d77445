"""``shprobe fit``: SH lighting from photographs (a thin shell over
[`shprobe.fitting`][shprobe.fitting])."""

from __future__ import annotations

import click

from ..fitting.settings import FitSettings
from ..lighting.export import FORMATS as EXPORT_FORMATS
from .common import force_option, setting_default
from .output import progress, verbosity, wrote

FORMATS = ("table", "json", *(f for f in EXPORT_FORMATS if f != "json"))


def _outputs(f):
    for opt in reversed([
        click.option("--format", "-F", "fmt", type=click.Choice(FORMATS), default="table",
                     show_default=True, help="Coefficients as `shprobe prefilter` writes them "
                     "(json: its document plus a 'fit' object)."),
        click.option("--output", "-o", type=click.Path(dir_okay=False),
                     help="Write the coefficients to FILE instead of stdout."),
        click.option("--saturation", type=float,
                     default=setting_default(FitSettings, "saturation"),
                     help="Pixels with a channel >= this are clipped [default: 0.999 for "
                     "8/16-bit photos, none for HDR]."),
        click.option("--residual", type=click.Path(dir_okay=False),
                     help="Residual image photo - fit (.exr .pfm .tif; linear, signed)."),
        click.option("--fitted", type=click.Path(dir_okay=False),
                     help="Fitted radiance image (.exr .pfm .tif .png)."),
        click.option("--mask", type=click.Path(dir_okay=False),
                     help="Rejected-pixel mask (1 = clipped or rejected), e.g. .png."),
        click.option("--report", type=click.Path(dir_okay=False),
                     help="Labelled PNG panel: photo, fit, residual, rejected mask."),
        force_option,
    ]):
        f = opt(f)
    return f


def _ball_options(f):
    for opt in reversed([
        click.option("--circle", help="The ball's outline CX,CY,R in pixels from the image's "
                     "top-left corner (pixel centres at +0.5, y down) [default: detect]."),
        click.option("--camera", "camera_text", default="orthographic", show_default=True,
                     help="orthographic or perspective:FOV (vertical field of view of the "
                     "image, degrees)."),
    ]):
        f = opt(f)
    return f


def _read_photo(path: str):
    """The photo ([`shprobe.fitting.read_photo`][shprobe.fitting.read_photo]): LDR photos give one
    warning line, not a Python warning; an exposure shprobe recorded is undone (said by `_emit`)."""
    import warnings

    from ..fitting import read_photo
    from ..probes.images import LDRWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LDRWarning)
        photo = read_photo(path)
    if photo.ldr:
        click.echo(f"shprobe: warning: {path}: 8/16-bit photo decoded from sRGB; pixels at "
                   "the top code value are treated as clipped", err=True)
    return photo


def _start(photo: str, saturation, output, images: dict, report, force: bool):
    """Refuse outputs before the work, read the photo: (photo, image, saturation level)."""
    _check(output, {**images, "report": report}, force)
    ph = _read_photo(photo)
    return ph, ph.image, ph.saturation(saturation)


def _ball(circle, camera_text):
    from ..fitting import parse_ball_camera, parse_circle

    return (parse_circle(circle) if circle else None), parse_ball_camera(camera_text)


def _check(output, images: dict, force: bool) -> None:
    from ..files import check_output_path
    from ..probes.images import check_image_output

    if output:
        check_output_path(output, force)
    for p in images.values():
        if p:
            check_image_output(p, force)


def _emit(result, photo, source: str, fmt: str, output, images: dict, report, force: bool,
          title: str, ph=None) -> None:
    import json

    from ..files import transaction, write_text
    from ..fitting.report import fit_images, fit_table_rows, save_fit_figure
    from ..lighting.export import export_coeffs
    from ..probes.images import write_image

    if fmt == "table":
        text = _table_text(fit_table_rows(result))
    elif fmt == "json":
        text = json.dumps(result.as_dict(source, ph), indent=2) + "\n"
    else:
        text = export_coeffs(result.coeffs, fmt, source=source)
    written = []
    with transaction():  # the images, the report and the coefficients: all or none
        if any(images.values()):
            ims = fit_images(result)
            for name, p in images.items():
                if p and name in ims:
                    write_image(p, ims[name], overwrite=force)
                    written.append(p)
        if report:
            save_fit_figure(report, photo, result, title, overwrite=force)
            written.append(report)
        if output:
            write_text(output, text, force)
            written.insert(0, output)
    if not output:
        click.echo(text, nl=not text.endswith("\n"))
    if ph is not None and ph.exposure and not verbosity().quiet:
        click.echo(f"shprobe: {source}: the exposure {ph.exposure:+.3g} EV recorded in its "
                   "metadata was undone", err=True)
    if written:
        wrote(written, result.summary())
    elif not verbosity().quiet:  # the coefficients went to stdout: the fit's summary alone
        click.echo(f"shprobe: {result.summary()}", err=True)


def _fitting(what: str):
    """The fit's stage on the terminal reporter."""
    from ..progress import stage

    return stage(progress(), f"fitting the lighting to {what}")


def _table_text(rows) -> str:
    lines = [f"{'':6}{'R':>10}{'G':>10}{'B':>10}   {'± stderr (R G B)':>28}  {'cond':>7}"]
    for lab, v, e, cond, poor in rows:
        lines.append(f"{lab:6}" + "".join(f"{x:+10.4f}" for x in v) + "   "
                     + "".join(f"{x:9.2g}" for x in e) + f"  {cond:7.2f}"
                     + ("  poorly determined" if poor else ""))
    return "\n".join(lines) + "\n"



@click.group("fit")
def fit_group():
    """SH lighting (nine RGB coefficients L_lm) from photos of a grey ball, a chrome ball,
    or any diffuse object of known shape (R&H 2001 §2–3 run backwards)."""

@fit_group.command("grey-ball")
@click.argument("photo", type=click.Path(dir_okay=False))
@_ball_options
@click.option("--albedo", type=float, default=1.0, show_default=True,
              help="The ball's albedo x exposure (1: coefficients carry that scale).")
@click.option("--inset", type=float, default=1.0, show_default=True,
              help="Leave out pixels within this many px of the outline.")
@click.option("--irradiance", type=click.Path(dir_okay=False),
              help="Fitted irradiance E(n) on the ball (.exr .pfm .tif .png).")
@click.option("--no-robust", is_flag=True, help="Plain least squares (no IRLS).")
@_outputs
def grey_ball_cmd(photo, circle, camera_text, albedo, inset, irradiance, no_robust, fmt,
                  output, saturation, residual, fitted, mask, report, force):
    """Lighting from a photo of a diffuse (grey) ball."""
    from ..fitting import FitSettings, fit_grey_ball

    images = {"residual": residual, "fitted": fitted, "rejected": mask,
              "irradiance": irradiance}
    c, cam = _ball(circle, camera_text)
    ph, img, sat = _start(photo, saturation, output, images, report, force)
    with _fitting("the grey ball"):
        res = fit_grey_ball(img, c, cam, FitSettings(saturation=sat, robust=not no_robust),
                            albedo=albedo, inset=inset, path=photo)
    _emit(res, img, photo, fmt, output, images, report, force, f"grey ball: {photo}", ph)

@fit_group.command("chrome-ball")
@click.argument("photo", type=click.Path(dir_okay=False))
@_ball_options
@click.option("--reflectance", type=float, default=1.0, show_default=True,
              help="The mirror's reflectance x exposure.")
@click.option("--inset", type=float, default=0.5, show_default=True,
              help="Leave out pixels within this many px of the outline (the blind spot "
              "behind the ball grows with it).")
@_outputs
def chrome_ball_cmd(photo, circle, camera_text, reflectance, inset, fmt, output,
                    saturation, residual, fitted, mask, report, force):
    """Lighting from a photo of a mirror (chrome) ball."""
    from ..fitting import fit_chrome_ball

    images = {"residual": residual, "fitted": fitted, "rejected": mask}
    c, cam = _ball(circle, camera_text)
    ph, img, sat = _start(photo, saturation, output, images, report, force)
    with _fitting("the chrome ball"):
        res = fit_chrome_ball(img, c, cam, reflectance=reflectance, saturation=sat,
                              inset=inset, path=photo)
    _emit(res, img, photo, fmt, output, images, report, force, f"chrome ball: {photo}", ph)

@fit_group.command("normals")
@click.argument("photo", type=click.Path(dir_okay=False))
@click.argument("normal_map", type=click.Path(dir_okay=False))
@click.option("--albedo", type=float, default=1.0, show_default=True)
@click.option("--irradiance", type=click.Path(dir_okay=False),
              help="Fitted irradiance E(n) image.")
@click.option("--no-robust", is_flag=True, help="Plain least squares (no IRLS).")
@_outputs
def normals_cmd(photo, normal_map, albedo, irradiance, no_robust, fmt, output, saturation,
                residual, fitted, mask, report, force):
    """Lighting from a photo and a per-pixel normal map (float image, e.g. .exr, holding
    unit normals in the lighting's frame; zero = background)."""
    from ..fitting import fit_normals, read_normal_map

    images = {"residual": residual, "fitted": fitted, "rejected": mask,
              "irradiance": irradiance}
    ph, img, sat = _start(photo, saturation, output, images, report, force)
    nrm = read_normal_map(normal_map)
    if nrm.shape[:2] != img.shape[:2]:
        from ..errors import ShprobeError

        raise ShprobeError(f"normal map is {nrm.shape[1]}x{nrm.shape[0]} but the photo is "
                           f"{img.shape[1]}x{img.shape[0]}", normal_map)
    with _fitting("the normal map's pixels"):
        res = fit_normals(img, nrm, albedo=albedo, saturation=sat, robust=not no_robust)
    _emit(res, img, photo, fmt, output, images, report, force, f"normal map: {photo}", ph)

@fit_group.command("mesh")
@click.argument("photo", type=click.Path(dir_okay=False))
@click.argument("mesh", type=click.Path(dir_okay=False))
@click.option("--projection", type=click.Choice(("perspective", "orthographic")),
              default="perspective", show_default=True)
@click.option("--fov", type=float, default=40.0, show_default=True,
              help="Vertical field of view, degrees.")
@click.option("--azimuth", type=float, default=0.0, show_default=True)
@click.option("--elevation", type=float, default=0.0, show_default=True)
@click.option("--distance", type=float, help="Camera distance [default: framing fit].")
@click.option("--margin", type=float, default=1.1, show_default=True)
@click.option("--albedo", type=float, default=1.0, show_default=True)
@click.option("--irradiance", type=click.Path(dir_okay=False),
              help="Fitted irradiance E(n) image.")
@click.option("--no-robust", is_flag=True, help="Plain least squares (no IRLS).")
@_outputs
def mesh_cmd(photo, mesh, projection, fov, azimuth, elevation, distance, margin, albedo,
             irradiance, no_robust, fmt, output, saturation, residual, fitted, mask,
             report, force):
    """Lighting from a photo of a diffuse mesh seen by the renderer's camera (`shprobe
    render` options: the photo's size is the camera's)."""
    from ..fitting import fit_mesh
    from ..scene import Camera, load_mesh

    images = {"residual": residual, "fitted": fitted, "rejected": mask,
              "irradiance": irradiance}
    ph, img, sat = _start(photo, saturation, output, images, report, force)
    m = load_mesh(mesh)
    cam = Camera(img.shape[1], img.shape[0], projection, azimuth, elevation, fov,
                 distance, None, margin)
    with _fitting(f"the {len(m.vertices):,}-vertex mesh"):
        res = fit_mesh(img, m, cam, albedo=albedo, saturation=sat, robust=not no_robust)
    _emit(res, img, photo, fmt, output, images, report, force, f"mesh {mesh}: {photo}", ph)


def register(group: click.Group) -> None:
    """Add the ``fit`` group."""
    group.add_command(fit_group)
