"""CLI commands: ``shprobe hbasis study|bake|render`` (H-basis, Habel & Wimmer 2010)."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import ShprobeError
from .common import console, force_option


@click.group("hbasis")
def hbasis_group() -> None:
    """H-basis (Habel & Wimmer 2010): error study, per-vertex bake, normal-mapped render."""


@hbasis_group.command("study")
@click.option("--signals", "-n", type=click.IntRange(1, 10_000_000), default=10000,
              show_default=True, help="Number of random irradiance signals.")
@click.option("--seed", type=int, default=0, show_default=True, help="Generator seed.")
@click.option("--output", "-o", "outdir", type=click.Path(file_okay=False, path_type=Path),
              default=None, help="Folder for hbasis_study.{md,csv,png} (created if missing).")
@force_option
def study_cmd(signals: int, seed: int, outdir: Path | None, force: bool) -> None:
    """Fig. 3 study: mean IMSE (eq. 16) of every hemispherical basis, random signals."""
    from ..files import atomic_output, write_text
    from ..hbasis.study import run_study

    res = run_study(signals, seed)
    click.echo(res.markdown(), nl=False)
    if outdir is None:
        return
    if outdir.exists() and not outdir.is_dir():
        raise ShprobeError("is not a folder", outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    write_text(outdir / "hbasis_study.md", res.markdown(), overwrite=force)
    write_text(outdir / "hbasis_study.csv", res.csv(), overwrite=force)
    with atomic_output(outdir / "hbasis_study.png", overwrite=force) as tmp:
        res.plot(tmp)
    console(stderr=True).print(f"wrote {outdir}/hbasis_study.md, .csv, .png")


def _lighting(probe: Path, lmax: int):
    from ..hbasis._env import load_lighting

    return load_lighting(probe, lmax)


@hbasis_group.command("bake")
@click.argument("mesh", type=click.Path(path_type=Path))
@click.argument("probe", type=click.Path(path_type=Path))
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Output .npz (h, sh9, frames, handedness, t_h).")
@click.option("--basis", type=click.Choice(["h6", "h4"]), default="h6", show_default=True)
@click.option("--bands", type=click.IntRange(2, 16), default=4, show_default=True,
              help="SH bands of the irradiance projected into H (2: paper's T_h; 4: + App. A).")
@force_option
def bake_cmd(mesh: Path, probe: Path, output: Path, basis: str, bands: int, force: bool) -> None:
    """Bake per-vertex tangent-space H coefficients of MESH under PROBE (lat-long image, or
    .npy/.npz SH radiance coefficients (K, 3))."""
    import numpy as np

    from ..files import save_npz
    from ..hbasis.basis import sh_to_h_matrix
    from ..hbasis.normalmap import bake, load_mesh, mesh_uvs, tangent_frames
    from ..zonal import clamped_cosine_factors, convolve

    if not mesh.is_file():
        raise ShprobeError("no such file", mesh)
    m = load_mesh(mesh)
    light = _lighting(probe, max(bands, 2))
    from ..sh import lmax_of

    lm = lmax_of(light.sh.shape[0])
    e = convolve(light.sh, clamped_cosine_factors(lm))
    fr = tangent_frames(m.vertices, m.faces, np.asarray(m.vertex_normals), mesh_uvs(m))
    n = 6 if basis == "h6" else 4
    bk = bake(e, fr.matrix, n=n, lmax=bands)
    save_npz(output, overwrite=force, h=bk.h, sh9=bk.sh, frames=fr.matrix,
             handedness=fr.handedness.astype(np.int8),
             t_h=sh_to_h_matrix(min(bands, lm), n), basis=np.array(basis.upper()))
    console(stderr=True).print(f"wrote {output}: {len(m.vertices)} vertices × {n} × 3")


@hbasis_group.command("render")
@click.argument("mesh", type=click.Path(path_type=Path))
@click.argument("probe", type=click.Path(path_type=Path))
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Output PNG: reference | H6 | H4 | SH9 over |error| × gain.")
@click.option("--size", type=click.IntRange(16, 4096), default=256, show_default=True)
@click.option("--bump", type=click.FloatRange(0, 5), default=0.3, show_default=True,
              help="Slope amplitude of the procedural bump (0: no normal map).")
@click.option("--gain", type=click.FloatRange(0, 1000), default=4.0, show_default=True,
              help="Multiplier of the error panels.")
@click.option("--normal-map", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Tangent-space normal-map image (needs a mesh with UVs) instead of the bump.")
@force_option
def render_cmd(mesh: Path, probe: Path, output: Path, size: int, bump: float, gain: float,
               normal_map: Path | None, force: bool) -> None:
    """Render MESH with a procedural normal map under PROBE, shading with per-vertex H6, H4 and
    SH9 against the brute-force reference; prints the relative RMS errors."""
    from PIL import Image

    from ..files import atomic_output, check_output_path
    from ..hbasis.normalmap import load_mesh, panel_image, read_normal_map, render_normal_mapped

    if output.suffix.lower() != ".png":
        raise ShprobeError("the comparison panel is written as .png", output)
    check_output_path(output, force)
    if not mesh.is_file():
        raise ShprobeError("no such file", mesh)
    m = load_mesh(mesh)
    nmap = None if normal_map is None else read_normal_map(normal_map)
    res = render_normal_mapped(m, _lighting(probe, 16), size=size, bump_amplitude=bump,
                               normal_map=nmap)
    with atomic_output(output, overwrite=force) as tmp:
        Image.fromarray(panel_image(res, gain)).save(tmp, format="PNG")
    click.echo("| basis | relative RMS error vs brute force |\n| --- | ---: |")
    for k, v in res.rel_rms.items():
        click.echo(f"| {k} | {v:.4f} |")
    console(stderr=True).print(f"wrote {output}")


def register(group: click.Group) -> None:
    """Add this module's commands to the top-level group."""
    group.add_command(hbasis_group)
