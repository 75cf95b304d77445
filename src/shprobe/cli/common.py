"""Shared CLI helpers: console, option types, progress bars."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import TypeVar

import click

from ..errors import ShprobeError

T = TypeVar("T")


def console(stderr: bool = False):
    """A rich console (imported lazily)."""
    from rich.console import Console

    return Console(stderr=stderr, highlight=False)


def progress(items: Iterable[T], description: str, total: int | None = None) -> Iterator[T]:
    """Iterate with a rich progress bar on stderr (quiet when stderr is not a terminal)."""
    from rich.progress import track

    yield from track(items, description=description, total=total, console=console(stderr=True),
                     transient=True)


def parse_floats(text: str, n: int | None = None, what: str = "value") -> list[float]:
    """Parse 'a,b,c' into floats; one-line error otherwise."""
    try:
        vals = [float(t) for t in text.replace(" ", "").split(",") if t != ""]
    except ValueError:
        raise ShprobeError(
            f"cannot parse {what} {text!r}: expected comma-separated numbers"
        ) from None
    if n is not None and len(vals) != n:
        raise ShprobeError(f"{what} {text!r} must have {n} comma-separated numbers")
    return vals


def unit_vector(values: list[float], text: str, what: str = "direction"):
    """Three floats → a unit vector (numpy array); one-line error for non-finite or zero
    vectors. Scaled by the largest component first, so (1e200, 1e200, 0) does not overflow."""
    import numpy as np

    v = np.asarray(values, dtype=np.float64)
    big = float(np.abs(v).max()) if v.size else 0.0
    if not np.all(np.isfinite(v)) or big == 0.0:
        raise ShprobeError(f"{what} {text!r} must be a finite, non-zero vector")
    v = v / big
    return v / np.linalg.norm(v)


def parse_size(text: str) -> tuple[int, int]:
    """Parse 'WxH' into (W, H)."""
    try:
        w, h = (int(t) for t in text.lower().split("x"))
    except ValueError:
        raise ShprobeError(f"cannot parse size {text!r}: expected WxH, e.g. 256x128") from None
    if w <= 0 or h <= 0:
        raise ShprobeError(f"size {text!r} must be positive")
    return w, h


force_option = click.option(
    "--force", "-f", is_flag=True, help="Replace output files that already exist."
)


# layouts (see shprobe.layouts); names listed here so `--help` needs no numpy import
LAYOUT_CHOICES = ("auto", "latlong", "angular", "mirrorball", "cube")

layout_option = click.option(
    "--layout", "-l", type=click.Choice(LAYOUT_CHOICES), default="auto", show_default=True,
    help="Image layout of the probe: auto detects it from the aspect (2:1 lat-long, square "
         "angular map, 4:3 / 3:4 cross or 6:1 / 1:6 strip cube map); mirror ball only when "
         "asked for.",
)

clamp_option = click.option(
    "--clamp", is_flag=True,
    help="Set NaN, infinite and negative pixels to 0 (+inf to the largest value) instead of "
         "refusing the image.",
)


def load_env_cli(path: str | list[str], layout: str = "auto", clamp: bool = False):
    """``shprobe.layouts.load_env`` for commands: an LDR image gives one warning line on
    stderr (not a Python warning)."""
    import warnings

    from ..probes.images import LDRWarning
    from ..probes.layouts import load_env

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LDRWarning)
        env = load_env(path, layout=None if layout == "auto" else layout, clamp=clamp)
    for w in caught:
        if issubclass(w.category, LDRWarning):
            click.echo(f"shprobe: warning: {w.message}", err=True)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return env
