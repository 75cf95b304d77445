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
    from ..files import atomic_output, check_output_path, write_text
    from ..hbasis.study import run_study

    names = ("hbasis_study.md", "hbasis_study.csv", "hbasis_study.png")
    if outdir is not None:  # refuse before the work, not after it
        if outdir.exists() and not outdir.is_dir():
            raise ShprobeError("is not a folder", outdir)
        if outdir.exists():
            for name in names:
                check_output_path(outdir / name, force)
    res = run_study(signals, seed)
    click.echo(res.markdown(), nl=False)
    if outdir is None:
        return
    outdir.mkdir(parents=True, exist_ok=True)
    write_text(outdir / names[0], res.markdown(), overwrite=force)
    write_text(outdir / names[1], res.csv(), overwrite=force)
    with atomic_output(outdir / names[2], overwrite=force) as tmp:
        res.plot(tmp)
    console(stderr=True).print(f"wrote {outdir}/hbasis_study.md, .csv, .png")


def _lighting(probe: Path, lmax: int):
    from ..hbasis._env import load_lighting

    return load_lighting(probe, lmax)


@hbasis_group.command("bake")
@click.argument("mesh", type=click.Path(path_type=Path))
@click.argument("probe", type=click.Path(path_type=Path))
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Output .npz (h, sh9, frames, handedness, t_h, mesh_hash, L).")
@click.option("--basis", type=click.Choice(["h6", "h4"]), default="h6", show_default=True)
@click.option("--bands", type=click.IntRange(2, 16), default=4, show_default=True,
              help="SH bands of the irradiance projected into H (2: paper's T_h; 4: + App. A).")
@force_option
def bake_cmd(mesh: Path, probe: Path, output: Path, basis: str, bands: int, force: bool) -> None:
    """Bake per-vertex tangent-space H coefficients of MESH under PROBE (lat-long image, or
    .npy/.npz SH radiance coefficients (K, 3)). The .npz also keeps the mesh's hash and the
    probe's radiance SH L (l ≤ 16), so `hbasis render MESH FILE.npz` can use it directly."""
    import numpy as np

    from ..files import check_output_path, save_npz
    from ..hbasis.basis import sh_to_h_matrix
    from ..hbasis.normalmap import bake, load_mesh, mesh_uvs, tangent_frames
    from ..prt.scene import mesh_hash
    from ..sh import lmax_of, num_coeffs
    from ..sh.zonal import clamped_cosine_factors, convolve

    check_output_path(output, force)
    if not mesh.is_file():
        raise ShprobeError("no such file", mesh)
    m = load_mesh(mesh)
    light = _lighting(probe, 16)
    lm = lmax_of(light.sh.shape[0])
    e = convolve(light.sh, clamped_cosine_factors(lm))
    fr = tangent_frames(m.vertices, m.faces, np.asarray(m.vertex_normals), mesh_uvs(m))
    n = 6 if basis == "h6" else 4
    bk = bake(e[: num_coeffs(min(bands, lm))], fr.matrix, n=n, lmax=bands)
    save_npz(output, overwrite=force, h=bk.h, sh9=bk.sh, frames=fr.matrix,
             handedness=fr.handedness.astype(np.int8),
             t_h=sh_to_h_matrix(min(bands, lm), n), basis=np.array(basis.upper()),
             bands=np.array(min(bands, lm)), L=light.sh,
             mesh_hash=np.array(mesh_hash(m.vertices, m.faces)))
    console(stderr=True).print(f"wrote {output}: {len(m.vertices)} vertices × {n} × 3")


def _is_bake(path: Path) -> bool:
    """True for an .npz written by `hbasis bake` (it has arrays h and frames)."""
    import numpy as np

    if path.suffix.lower() != ".npz" or not path.is_file():
        return False
    try:
        with np.load(path, allow_pickle=False) as z:
            return "h" in z.files and "frames" in z.files
    except (OSError, ValueError, EOFError):
        return False


@hbasis_group.command("render")
@click.argument("mesh", type=click.Path(path_type=Path))
@click.argument("probe", type=click.Path(path_type=Path))
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Output PNG: reference | H6 | H4 | SH9 over |error| × gain.")
@click.option("--coeffs", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Per-vertex coefficients from `hbasis bake` (.npz) for this MESH, instead of "
                   "baking them here.")
@click.option("--size", type=click.IntRange(16, 4096), default=256, show_default=True)
@click.option("--bump", type=click.FloatRange(0, 5), default=0.3, show_default=True,
              help="Slope amplitude of the procedural bump (0: no normal map).")
@click.option("--gain", type=click.FloatRange(0, 1000), default=4.0, show_default=True,
              help="Multiplier of the error panels.")
@click.option("--normal-map", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Tangent-space normal-map image (needs a mesh with UVs) instead of the bump.")
@force_option
def render_cmd(mesh: Path, probe: Path, output: Path, coeffs: Path | None, size: int,
               bump: float, gain: float, normal_map: Path | None, force: bool) -> None:
    """Render MESH with a procedural normal map under PROBE, shading with per-vertex H6, H4 and
    SH9 against the brute-force reference; prints the relative RMS errors.

    PROBE may also be a `hbasis bake` .npz: its coefficients are used (as with --coeffs) and
    the reference is its stored radiance SH expansion (l ≤ 16) instead of brute force.
    """
    from PIL import Image

    from ..files import atomic_output, check_output_path
    from ..hbasis.normalmap import (
        load_bake,
        load_mesh,
        panel_image,
        read_normal_map,
        render_normal_mapped,
    )

    if output.suffix.lower() != ".png":
        raise ShprobeError("the comparison panel is written as .png", output)
    check_output_path(output, force)
    if not mesh.is_file():
        raise ShprobeError("no such file", mesh)
    m = load_mesh(mesh)
    if coeffs is None and _is_bake(probe):
        coeffs = probe
    baked = None if coeffs is None else load_bake(coeffs, m)
    nmap = None if normal_map is None else read_normal_map(normal_map)
    light = _lighting(probe, 16)
    res = render_normal_mapped(m, light, size=size, bump_amplitude=bump, normal_map=nmap,
                               baked=baked)
    with atomic_output(output, overwrite=force) as tmp:
        Image.fromarray(panel_image(res, gain)).save(tmp, format="PNG")
    if light.dirs is not None:
        ref = "brute force"
    elif coeffs == probe:
        ref = "SH (l ≤ 16) of the baked probe"
    else:
        ref = "the SH expansion of PROBE"
    click.echo(f"| basis | relative RMS error vs {ref} |\n| --- | ---: |")
    for k, v in res.rel_rms.items():
        click.echo(f"| {k} | {v:.4f} |")
    console(stderr=True).print(f"wrote {output}")


def register(group: click.Group) -> None:
    """Add this module's commands to the top-level group."""
    group.add_command(hbasis_group)
