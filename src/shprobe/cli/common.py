"""Shared CLI helpers: console, option types."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TypeVar

import click

from ..errors import ShprobeError

T = TypeVar("T")


def console(stderr: bool = False):
    """A rich console (imported lazily). Piped or redirected (no terminal, no ``COLUMNS``) it
    has no width to honour: a table row stays one line instead of wrapping at rich's 80."""
    import sys

    from rich.console import Console

    stream = sys.stderr if stderr else sys.stdout
    piped = not (getattr(stream, "isatty", lambda: False)() or os.environ.get("COLUMNS"))
    return Console(stderr=stderr, highlight=False, width=10_000 if piped else None)


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


def setting_default(settings_type: type, name: str):
    """The default of field ``name`` of a settings dataclass: the one defaults table the CLI's
    options read (``tests/cli/test_cli_defaults.py`` checks they agree)."""
    import dataclasses

    f = settings_type.__dataclass_fields__[name]
    if f.default is not dataclasses.MISSING:
        return f.default
    return f.default_factory()  # type: ignore[misc]


def parse_albedo(text: str):
    """One ``--albedo`` value: a grey number or r,g,b."""
    v = parse_floats(text, what="albedo")
    if len(v) not in (1, 3):
        raise ShprobeError(f"albedo {text!r} must be one number or r,g,b")
    return v[0] if len(v) == 1 else tuple(v)


def parse_vector(text: str, what: str = "direction"):
    """'x,y,z' → a unit vector (numpy array), via `shprobe.sh.rotation.unit_vectors`
    (overflow-safe; zero and non-finite vectors refused in one line)."""
    from ..sh.rotation import unit_vectors

    v = parse_floats(text, 3, what)
    try:
        return unit_vectors(v, what)
    except ShprobeError as e:
        raise ShprobeError(f"{what} {text!r}: {e.message}") from None


#: The forms every ``--rotate`` accepts (edit, render, prt render, hbasis render).
ROTATE_HELP = ("Rotation AX,AY,AZ:DEGREES (right-hand rule about the axis), "
               "euler:ALPHA,BETA,GAMMA (ZYZ, degrees) or quat:W,X,Y,Z (scalar first).")


def parse_rotation(text: str):
    """One ``--rotate`` value (`ROTATE_HELP`) → a checked 3×3 rotation matrix."""
    import numpy as np

    from ..sh.rotation import from_axis_angle, from_euler_zyz, from_quaternion, one_rotation

    kind, sep, rest = text.partition(":")
    if sep and kind.strip().lower() == "euler":
        a, b, g = np.radians(parse_floats(rest, 3, "ZYZ Euler angles"))
        return one_rotation(from_euler_zyz(a, b, g))
    if sep and kind.strip().lower() == "quat":
        return one_rotation(from_quaternion(parse_floats(rest, 4, "quaternion (w,x,y,z)")))
    if not sep or not rest:
        raise ShprobeError(f"rotation {text!r}: expected AX,AY,AZ:DEGREES (e.g. 0,1,0:90), "
                           "euler:A,B,G or quat:W,X,Y,Z")
    axis = parse_floats(kind, 3, "rotation axis")
    try:
        return from_axis_angle(axis, parse_floats(rest, 1, "rotation angle")[0])
    except ShprobeError as e:
        raise ShprobeError(f"rotation {text!r}: {e.message}") from None


def parse_exposure(text: str) -> float | None:
    """The one ``--exposure`` grammar: ``auto`` → None (the command picks it by
    `shprobe.probes.tonemap.auto_exposure` and prints it); otherwise finite stops."""
    import math

    if str(text).strip().lower() == "auto":
        return None
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v):
        raise ShprobeError(f"--exposure must be 'auto' or a number of stops, got {text!r}")
    return v


#: Largest image side any command makes (a refusal, not an allocation, above it).
MAX_SIDE = 16384


def parse_size(text: str, layout: str | None = None) -> tuple[int, int]:
    """The one ``--size`` grammar → (W, H): 'WxH' everywhere; a bare 'N' is N×N for camera
    images and square layouts, and N×N/2 for lat-long (its 2:1 aspect). Sides are capped at
    `MAX_SIDE`."""
    t = text.strip().lower()
    try:
        if "x" in t:
            w, h = (int(v) for v in t.split("x"))
        else:
            w = int(t)
            h = w // 2 if layout == "latlong" else w
    except ValueError:
        raise ShprobeError(f"cannot parse size {text!r}: expected WxH or N, e.g. 256x128"
                           ) from None
    if w <= 0 or h <= 0:
        raise ShprobeError(f"size {text!r} must be positive")
    if max(w, h) > MAX_SIDE:
        raise ShprobeError(f"size {text!r} is over the limit of {MAX_SIDE} pixels a side")
    if layout not in (None, "latlong") and w != h:
        raise ShprobeError(f"the {layout} layout is square: --size N or NxN, got {text}")
    return w, h


force_option = click.option(
    "--force", "-f", is_flag=True, help="Replace output files that already exist."
)


# layouts (see shprobe.probes.layouts); names listed here so `--help` needs no numpy import
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


@contextmanager
def ldr_warnings_as_lines() -> Iterator[None]:
    """An LDR probe's [`shprobe.probes.images.LDRWarning`][shprobe.probes.images.LDRWarning] as one
    line on stderr (not a Python warning); other warnings pass through."""
    import warnings

    from ..probes.images import LDRWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LDRWarning)
        yield
    for w in caught:
        if issubclass(w.category, LDRWarning):
            click.echo(f"shprobe: warning: {w.message}", err=True)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
