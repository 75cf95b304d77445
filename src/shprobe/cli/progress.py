"""The one place that draws progress in the terminal.

`TerminalProgress` implements [`shprobe.progress.Progress`][shprobe.progress.Progress]. On a
terminal: one rich display on stderr holding a bar per stage under way (description "k/N: what", a
percentage and an ETA when the stage's total is known, the elapsed time always); a stage that ends
is shown at 100 % and removed, and the display is erased when the last stage ends, so no bar is left
on screen below 100 %. Otherwise (stderr redirected to a file or a pipe): one plain line on
stderr, "k/N: what …", for each stage still under way after `LOG_AFTER` seconds, and
nothing else, so logs get no blank lines and no control codes, and a quick command's log is
its closing line alone (bad input still gives one line). Quiet mode reports nothing. Stages
may nest (a library stage inside a command's stage): each gets its own bar, the inner one
under the outer.
"""

from __future__ import annotations

import sys
import threading
from typing import Any

#: Seconds a stage must last before a log (a stderr that is not a terminal) gets its line.
LOG_AFTER = 1.0


def _columns() -> list[Any]:
    """The bar's columns: description, bar, percent and ETA (countable stages only), elapsed."""
    from rich.progress import BarColumn, ProgressColumn, TextColumn, TimeElapsedColumn
    from rich.text import Text

    class Percent(ProgressColumn):
        def render(self, task: Any) -> Text:
            return Text("" if task.total is None else f"{task.percentage:>3.0f} %")

    class Eta(ProgressColumn):
        max_refresh = 0.5

        def render(self, task: Any) -> Text:
            left = task.time_remaining if task.total is not None else None
            if left is None:
                return Text("")
            m, s = divmod(round(left), 60)
            h, m = divmod(m, 60)
            return Text(f"ETA {h}:{m:02d}:{s:02d}" if h else f"ETA {m}:{s:02d}")

    return [TextColumn("{task.description}"), BarColumn(), Percent(), TimeElapsedColumn(),
            Eta()]


class TerminalProgress:
    """A [`shprobe.progress.Progress`][shprobe.progress.Progress] for the CLI (see the module
    docstring)."""

    def __init__(self, quiet: bool = False, stream: Any = None,
                 log_after: float | None = None) -> None:
        self.quiet = quiet
        self.stream = stream if stream is not None else sys.stderr
        self.log_after = LOG_AFTER if log_after is None else log_after
        self._live: Any = None  # the rich display, while a stage is under way on a terminal
        # per stage under way: its rich task (terminal) or its line's timer (log), its total
        self._stack: list[tuple[Any, float | None]] = []

    @property
    def interactive(self) -> bool:
        isatty = getattr(self.stream, "isatty", None)
        try:
            return bool(isatty and isatty())
        except ValueError:  # a closed stream
            return False

    def begin(self, description: str, total: float | None = None) -> None:
        task: Any = None
        if not self.quiet and not self.interactive and self.log_after <= 0:
            self._log(f"{description} …\n")
        elif not self.quiet and not self.interactive:
            task = threading.Timer(self.log_after, self._log, (f"{description} …\n",))
            task.daemon = True
            task.start()
        elif not self.quiet:
            if self._live is None:
                from rich.console import Console
                from rich.progress import Progress

                self._live = Progress(*_columns(), transient=True,
                                      console=Console(file=self.stream, highlight=False))
                self._live.start()
            task = self._live.add_task(description, total=total)
        self._stack.append((task, total))

    def _log(self, line: str) -> None:
        self.stream.write(line)
        self.stream.flush()

    def update(self, done: float) -> None:
        if self._stack and self._live is not None:
            self._live.update(self._stack[-1][0], completed=done)

    def end(self) -> None:
        if not self._stack:
            return
        task, total = self._stack.pop()
        if isinstance(task, threading.Timer):
            task.cancel()  # a stage done within LOG_AFTER gets no line
            task.join()  # (or its line is out before what follows the stage)
            return
        if self._live is None:
            return
        if total is not None:  # the last frame of a countable stage is its 100 %
            self._live.update(task, completed=total)
            self._live.refresh()
        self._live.remove_task(task)
        if not self._stack:
            self._live.stop()
            self._live = None

    def close(self) -> None:
        """End every stage still under way (the display is erased)."""
        while self._stack:
            self.end()
