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
