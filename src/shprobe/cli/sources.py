"""Coefficient sources shared by commands: a probe image, an R&H preset or a JSON file.

Use :func:`coeff_source_options` on a click command and :func:`resolve_coeffs` in its body::

    @group.command()
    @coeff_source_options
    def render(probe, layout, preset, coeffs_file, clamp, ...):
        src = resolve_coeffs(probe, preset, coeffs_file, layout=layout, lmax=2, clamp=clamp)
        src.coeffs  # (K, 3)
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import click
import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from .common import clamp_option, layout_option

PRESET_NAMES = ("grace", "eucalyptus", "stpeters")


@dataclass(frozen=True)
class CoeffSource:
    """Resolved lighting: ``coeffs`` (K, 3); ``source`` a name for humans and JSON; ``layout``
    the probe's layout name (None for presets and JSON); ``env`` the loaded probe (or None)."""

    coeffs: NDArray[np.float64]
    source: str
    layout: str | None = None
    env: Any = None


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
                   lmax: int | None = 2, clamp: bool = False, need_env: bool = False
                   ) -> CoeffSource:
    """Exactly one of ``probe`` / ``preset`` / ``coeffs_file`` → coefficients.

    A probe is projected to ``lmax`` (R&H eq. 10). A preset (lmax 2) or coefficient file (any
    export format, :func:`shprobe.export.import_coeffs`; one channel is repeated to RGB) is cut
    to ``lmax`` when that is lower, and refused when it is higher. ``lmax=None`` keeps a preset's
    or file's own degree (a probe then uses 2). ``need_env`` refuses sources without a probe.
    """
    from ..sh import lmax_of, num_coeffs

    given = [n for n, v in (("PROBE", probe), ("--preset", preset), ("--coeffs", coeffs_file))
             if v]
    if len(given) != 1:
        raise ShprobeError("give exactly one lighting source: PROBE, --preset NAME or "
                           f"--coeffs FILE.json (got {', '.join(given) or 'none'})")
    if need_env and not probe:
        raise ShprobeError(f"this command needs a probe image, not {given[0]}")
    if probe:
        from ..lighting.projection import project
        from .common import load_env_cli

        if isinstance(probe, list) and layout not in ("auto", "cube"):
            raise ShprobeError(f"six face images make a cube map, not --layout {layout}")
        env = load_env_cli(probe, "auto" if isinstance(probe, list) else layout, clamp)
        name = probe if isinstance(probe, str) else f"{probe[0]} … {probe[-1]} (cube faces)"
        return CoeffSource(project(env, 2 if lmax is None else lmax), name,
                           env.layout.name, env)
    if preset:
        from ..probes.presets import get_preset

        c, name, have = get_preset(preset), f"preset:{preset}", None
    else:
        from ..lighting.export import import_coeffs

        c, name, have = import_coeffs(coeffs_file), coeffs_file, coeffs_file
        if c.shape[1] == 1:
            c = np.repeat(c, 3, axis=1)
    if lmax is not None:
        own = lmax_of(c.shape[0])
        if lmax > own:
            raise ShprobeError(f"has coefficients up to lmax={own}, not {lmax}", have or name)
        c = c[: num_coeffs(lmax)]
    return CoeffSource(c, name)


__all__ = ["CoeffSource", "coeff_source_options", "resolve_coeffs"]
