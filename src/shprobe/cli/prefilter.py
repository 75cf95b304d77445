"""CLI commands of the main job (R&H 2001): ``prefilter``, ``irradiance``, ``error``, ``demo``."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import ShprobeError
from ..lighting.export import FORMATS as EXPORT_FORMATS
from ..lighting.workflow import (
    IRRADIANCE_METHODS,
    OUT_LAYOUTS,
    IrradianceSettings,
    PrefilterSettings,
)
from .common import force_option, parse_exposure, setting_default
from .output import detail, estimate, progress, wrote
from .sources import coeff_source_options, resolve_coeffs

#: --format choices of `shprobe prefilter` (all but table/json go to shprobe.lighting.export).
FORMATS = ("table", "json", *(f for f in EXPORT_FORMATS if f != "json"))


def coeff_table(coeffs, title: str | None = None):
    """A rich table of (K, 3) coefficients laid out as R&H Fig. 2 (rows L_lm, columns R G B)."""
    from rich.table import Table

    from ..sh import lmax_of

    t = Table()
    t.add_column("", style="bold")
    for ch in ("R", "G", "B"):
        t.add_column(ch, justify="right")
    lmax = lmax_of(coeffs.shape[0])
    k = 0
    for l in range(lmax + 1):
        for m in range(-l, l + 1):
            t.add_row(f"L{l}{m}", *(f"{v:+.4f}" for v in coeffs[k]))
            k += 1
    return _titled(t, title)


def coeff_text(coeffs) -> str:
    """Plain-text version of `coeff_table`."""
    from ..sh import lmax_of

    lines = [f"{'':6}{'R':>10}{'G':>10}{'B':>10}"]
    k = 0
    for l in range(lmax_of(coeffs.shape[0]) + 1):
        for m in range(-l, l + 1):
            lines.append(f"{f'L{l}{m}':6}" + "".join(f"{v:+10.4f}" for v in coeffs[k]))
            k += 1
    return "\n".join(lines) + "\n"


def error_table(report, title: str | None = None):
    """A rich table of an [`ErrorReport`][shprobe.lighting.ErrorReport]."""
    from rich.table import Table

    from ..report.probe import error_note

    t = Table()
    refined = getattr(report, "refined", False)
    names = ["lmax", "mean |ΔE| / ∫L", "max |ΔE| / ∫L", "mean rel.", "sMAPE", "note"]
    if refined:
        names = ["lmax", "mean |ΔE|/∫L", "max |ΔE|/∫L", "worst normal", "mean rel.", "sMAPE",
                 "note"]
    for name in names:
        t.add_column(name, justify="left" if name == "note" else "right",
                     no_wrap=name == "worst normal")
    for r in report.rows:
        cells = [str(r.lmax), f"{100 * r.mean_frac:.3f} %", f"{100 * r.max_frac:.3f} %",
                 f"{100 * r.mean_rel:.3f} %", f"{100 * r.smape:.3f} %", error_note(r.lmax)]
        if refined:
            cells.insert(3, " ".join(f"{x:+.2f}" for x in r.max_normal) + " "
                         + "RGB"[r.max_channel])
        t.add_row(*cells)
    if refined and report.rows:
        import math

        mc = max(r.mean_change for r in report.rows)
        loose = [str(r.lmax) for r in report.rows if r.max_change >= r.max_tol]
        t.caption = (f"max: refined on the sphere, ± {100 * report.rows[0].max_tol:.3g} pp "
                     "(stated tolerance)" + ("" if math.isnan(mc) else
                                             f"; mean: |mean(N) − mean(N/2)| ≤ "
                                             f"{100 * mc:.3g} pp")
                     + ("" if not loose else f"; NOT converged to it for lmax "
                        f"{', '.join(loose)} (see max_change in -F json)"))
    return _titled(t, title)



def _titled(table, title: str | None):
    from rich.console import Group
    from rich.text import Text

    return table if not title else Group(Text(title, style="bold"), table)


def error_document(report, source: str | None) -> dict:
    """JSON form of an error report: the library's one document
    ([`shprobe.lighting.reference.ErrorReport.as_dict`][shprobe.lighting.ErrorReport.as_dict])."""
    return report.as_dict(source)


def _grid_size(text: str | None, layout: str) -> int | tuple[int, int]:
    """--size (the one grammar, `shprobe.cli.common.parse_size`) → the layout's size
    argument; defaults 256x128 (lat-long), 64 (cube face), 256 (discs)."""
    from .common import parse_size

    if text is None:
        return {"latlong": (256, 128), "cube": 64}.get(layout, 256)
    w, h = parse_size(text, layout)
    return (w, h) if layout == "latlong" else w



@click.command("prefilter")
@coeff_source_options
@click.option("--lmax", "-n", type=click.IntRange(0, 64),
              default=setting_default(PrefilterSettings, "lmax"), show_default=True,
              help="Highest SH degree l.")
@click.option("--format", "-F", "fmt", type=click.Choice(FORMATS), default="table",
              show_default=True, help="Output: R&H Fig. 2 table, JSON, or a shader/engine "
              "format (shprobe.lighting.export).")
@click.option("--output", "-o", type=click.Path(dir_okay=False),
              help="Write to FILE instead of stdout.")
@force_option
def prefilter_cmd(probe, layout, clamp, preset, coeffs_file, lmax, fmt, output, force):
    """Prefilter a light probe into SH lighting coefficients L_lm (R&H 2001 eq. 10).

    PROBE is an environment map (.hdr .exr .pfm .tif .png .jpg) in any layout; --preset
    or --coeffs give coefficients without an image.
    """
    import json

    from ..files import check_output_path, write_text
    from ..lighting.workflow import lighting_document

    if output:
        check_output_path(output, force)  # refuse before the work
    src = resolve_coeffs(probe, preset, coeffs_file, layout, lmax, clamp)
    if fmt == "table":
        if output:
            write_text(output, coeff_text(src.coeffs), force)
            wrote(output, f"table, lmax {lmax}")
        else:
            from .common import console

            title = f"{src.source}  (layout {src.layout})" if src.layout else src.source
            console().print(coeff_table(src.coeffs, title))
        return
    if fmt == "json":
        text = json.dumps(lighting_document(src), indent=2) + "\n"
    else:
        from ..lighting.export import export_coeffs

        text = export_coeffs(src.coeffs, fmt, source=src.source)
    if output:
        write_text(output, text, force)
        wrote(output, f"{fmt}, lmax {lmax}")
    else:
        click.echo(text, nl=not text.endswith("\n"))

@click.command("irradiance")
@coeff_source_options
@click.option("--output", "-o", required=True, type=click.Path(dir_okay=False),
              help="Irradiance map to write (.exr .hdr .pfm .tif, or tone-mapped .png).")
@click.option("--out-layout", type=click.Choice(OUT_LAYOUTS),
              default=setting_default(IrradianceSettings, "out_layout"),
              show_default=True, help="Layout of the map (same: the probe's; lat-long for "
              "presets). 'angular' gives the view of R&H Fig. 3.")
@click.option("--size", help="WxH, or N: NxN/2 for lat-long, NxN for angular, mirror ball "
              "and cube faces (the size of one face). Default 256x128 / 256 / 64.")
@click.option("--lmax", "-n", type=click.IntRange(0, 64),
              default=setting_default(PrefilterSettings, "lmax"), show_default=True)
@click.option("--method", type=click.Choice(IRRADIANCE_METHODS),
              default=setting_default(IrradianceSettings, "method"),
              show_default=True, help="sh: eq. 7 from L_lm; brute: the hemispherical "
              "integral per pixel (slow, exact).")
@click.option("--exposure", default="auto", show_default=True, metavar="auto|STOPS",
              help="PNG only: exposure in stops; auto maps the 99th percentile of the "
              "largest channel to white (at most 1 % of the pixels clip). The PNG shows "
              "E/π, the radiance a white diffuse surface reflects; linear files hold E.")
@force_option
def irradiance_cmd(probe, layout, clamp, preset, coeffs_file, output, out_layout, size,
                   lmax, method, exposure, force):
    """Write an irradiance environment map E(n) (R&H 2001 §3.1).

    Linear files (.exr .hdr .pfm .tif) hold E; a .png shows E/π (the radiance a white
    diffuse surface reflects), tone-mapped at --exposure (auto by default, printed)."""
    from dataclasses import replace

    from ..lighting.workflow import IrradianceSettings, irradiance_map_cost, write_irradiance_map
    from ..probes.images import check_image_output
    from .output import limits

    check_image_output(output, force)
    settings = IrradianceSettings(method=method, out_layout=out_layout,
                                  exposure=parse_exposure(exposure),  # refused before the work
                                  limits=limits())
    src = resolve_coeffs(probe, preset, coeffs_file, layout, lmax, clamp,
                         need_env=(method == "brute"))
    if size is not None:
        settings = replace(settings, size=_grid_size(size, settings.layout_for(src)[0].name))
    cost = irradiance_map_cost(src, settings)
    if cost is not None:
        lay, sz = settings.layout_for(src)
        estimate(cost, f"the brute-force irradiance map "
                       f"{'x'.join(map(str, lay.grid_shape(sz)[::-1]))}")
    res = write_irradiance_map(src, output, settings, progress(), overwrite=force)
    note = ""
    if Path(output).suffix.lower() == ".png":
        note = (f", E/π at exposure {res.exposure:+.1f} EV"
                f"{' (auto)' if res.auto_exposure else ''}")
    wrote(output, f"{res.layout} {'x'.join(map(str, res.grid[::-1]))}, "
                  f"{method}, lmax {lmax}{note}")


@click.command("error")
@coeff_source_options
@click.option("--lmax-max", type=click.IntRange(0, 32), default=4, show_default=True,
              help="Report lmax = 1 .. this value.")
@click.option("--normals", "grid_h", type=click.IntRange(2, 512), default=32,
              show_default=True, help="Normals: the centres of a 2N×N lat-long grid (the "
              "mean's quadrature; the max is refined on the sphere from them).")
@click.option("--tol", type=float, default=None, metavar="FRACTION",
              help="Stated tolerance of the max, as a fraction of ∫L dω; the refinement "
              "stops when a level moves the max by less. Default: the library's, 1e-5 "
              "(0.001 percentage points).")
@click.option("--format", "-F", "fmt", type=click.Choice(("table", "json")),
              default="table", show_default=True)
def error_cmd(probe, layout, clamp, preset, coeffs_file, lmax_max, grid_h, tol, fmt):
    """Error of the SH irradiance against the exact hemispherical integral, as a fraction
    of the total intensity ∫L dω (R&H 2001 §3.1)."""
    import json

    from ..lighting.reference import error_report, reference_cost

    src = resolve_coeffs(probe, preset, coeffs_file, layout, 0, clamp, need_env=True)
    if src.env.layout.name != "latlong":  # lat-long maps: row sums, milliseconds
        estimate(reference_cost(src.env, 2 * grid_h * grid_h),
                 f"the exact irradiance at {2 * grid_h * grid_h} normals")
    # lat-long: row sums, milliseconds; other layouts: the brute-force stage, counted
    rep = error_report(src.env, tuple(range(min(1, lmax_max), lmax_max + 1)),
                       normal_grid=grid_h, progress=progress(),
                       **({} if tol is None else {"tol": tol}))
    if fmt == "json":
        click.echo(json.dumps(error_document(rep, src.source), indent=2))
    else:
        from .common import console

        console().print(error_table(rep, f"{src.source}: SH irradiance vs brute force, "
                                          f"mean over {rep.n_normals} normals, max refined "
                                          "on the sphere"))

@click.command("demo")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="shprobe-demo",
              show_default=True, help="Folder for the pictures (created if missing).")
@click.option("--size", default="256x128", show_default=True,
              help="Size WxH (or N for NxN/2) of the procedural lat-long environment.")
@click.option("--exposure", default="auto", show_default=True, metavar="auto|STOPS",
              help="Exposure of the PNGs in stops; auto maps the 99th percentile of the "
              "largest channel of the sky and E/π together to white.")
@click.option("--table", "show_table", is_flag=True,
              help="Also print the coefficient and error tables (the error table is "
              "always in the closing line's summary).")
@force_option
def demo_cmd(out_dir, size, exposure, show_table, force):
    """The main job with no files: a procedural sky → SH coefficients → irradiance map,
    a labelled side-by-side picture and the error against the exact integral. The PNGs
    show E/π (the radiance a white diffuse surface reflects) at the sky's exposure, so
    the two compare."""
    import numpy as np

    from ..files import check_output_path, write_json
    from ..lighting.document import coeffs_document
    from ..lighting.irradiance import irradiance_map
    from ..lighting.projection import project
    from ..lighting.reference import error_report
    from ..probes.environments import procedural_env
    from ..probes.figures import Panel, exposure_for, figure
    from ..probes.images import write_image
    from ..progress import Steps

    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ShprobeError("exists and is not a folder", out)
    names = ["probe.exr", "irradiance.exr", "irradiance.png", "side_by_side.png",
             "coefficients.json"]
    for n in names:  # refuse before writing anything
        check_output_path(out / n, force)
    fixed = parse_exposure(exposure)
    w, h = _grid_size(size, "latlong")
    with Steps(progress(), 4) as step:
        step("the procedural sky and its SH coefficients (R&H eq. 10)")
        env = procedural_env(w, h)
        coeffs = project(env, 2)
        step("its irradiance map (R&H eq. 7)")
        emap = irradiance_map(coeffs, "latlong", (w, h))
        shown = emap.radiance / np.pi
        stops = (exposure_for(np.concatenate([env.radiance, shown], axis=1))
                 if fixed is None else fixed)
        side = figure([Panel(env.radiance, "procedural sky: radiance L",
                             units="relative radiance", exposure=stops),
                       Panel(shown, "irradiance E/π (SH, lmax 2)",
                             units="white diffuse radiance", exposure=stops)],
                      title="probe | its SH irradiance map (lat-long, +Y up)")
        bar = step(f"writing {len(names)} files", total=len(names))
        from ..files import transaction

        with transaction():  # the five files together or none
            write_image(out / "probe.exr", env.radiance, overwrite=force)
            write_image(out / "irradiance.exr", emap.radiance, overwrite=force)
            write_image(out / "irradiance.png", shown, overwrite=force, exposure=stops)
            bar.set(3)
            side.save(out / "side_by_side.png", overwrite=force)
            write_json(out / "coefficients.json",
                       coeffs_document(coeffs, "procedural", "latlong"), overwrite=force)
            bar.set(5)
        step("the error against the exact irradiance (R&H §3.1)")
        rep = error_report(env)
    if show_table:
        from .common import console

        con = console()
        con.print(coeff_table(coeffs, "procedural sky: lighting coefficients L_lm "
                                      "(R&H 2001 Fig. 2 layout)"))
        con.print(error_table(rep, "error vs brute force (fraction of ∫L dω)"))
    detail("the .pngs show E/π, the radiance of a white diffuse surface, at the sky's "
           "exposure")
    e2 = rep.row(2)
    wrote([out / n for n in names],
          f"E/π at exposure {stops:+.1f} EV{' (auto)' if fixed is None else ''}; lmax 2 "
          f"error {100 * e2.mean_frac:.2g} % mean, {100 * e2.max_frac:.2g} % max of ∫L dω")


def register(group: click.Group) -> None:
    """Add ``prefilter``, ``irradiance``, ``error`` and ``demo`` to the top-level group."""
    group.add_command(prefilter_cmd)
    group.add_command(irradiance_cmd)
    group.add_command(error_cmd)
    group.add_command(demo_cmd)
