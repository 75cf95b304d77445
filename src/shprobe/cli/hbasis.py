"""CLI commands: ``shprobe hbasis study|bake|render`` (H-basis, Habel & Wimmer 2010)."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import ShprobeError
from ..hbasis.baking import BASES, HBasisSettings, bake_hbasis
from ..progress import stage
from .common import ROTATE_HELP, force_option, parse_rotation, setting_default
from .output import estimate, limits, progress, wrote

table_option = click.option("--table", "show_table", is_flag=True,
                            help="Also print the result's tables (markdown) on stdout.")


@click.group("hbasis")
def hbasis_group() -> None:
    """H-basis (Habel & Wimmer 2010): error study, per-vertex bake, normal-mapped render."""


@hbasis_group.command("study", short_help="Habel & Wimmer Fig. 3: the mean IMSE of every "
                                          "hemispherical basis over random signals.")
@click.option("--signals", "-n", type=click.IntRange(1, 200_000), default=10000,
              show_default=True, help="Number of random irradiance signals (about 1 s per "
                                      "2000 on one core).")
@click.option("--seed", type=int, default=0, show_default=True, help="Generator seed.")
@click.option("--output", "-o", "outdir", type=click.Path(file_okay=False, path_type=Path),
              default=None, help="Folder for hbasis_study.{md,csv,png} (created if missing); "
                                 "without it, the tables are printed.")
@table_option
@force_option
def study_cmd(signals: int, seed: int, outdir: Path | None, show_table: bool,
              force: bool) -> None:
    """Fig. 3 study: mean IMSE (eq. 16) of every hemispherical basis, random signals. The
    tables go to hbasis_study.md (printed with --table, or when there is no --output)."""
    from ..files import atomic_output, check_output_path, transaction, write_text
    from ..hbasis.study import run_study, study_cost

    names = ("hbasis_study.md", "hbasis_study.csv", "hbasis_study.png")
    if outdir is not None:  # refuse before the work, not after it
        if outdir.exists() and not outdir.is_dir():
            raise ShprobeError("is not a folder", outdir)
        if outdir.exists():
            for name in names:
                check_output_path(outdir / name, force)
    estimate(study_cost(signals), f"the study of {signals:,} signals")
    res = run_study(signals, seed, progress=progress())
    if show_table or outdir is None:
        click.echo(res.markdown(), nl=False)
    if outdir is None:
        return
    outdir.mkdir(parents=True, exist_ok=True)
    with transaction():  # the table, the CSV and the plot together or none
        write_text(outdir / names[0], res.markdown(), overwrite=force)
        write_text(outdir / names[1], res.csv(), overwrite=force)
        with atomic_output(outdir / names[2], overwrite=force) as tmp:
            res.plot(tmp)
    best = min(zip(res.mean_imse, res.names, strict=True))
    wrote([outdir / n for n in names], f"{len(res.names)} bases over {signals:,} signals; "
                                       f"lowest mean IMSE {best[1]} {best[0]:.3g}")


def _lighting(probe: Path):
    """PROBE as the H-basis commands take it, through the one resolver: radiance SH (K, 3)
    from an .npy / .npz (a bake file gives its probe's L), else the probe image itself (the
    exact reference needs its pixels)."""
    from ..lighting.source import resolve_lighting

    if probe.suffix.lower() in (".npy", ".npz"):
        return resolve_lighting(coeffs=probe, lmax=None).coeffs
    return resolve_lighting(probe=probe, need_env=True).env


@hbasis_group.command("bake")
@click.argument("mesh", type=click.Path(path_type=Path))
@click.argument("probe", type=click.Path(path_type=Path))
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Output .npz (h, sh9, frames, handedness, t_h, mesh_hash, L).")
@click.option("--basis", type=click.Choice(list(BASES)),
              default=setting_default(HBasisSettings, "basis"), show_default=True)
@click.option("--bands", type=click.IntRange(2, 16),
              default=setting_default(HBasisSettings, "bands"), show_default=True,
              help="SH bands of the irradiance projected into H (2: paper's T_h; 4: + App. A).")
@force_option
def bake_cmd(mesh: Path, probe: Path, output: Path, basis: str, bands: int, force: bool) -> None:
    """Bake per-vertex tangent-space H coefficients of MESH under PROBE (lat-long image, or
    .npy/.npz SH radiance coefficients (K, 3)). The .npz also keeps the mesh's hash and the
    probe's radiance SH L (l ≤ 16), so `hbasis render MESH FILE.npz` can use it directly."""
    from ..files import check_output_path
    from ..hbasis.bakefile import save_bake
    from ..progress import numbered
    from ..scene.mesh import load_mesh

    check_output_path(output, force)
    settings = HBasisSettings(basis=basis, bands=bands, limits=limits())
    m = load_mesh(mesh)  # bad input is refused here, in one line, before any stage
    light = _lighting(probe)
    bk = bake_hbasis(m, light, settings, numbered(progress(), 1, 2))
    with stage(progress(), "writing", index=2, count=2):
        save_bake(output, bk, overwrite=force)
    summary = bk.as_dict()
    wrote(output, f"{summary['vertices']} vertices × {summary['coefficients']} × 3")


#: Largest brute-force reference `hbasis render` starts (pixels × probe texels): minutes.
MAX_REFERENCE_PAIRS = 2e11


@hbasis_group.command("render")
@click.argument("mesh", type=click.Path(path_type=Path))
@click.argument("probe", type=click.Path(path_type=Path))
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Output PNG: a labelled figure, reference | H6 | H4 | SH9 over their errors.")
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
@click.option("--rotate", default=None, help="Turn the lighting. " + ROTATE_HELP)
@table_option
@force_option
def render_cmd(mesh: Path, probe: Path, output: Path, coeffs: Path | None, size: int,
               bump: float, gain: float, normal_map: Path | None, rotate: str | None,
               show_table: bool, force: bool) -> None:
    """Render MESH with a procedural normal map under PROBE, shading with per-vertex H6, H4 and
    SH9 against the brute-force reference; the closing line gives the relative RMS errors
    (--table prints them as a table).

    PROBE may also be a `hbasis bake` .npz: its coefficients are used (as with --coeffs) and
    the reference is its stored radiance SH expansion (l ≤ 16) instead of brute force.
    """
    import numpy as np

    from ..files import check_output_path
    from ..hbasis.bakefile import is_bake, load_bake
    from ..hbasis.normalmap import read_normal_map
    from ..hbasis.rendering import render_normal_mapped, save_panel
    from ..scene.mesh import load_mesh

    if output.suffix.lower() != ".png":
        raise ShprobeError("the comparison panel is written as .png", output)
    check_output_path(output, force)
    m = load_mesh(mesh)
    if coeffs is None and is_bake(probe):
        coeffs = probe
    baked = None if coeffs is None else load_bake(coeffs, m)
    nmap = None if normal_map is None else read_normal_map(normal_map)
    light = _lighting(probe)
    if not isinstance(light, np.ndarray):  # the exact reference: every pixel × every texel
        pairs = float(size) ** 2 * float(np.prod(light.grid))
        if pairs > MAX_REFERENCE_PAIRS:
            raise ShprobeError(f"the brute-force reference at --size {size} would take "
                               f"{pairs:.2g} pixel-texel products (about "
                               f"{pairs / 1e9 / 60:.0f} min), over the limit of "
                               f"{MAX_REFERENCE_PAIRS:.0e}: use a smaller --size or a "
                               "smaller probe, or `hbasis bake` it first (SH reference)", probe)
    if rotate is not None:
        if baked is not None:
            raise ShprobeError("--rotate turns the lighting; a bake holds it unturned: bake "
                               "again, or drop --coeffs", coeffs)
        from ..lighting.design import rotate_lighting

        R = parse_rotation(rotate)
        light = rotate_lighting(light, R) if isinstance(light, np.ndarray) else light.rotated(R)
    if not isinstance(light, np.ndarray):
        from ..lighting.reference import reference_cost

        estimate(reference_cost(light, size * size), f"the brute-force reference at --size "
                                                     f"{size}")
    rep = progress()
    res = render_normal_mapped(m, light, size=size, bump_amplitude=bump, normal_map=nmap,
                               baked=baked, progress=rep)
    with stage(rep, "writing the panel"):
        save_panel(output, res, gain, overwrite=force)
    if not isinstance(light, np.ndarray):
        ref = "brute force"
    elif coeffs == probe:
        ref = "SH (l ≤ 16) of the baked probe"
    else:
        ref = "the SH expansion of PROBE"
    if show_table:
        click.echo(f"| basis | relative RMS error vs {ref} |\n| --- | ---: |")
        for k, v in res.info["rel_rms"].items():
            click.echo(f"| {k} | {v:.4f} |")
    wrote(output, "relative RMS error " + ", ".join(f"{k} {v:.4f}" for k, v in
                                                    res.info["rel_rms"].items())
          + f" vs {ref}")


def register(group: click.Group) -> None:
    """Add this module's commands to the top-level group."""
    group.add_command(hbasis_group)
