"""The probe report: one self-contained HTML page (every image inlined as a data: URL, no
script, no network) with

- the probe (tone-mapped, lat-long view) and its total intensity ∫L dω;
- its irradiance map E/π from the 9 coefficients (R&H 2001 eq. 7) beside the exact one (the
  hemispherical integral, `shprobe.lighting.reference.reference_irradiance_map`) and
  the map of their difference as a fraction of ∫L dω, with the error table (R&H §3.1) for
  lmax 1..4 on the same normals;
- the coefficient table in the layout of R&H Fig. 2 and the matrices M of eq. 11–12;
- the non-negativity certificate of E
  ([`shprobe.lighting.windows.min_irradiance`][shprobe.lighting.min_irradiance]) and the window
  ``auto`` chooses ([`shprobe.lighting.windows.auto_window`][shprobe.lighting.auto_window]);
- the nine irradiance basis images of a mesh (R&H Fig. 4) and a render of it under the probe
  (beside one with the auto window when E goes negative).

Every picture is a labelled figure (`shprobe.probes.figures`).
"""

from __future__ import annotations

import base64
import html
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..probes.env import Env
from ..probes.figures import Figure, Panel, exposure_for, figure
from ..probes.layouts import LatLong
from ..progress import Progress, Steps

#: The page loads nothing: only inline styles and data: images (a browser enforces it).
_CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'"

#: Largest render side the report accepts (a refusal, not an allocation, above it).
MAX_RENDER = 2048


@dataclass
class ProbeReport:
    """The page (``html``) and what it shows.

    Attributes
    ----------
    html
        The self-contained page.
    source
        The probe's name.
    coeffs
        (K, 3) its lighting coefficients.
    errors
        The error table ([`ErrorReport`][shprobe.lighting.ErrorReport]).
    minimum
        The certified minimum irradiance.
    window
        The window ``auto`` picks.
    figures
        The page's figures by name.
    """

    html: str
    source: str
    coeffs: NDArray[np.float64]
    errors: Any  # shprobe.lighting.reference.ErrorReport
    minimum: Any  # shprobe.lighting.windows.IrradianceMinimum
    window: Any  # shprobe.lighting.windows.WindowChoice
    figures: dict[str, Figure] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """A JSON-able summary of the report (not its page): the source, the coefficients,
        the error report's document, the non-negativity certificate and the window.

        Returns
        -------
        dict
            source, coeffs, errors, nonnegative, window, figures (their names), html_bytes.
        """
        return {"source": self.source, "coeffs": np.asarray(self.coeffs, float).tolist(),
                "errors": self.errors.as_dict(self.source),
                "nonnegative": bool(getattr(self.minimum, "nonnegative", False)),
                "window": str(getattr(self.window, "kind", None)),
                "figures": list(self.figures), "html_bytes": len(self.html.encode())}

    def __repr__(self) -> str:
        return (f"ProbeReport({self.source!r}, {len(self.figures)} figures, "
                f"{len(self.html) / 1024:.0f} KiB, window {self.window.kind})")


def _latlong_view(env: Env, width: int = 512) -> NDArray[np.float32]:
    """The probe as a lat-long image (resampled when it is in another layout)."""
    if env.layout.name == "latlong" and env.grid[1] <= width:
        return env.radiance
    w = min(width, env.grid[-1] * 2)
    dirs = LatLong().pixel_directions((w // 2, w))
    return env.sample(dirs)


def error_note(lmax: int) -> str:
    """The note of an error-table row that repeats the one above: Â_l = 0 for odd l > 1
    (R&H eq. 9), so degree l adds nothing to the irradiance and lmax = l equals lmax = l − 1
    (used by this page and by ``shprobe error``)."""
    if lmax >= 3 and lmax % 2 == 1:
        return f"= lmax {lmax - 1} (Â_{lmax} = 0)"
    return ""


def _img(fig: Figure, alt: str) -> str:
    data = base64.b64encode(fig.png_bytes()).decode("ascii")
    h, w = fig.pixels.shape[:2]
    return (f'<img alt="{html.escape(alt)}" width="{w}" height="{h}" '
            f'src="data:image/png;base64,{data}">')


def _table(header: list[str], rows: list[list[str]], cls: str = "") -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>"
                   for r in rows)
    c = f' class="{cls}"' if cls else ""
    return f"<table{c}><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _vec(v) -> str:
    return "(" + ", ".join(f"{x:.4g}" for x in np.asarray(v, dtype=float).ravel()) + ")"


#: Radiance the report analyses: ∫L dω of the brightest channel within these bounds. Outside,
#: the exposure of its pictures (2^stops) and the certificate's products leave the float range.
INTEGRAL_RANGE = (1e-30, 1e30)


def _check_probe(env: Env, map_height: int) -> None:
    """Refuse, before any work, a probe the report cannot analyse: radiance too small or too
    large for its pictures, or an exact irradiance map beyond the brute-force limit."""
    from ..lighting.projection import total_intensity
    from ..lighting.reference import check_env

    check_env(env, "the probe")
    top = float(np.max(total_intensity(env)))
    if not INTEGRAL_RANGE[0] <= top <= INTEGRAL_RANGE[1]:
        raise ShprobeError(f"its radiance integrates to {top:.3g} (brightest channel), outside "
                           f"the {INTEGRAL_RANGE[0]:g}..{INTEGRAL_RANGE[1]:g} a report "
                           "analyses: scale its pixel values",
                           env.path)
    check_map_cost(float(np.prod(env.grid, dtype=np.float64)), map_height, env.path)


def check_map_cost(pixels: float, map_height: int, where: Any = None) -> None:
    """Refuse an exact irradiance map of 2N² normals (N = ``map_height``) over a probe of
    ``pixels`` pixels beyond the brute-force limit
    ([`shprobe.limits.check_pairs`][shprobe.limits.check_pairs]); the CLI calls it with the size in
    the file's header, before the probe is read."""
    from ..lighting.reference import SAMPLE_COST
    from ..limits import check_pairs

    check_pairs(float(pixels) * (2.0 * map_height * map_height + SAMPLE_COST),
                f"the exact irradiance map at --map-size {map_height}", where,
                "use a smaller --map-size or a smaller probe")


@dataclass(frozen=True)
class ReportSettings:
    """Settings of a probe report ([`probe_report`][shprobe.report.probe_report]); the defaults are
    ``shprobe report``'s.

    Parameters
    ----------
    map_height
        Rows N of the lat-long irradiance maps (2N × N normals; the exact map and the error
        table use the same normals), 2..256.
    render_size
        Side of the basis images and the render, pixels (16..MAX_RENDER).
    """

    map_height: int = 32
    render_size: int = 256

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values.

        Returns
        -------
        dict
            map_height, render_size.
        """
        return {"map_height": self.map_height, "render_size": self.render_size}


def probe_report(env: Env, mesh: Any = None, mesh_name: str | None = None,
                 settings: ReportSettings | None = None, progress: Progress | None = None,
                 **changes: Any) -> ProbeReport:
    """Build the report of ``env``.

    Parameters
    ----------
    env
        The probe.
    mesh
        A trimesh mesh for the basis images and the render (None: the unit sphere).
    mesh_name
        Its name on the page.
    settings
        The report's [`ReportSettings`][shprobe.report.ReportSettings] (default: its defaults).
    progress
        Gets the job's `REPORT_STAGES` stages "k/N: …" (the brute-force integral
        counted inside its stage).
    **changes
        Fields of [`ReportSettings`][shprobe.report.ReportSettings] changed from ``settings``
        (``map_height=16``).

    Returns
    -------
    ProbeReport
        The page and what it shows (``as_dict()`` summarises it).
    """
    s = settings if settings is not None else ReportSettings()
    if changes:
        s = replace(s, **changes)
    map_height, render_size = s.map_height, s.render_size
    h = int(map_height)
    if not 2 <= h <= 256:  # the brute-force integral is 2N² normals × every probe pixel
        raise ShprobeError(f"map height {h} must be 2..256")
    r = int(render_size)
    if not 16 <= r <= MAX_RENDER:
        raise ShprobeError(f"render size {r} must be 16..{MAX_RENDER}")
    _check_probe(env, h)
    with Steps(progress, REPORT_STAGES) as say:
        return _build(env, mesh, mesh_name, h, r, say, progress)


#: The stages of :func:`probe_report` (what ``progress`` is told).
REPORT_STAGES = 7


def _build(env: Env, mesh: Any, mesh_name: str | None, h: int, r: int, say: Steps,
           progress: Progress | None) -> ProbeReport:
    """[`probe_report`][shprobe.report.probe_report]'s work, one stage after the other."""
    from .._version import __version__
    from ..lighting.irradiance import irradiance_map, irradiance_matrix
    from ..lighting.projection import project, total_intensity
    from ..lighting.reference import error_report, reference_irradiance_map
    from ..lighting.windows import auto_window, min_irradiance
    from ..scene import Camera, basis_images, render
    from ..sh import sh_lm

    source = os.path.basename(env.path) if env.path else "environment"
    obj = mesh_name or ("the unit sphere" if mesh is None else "the mesh")
    figs: dict[str, Figure] = {}

    say("projecting")
    L = project(env, 2)
    tot = total_intensity(env)
    view = _latlong_view(env)
    e_probe = exposure_for(view)
    figs["probe"] = figure([Panel(view, f"{source} ({env.layout.name} "
                                  f"{'x'.join(map(str, env.grid[::-1]))})",
                                  units="radiance L (relative)", exposure=e_probe),
                            Panel(view, "the same, +4 EV (the shadows)",
                                  units="radiance L (relative)", exposure=e_probe + 4.0)],
                           display_width=min(512, max(256, view.shape[1])))

    say(f"exact irradiance map {2 * h}x{h}")
    ref = reference_irradiance_map(env, "latlong", (2 * h, h), progress=progress)
    say("error table")
    rep = error_report(env, (1, 2, 3, 4), reference=ref.radiance.reshape(-1, 3),
                       normal_grid=h)
    sh = irradiance_map(L, "latlong", (2 * h, h))
    e_sh, e_ref = sh.radiance / np.pi, ref.radiance / np.pi
    e_irr = exposure_for(np.concatenate([e_sh, e_ref], axis=1))
    err = (np.abs(sh.radiance - ref.radiance) / tot).max(axis=-1) * 100.0
    figs["irradiance"] = figure(
        [Panel(e_sh, "E/π from 9 coefficients (eq. 7)", units="white diffuse radiance",
               exposure=e_irr),
         Panel(e_ref, "E/π exact (hemisphere integral)", units="white diffuse radiance",
               exposure=e_irr),
         Panel(err, "|E_SH − E_exact| / ∫L dω", "error", units="% (max over R, G, B)")],
        display_width=256)

    say("certificate and window")
    M = irradiance_matrix(L)
    mn = min_irradiance(L)
    win = auto_window(L)

    say(f"basis images of {obj}")
    cam = Camera(r, r)
    B = basis_images(mesh, cam, lmax=2).image
    scale = float(np.abs(B).max()) or 1.0
    rows: list[list[Panel | None]] = [[None] * 5 for _ in range(3)]
    for k in range(9):
        l, m = sh_lm(k)
        rows[l][2 + m] = Panel(B[..., k], f"(l, m) = ({l}, {m:+d})", "signed",
                               units="Â_l y_lm(n) / π", scale=scale)
    figs["basis"] = figure(rows, shared_colorbar=True, display_width=min(r, 160),
                           title=f"irradiance basis images of {obj} (R&H Fig. 4)")
    say(f"render of {obj}")
    res = render(mesh, L, cam, background=None)
    e_obj = exposure_for(res.image[res.mask]) if res.mask.any() else exposure_for(res.image)
    shots = [Panel(res.image, f"{obj} under {source} (9 coefficients)",
                   units="radiance ρE/π", exposure=e_obj)]
    if win.kind != "none":  # the ringing next to its cure, at one exposure
        from ..lighting.windows import apply_window

        fixed = render(mesh, apply_window(L, win.factors), cam, background=None)
        shots.append(Panel(fixed.image, f"with the {win.kind} window (auto)",
                           units="radiance ρE/π", exposure=e_obj))
    figs["render"] = figure(shots, display_width=max(288, min(r, 384)))

    say("building the page")
    coeff_rows = []
    k = 0
    for l in range(3):
        for m in range(-l, l + 1):
            coeff_rows.append([f"L{l}{m}", *(f"{v:+.4f}" for v in L[k])])
            k += 1
    err_rows = []
    for row in rep.rows:
        note = error_note(row.lmax)
        err_rows.append([str(row.lmax), f"{100 * row.mean_frac:.3f} %",
                         f"{100 * row.max_frac:.3f} %", f"{100 * row.mean_rel:.3f} %",
                         f"{100 * row.smape:.3f} %", note])
    m_tables = "".join(
        f"<div class='m'><h3>M<sub>{ch}</sub></h3>"
        + _table(["", "x", "y", "z", "1"],
                 [[lab, *(f"{v:+.4f}" for v in M[c, i])]
                  for i, lab in enumerate(("x", "y", "z", "1"))]) + "</div>"
        for c, ch in enumerate("RGB"))
    cert = _table(["", "R", "G", "B"], [
        ["min E over the sphere", *(f"{v:.4g}" for v in mn.minimum)],
        ["proven lower bound", *(f"{v:.4g}" if np.isfinite(v) else "—" for v in mn.lower_bound)],
        ["attained at n", *(_vec(d) for d in mn.direction)],
    ])
    verdict = ("E ≥ 0 everywhere: " + ("certified" if mn.exact else "numerical search")
               if mn.nonnegative else "E < 0 somewhere: the lighting needs a window")
    if win.kind == "none":
        wtext = "none needed (E is already non-negative)"
    else:
        wtext = (f"{win.kind}, strength {win.strength:.5g}, bias {100 * win.bias:.3f} % "
                 f"(relative L2 change of E); factors "
                 + ", ".join(f"{f:.4f}" for f in win.factors)
                 + f"; after: min E = {_vec(win.after.minimum)}")
    cands = _table(["window", "strength", "bias"],
                   [[k2, f"{s:.5g}", f"{100 * b:.3f} %"] for k2, (s, b) in
                    win.candidates.items()]) if win.candidates else ""

    title = f"shprobe probe report: {source}"
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="{_CSP}">
<title>{html.escape(title)}</title>
<style>
body{{font:14px/1.45 system-ui,sans-serif;margin:24px;max-width:1500px;color:#111}}
h1{{font-size:20px}} h2{{font-size:16px;margin-top:28px;border-bottom:1px solid #ccc}}
table{{border-collapse:collapse;margin:6px 0}} td,th{{border:1px solid #ccc;padding:2px 8px;
text-align:right;font-variant-numeric:tabular-nums}}
td:first-child,th:first-child{{text-align:left}}
.m{{display:inline-block;margin-right:18px;vertical-align:top}} .note{{color:#444}}
img{{display:block;margin:6px 0;max-width:100%;height:auto}}
</style></head><body>
<h1>{html.escape(title)}</h1>
<p class="note">{html.escape(env.path or source)} · layout {env.layout.name}
{'x'.join(map(str, env.grid[::-1]))} · ∫L dω = {_vec(tot)} (R, G, B) · shprobe {__version__}.
Images are tone-mapped (× 2<sup>exposure</sup>, clamp, sRGB); pictures of irradiance show
E/π, the radiance a white diffuse surface reflects.</p>
<h2>Probe</h2>
{_img(figs["probe"], "the probe")}
<h2>Irradiance: 9 coefficients vs exact</h2>
{_img(figs["irradiance"], "irradiance maps and error")}
<p class="note">Lat-long maps, {2 * h}×{h} normals (the error table uses the same
normals). Error as a fraction of the total intensity ∫L dω, R&amp;H 2001 §3.1.</p>
{_table(["lmax", "mean |ΔE| / ∫L", "max |ΔE| / ∫L", "mean rel.", "sMAPE", "note"], err_rows)}
<h2>Lighting coefficients L<sub>lm</sub> (R&amp;H 2001 Fig. 2 layout)</h2>
{_table(["", "R", "G", "B"], coeff_rows, "coeffs")}
<h2>Matrices M (R&amp;H eq. 11–12): E(n) = nᵀ M n, n = (x, y, z, 1)</h2>
{m_tables}
<h2>Non-negativity of E</h2>
<p>{html.escape(verdict)} ({html.escape(mn.method)}).</p>
{cert}
<p>Window <code>auto</code> chooses: {html.escape(wtext)}.</p>
{cands}
<h2>Basis images and a render of {html.escape(obj)}</h2>
{_img(figs["basis"], "irradiance basis images")}
<p class="note">Any lighting L gives the image Σ L<sub>lm</sub> · basis<sub>lm</sub>.</p>
{_img(figs["render"], "render under the probe")}
</body></html>
"""
    return ProbeReport(page, source, L, rep, mn, win, figs)


def write_report(path: str | os.PathLike[str], report: ProbeReport,
                 overwrite: bool = False) -> Path:
    """Write the page atomically ([`shprobe.files.write_text`][shprobe.files.write_text]).

    Parameters
    ----------
    path
        The HTML file.
    report
        The report of [`probe_report`][shprobe.report.probe_report].
    overwrite
        Replace an existing file.

    Returns
    -------
    Path
        The file written.
    """
    from ..files import write_text

    p = Path(path)
    if p.suffix.lower() not in (".html", ".htm"):
        raise ShprobeError("a report is written as .html", p)
    write_text(p, report.html, overwrite)
    return p
