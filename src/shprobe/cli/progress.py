"""The one place that draws progress in the terminal.

:class:`TerminalProgress` implements :class:`shprobe.progress.Progress`: on a terminal, a rich
bar on stderr per stage (description "k/N: what", percent, ETA where the total is known; the bar
ends at 100 % and is removed); otherwise one plain line per stage on stderr and nothing else, so
logs get no blank lines and no control codes. Quiet mode reports nothing.
"""

from __future__ import annotations

import sys
import time
from typing import Any


class TerminalProgress:
    """A :class:`shprobe.progress.Progress` for the CLI (see the module docstring)."""

    def __init__(self, quiet: bool = False, stream: Any = None) -> None:
        self.quiet = quiet
        self.stream = stream if stream is not None else sys.stderr
        self._bar: Any = None
        self._task: Any = None
        self._total: float | None = None
        self._t0 = 0.0
        self._description = ""

    @property
    def interactive(self) -> bool:
        isatty = getattr(self.stream, "isatty", None)
        return bool(isatty and isatty())

    def begin(self, description: str, total: float | None = None) -> None:
        self.end()
        self._description, self._total, self._t0 = description, total, time.monotonic()
        if self.quiet:
            return
        if not self.interactive:
            self.stream.write(f"{description} …\n")
            self.stream.flush()
            return
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            Progress,
            TaskProgressColumn,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        columns: list[Any] = [TextColumn("{task.description}")]
        if total is not None:
            columns += [BarColumn(), TaskProgressColumn(), TimeElapsedColumn(),
                        TextColumn("ETA"), TimeRemainingColumn()]
        else:
            columns += [TimeElapsedColumn()]
        self._bar = Progress(*columns, console=Console(file=self.stream, highlight=False),
                             transient=True)
        self._bar.start()
        self._task = self._bar.add_task(description, total=total)

    def update(self, done: float) -> None:
        if self._bar is not None:
            self._bar.update(self._task, completed=done)

    def end(self) -> None:
        if self._bar is not None:
            if self._total is not None:
                self._bar.update(self._task, completed=self._total)
            self._bar.stop()
            self._bar = None
            self._task = None
