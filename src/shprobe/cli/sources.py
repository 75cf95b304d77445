"""The lighting-source options shared by commands (PROBE | --preset | --coeffs), resolved by the
library's one resolver, `shprobe.lighting.source.resolve_lighting`.

Use `coeff_source_options` on a click command and `resolve_coeffs` in its body::

    @group.command()
    @coeff_source_options
    def render(probe, layout, preset, coeffs_file, clamp, ...):
        src = resolve_coeffs(probe, preset, coeffs_file, layout=layout, lmax=2, clamp=clamp)
        src.coeffs  # (K, 3)
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

from ..errors import ShprobeError
from ..lighting.source import Lighting
from .common import clamp_option, layout_option, ldr_warnings_as_lines

PRESET_NAMES = ("grace", "eucalyptus", "stpeters")


def _probe_paths(ctx: click.Context, param: click.Parameter, value: tuple[str, ...]
                 ) -> str | list[str] | None:
    """PROBE...: none, one image, or six cube-face images (+X −X +Y −Y +Z −Z)."""
    if not value:
        return None
    if len(value) == 1:
        return value[0]
    if len(value) == 6:
        return list(value)
    raise click.BadParameter(f"give one probe image, or six cube faces in the order "
                             f"+X -X +Y -Y +Z -Z (got {len(value)} files)", ctx, param)


def coeff_source_options(fn: Callable) -> Callable:
    """Add ``[PROBE]...``, ``--layout``, ``--clamp``, ``--preset`` and ``--coeffs`` to a command
    (parameters ``probe``, ``layout``, ``clamp``, ``preset``, ``coeffs_file``). PROBE is one
    image, or six cube-face images in the order +X −X +Y −Y +Z −Z."""
    fn = click.option("--coeffs", "coeffs_file", type=click.Path(dir_okay=False),
                      help="Read lighting coefficients from a file in any `--format` that "
                           "`shprobe prefilter` writes (json, three, gltf, cmgen, cs-phase, "
                           "or a shprobe shader).")(fn)
    fn = click.option("--preset", type=click.Choice(PRESET_NAMES),
                      help="Use an R&H 2001 Fig. 2 table instead of a probe.")(fn)
    fn = clamp_option(fn)
    fn = layout_option(fn)
    return click.argument("probe", nargs=-1, callback=_probe_paths, metavar="[PROBE]...",
                          type=click.Path(dir_okay=False))(fn)


def resolve_coeffs(probe: str | list[str] | None = None, preset: str | None = None,
                   coeffs_file: str | None = None, layout: str = "auto",
                   lmax: int | None = 2, clamp: bool = False, need_env: bool = False,
                   cone: tuple[Any, float] | None = None, probe_flag: str = "PROBE"
                   ) -> Lighting:
    """`shprobe.lighting.source.resolve_lighting` for commands: the option names in the
    messages (``probe_flag``: how the command takes the probe), and an LDR probe's warning as
    one line on stderr."""
    from ..lighting.source import SourceChoiceError, resolve_lighting

    try:
        with ldr_warnings_as_lines():
            return resolve_lighting(probe, preset, coeffs_file, cone, layout, lmax, clamp,
                                    need_env)
    except SourceChoiceError as e:
        if e.need_env:
            raise ShprobeError(f"this command needs a probe image, not {e.given[0]}") from None
        flags = {"a probe": probe_flag, "a preset": "--preset", "a coefficient file":
                 "--coeffs", "a cone light": "--cone"}
        raise ShprobeError(f"give exactly one lighting source: {probe_flag}, --preset NAME, "
                           "--coeffs FILE" + (" or --cone X,Y,Z,APERTURE" if cone else "")
                           + f" (got {', '.join(flags.get(g, g) for g in e.given) or 'none'})"
                           ) from None


__all__ = ["coeff_source_options", "resolve_coeffs"]
