"""CLI commands: ``shprobe sh eval`` and ``shprobe sh zonal`` (wrapping shprobe.sh / .zonal)."""

from __future__ import annotations

import json
import math

import click

from ..errors import ShprobeError
from .common import parse_vector


def _lmax(value: int) -> int:
    from ..sh import check_lmax

    return check_lmax(value)


def _echo_table(header: list[str], rows: list[list[str]]) -> None:
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    click.echo("  ".join(h.rjust(w) for h, w in zip(header, widths, strict=True)))
    for r in rows:
        click.echo("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)))



@click.group("sh")
def sh() -> None:
    """Spherical-harmonic values and zonal factors (real orthonormal SH, R&H signs)."""

@sh.command("eval")
@click.option("--dir", "dirs", multiple=True, required=True, metavar="X,Y,Z",
              help="Direction (normalised before use); repeat for several.")
@click.option("--lmax", type=int, required=True, help="Largest degree l.")
@click.option("--format", "fmt", type=click.Choice(["table", "json"]), default="table",
              show_default=True)
def sh_eval(dirs: tuple[str, ...], lmax: int, fmt: str) -> None:
    """Print y_lm(dir) for l <= LMAX, flat index k = l(l+1)+m."""
    import numpy as np

    from ..sh import sh_basis, sh_lm

    lmax = _lmax(lmax)
    vecs = []
    for text in dirs:
        vecs.append(parse_vector(text))
    d = np.array(vecs)
    y = sh_basis(d, lmax)
    if fmt == "json":
        click.echo(json.dumps({
            "lmax": lmax,
            "index": "k = l(l+1)+m",
            "convention": "real orthonormal SH, R&H signs (no Condon-Shortley phase)",
            "directions": d.tolist(),
            "values": y.tolist(),
        }, indent=1))
        return
    header = ["k", "l", "m"] + [f"({a:.4g},{b:.4g},{c:.4g})" for a, b, c in d]
    rows = []
    for k in range(y.shape[1]):
        l, m = sh_lm(k)
        rows.append([str(k), str(l), str(m)] + [f"{v:.9g}" for v in y[:, k]])
    _echo_table(header, rows)

@sh.command("zonal")
@click.option("--lmax", type=int, default=8, show_default=True, help="Largest degree l.")
@click.option("--kind", type=click.Choice(["clamped-cosine", "window"]),
              default="clamped-cosine", show_default=True,
              help="clamped-cosine: Â_l (R&H eq. 8); window: LH §3.2 circular window.")
@click.option("--aperture", type=float, default=None, metavar="DEG",
              help="Window radius ζ in degrees (--kind window).")
@click.option("--format", "fmt", type=click.Choice(["table", "json"]), default="table",
              show_default=True)
def sh_zonal(lmax: int, kind: str, aperture: float | None, fmt: str) -> None:
    """Print per-band factors: Â_l, or the window's 2π∫h P_l (total power 4π).

    Â_l vanishes for odd l > 1 (R&H eq. 9): the clamped cosine keeps bands 0, 1, 2, 4, …"""
    from ..sh.zonal import clamped_cosine_factors, window_moments

    lmax = _lmax(lmax)
    if kind == "clamped-cosine":
        if aperture is not None:
            raise ShprobeError("--aperture applies only to --kind window")
        vals = clamped_cosine_factors(lmax)
        name = "A_hat_l"
    else:
        if aperture is None:
            raise ShprobeError("--kind window needs --aperture DEG")
        if not 0.0 < aperture <= 180.0:
            raise ShprobeError(f"--aperture {aperture} must be in (0, 180] degrees")
        vals = window_moments(math.radians(aperture), lmax)
        name = "window_l"
    if fmt == "json":
        out = {"kind": kind, "lmax": lmax, name: vals.tolist()}
        if aperture is not None:
            out["aperture_deg"] = aperture
        click.echo(json.dumps(out, indent=1))
        return
    _echo_table(["l", name], [[str(l), f"{v:.9g}"] for l, v in enumerate(vals)])


def register(group: click.Group) -> None:
    """Add this module's commands to the top-level group."""
    group.add_command(sh)
