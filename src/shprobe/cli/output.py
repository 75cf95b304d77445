"""What a command says when it is done: one line naming what it wrote.

Every command that writes files ends with :func:`wrote` (silenced by ``-q``; ``-v`` adds
detail lines through :func:`detail`). The product of a command (a table, a JSON document sent
to stdout) goes to stdout; this line goes to stderr so that a command's stdout stays its product.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import click


@dataclass
class Verbosity:
    """The global ``-q``/``-v`` choice, kept on the click context (``ctx.obj``)."""

    quiet: bool = False
    verbose: bool = False
    started: float = field(default_factory=time.monotonic)


def verbosity() -> Verbosity:
    """The current command's verbosity (defaults when called outside a command)."""
    ctx = click.get_current_context(silent=True)
    root = ctx.find_root() if ctx is not None else None
    obj = getattr(root, "obj", None)
    return obj if isinstance(obj, Verbosity) else Verbosity()


def progress():
    """The terminal reporter for this command (quiet under ``-q``)."""
    from .progress import TerminalProgress

    return TerminalProgress(quiet=verbosity().quiet)


def _size(paths: Sequence[str | os.PathLike]) -> str:
    total = 0
    for p in paths:
        try:
            total += os.path.getsize(p)
        except OSError:
            pass
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if total >= scale:
            return f"{total / scale:.1f} {unit}"
    return f"{total} B"


def wrote(paths: Sequence[str | os.PathLike] | str | os.PathLike, what: str = "") -> None:
    """The closing line: 'wrote PATH[, PATH …] (what, size, time)' on stderr."""
    v = verbosity()
    if v.quiet:
        return
    if isinstance(paths, str | os.PathLike):
        paths = [paths]
    names = [os.fspath(p) for p in paths]
    shown = (", ".join(names) if len(names) <= 3
             else f"{names[0]} … {names[-1]} ({len(names)} files)")
    parts = [p for p in (what, _size(names), f"{time.monotonic() - v.started:.1f} s") if p]
    click.echo(f"wrote {shown} ({', '.join(parts)})", err=True)


def detail(message: str) -> None:
    """A line shown only under ``-v``."""
    if verbosity().verbose:
        click.echo(message, err=True)
