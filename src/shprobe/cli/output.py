"""What a command says: its estimate before a long job, one line naming what it wrote.

Every command that writes files ends with `wrote` (silenced by ``-q``; ``-v`` adds
detail lines through `detail`). The product of a command (a table, a JSON document sent
to stdout) goes to stdout; these lines go to stderr so that a command's stdout stays its
product. A job estimated over [`shprobe.limits.LONG_JOB_SECONDS`][shprobe.limits.LONG_JOB_SECONDS]
says so before it starts (`estimate`, from the cost model its memory check uses); `progress` is the
one terminal reporter of the `shprobe.progress` protocol.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import click


@dataclass
class Verbosity:
    """The global ``-q``/``-v`` choice, kept on the click context (``ctx.obj``)."""

    quiet: bool = False
    verbose: bool = False
    started: float = field(default_factory=time.monotonic)
    reporter: Any = None  # the command's one terminal reporter, made on first use
    limits: Any = None  # the shprobe.limits.Limits built from --max-memory


def verbosity() -> Verbosity:
    """The current command's verbosity (defaults when called outside a command)."""
    ctx = click.get_current_context(silent=True)
    root = ctx.find_root() if ctx is not None else None
    obj = getattr(root, "obj", None)
    return obj if isinstance(obj, Verbosity) else Verbosity()


def limits():
    """The [`shprobe.limits.Limits`][shprobe.limits.Limits] of this command (from ``--max-memory``),
    which the command passes to the workflow it calls."""
    from ..limits import Limits

    v = verbosity()
    return v.limits if isinstance(v.limits, Limits) else Limits()


def progress():
    """The terminal reporter of this command (quiet under ``-q``): one per command, so that
    stages begun anywhere in it nest in one display."""
    from .progress import TerminalProgress

    v = verbosity()
    if v.reporter is None or v.reporter.stream is not sys.stderr:
        v.reporter = TerminalProgress(quiet=v.quiet)
    return v.reporter


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
    folders = {os.path.dirname(n) for n in names}
    if len(names) <= 3:
        shown = ", ".join(names)
    elif len(folders) == 1 and "" not in folders:
        shown = (f"{len(names)} files in {folders.pop()}{os.sep}: "
                 f"{os.path.basename(names[0])} … {os.path.basename(names[-1])}")
    else:
        shown = f"{len(names)} files: {names[0]} … {names[-1]}"
    for n in names if len(names) > 3 else ():
        detail(f"  {n}")
    parts = [p for p in (what, _size(names), f"{time.monotonic() - v.started:.1f} s") if p]
    click.echo(f"wrote {shown} ({', '.join(parts)})", err=True)


def estimate(cost, what: str) -> None:
    """Say ``what`` will take ``cost`` (a [`shprobe.limits.Cost`][shprobe.limits.Cost]) before it
    starts, when it is a long job; quiet under ``-q`` (and shown under ``-v`` whatever its length).
    A job whose bytes are over the memory limit is refused first, in one line
    ([`shprobe.limits.check_memory`][shprobe.limits.check_memory], the check the job itself
    makes)."""
    from ..limits import check_memory

    check_memory(cost.nbytes, what, limits=limits())
    v = verbosity()
    if not v.quiet and (cost.long or v.verbose):
        click.echo(f"{what}: {cost}", err=True)


def detail(message: str) -> None:
    """A line shown only under ``-v``."""
    if verbosity().verbose:
        click.echo(message, err=True)
