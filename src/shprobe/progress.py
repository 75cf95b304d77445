"""The one progress protocol: library code reports, the CLI (or the viewer) shows.

A long job is a sequence of *stages*; each stage has a description and, where the work is
countable, a total. Library functions take ``progress: Progress | None`` and report through it:

    with stage(progress, "tracing rays", total=n, index=2, count=3) as bar:
        for chunk in chunks:
            ...
            bar.advance(len(chunk))

or wrap an iterable with [`track`][shprobe.progress.track]. ``index``/``count`` make the description
read "2/3: tracing rays". Nothing here draws: `shprobe.cli.progress` builds the one terminal
bar (rich on a terminal, one plain line per stage otherwise) and the viewer forwards the same
calls to the page. ``None`` means quiet.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import Protocol, TypeVar, runtime_checkable

T = TypeVar("T")


@runtime_checkable
class Progress(Protocol):
    """What a reporter implements: one stage at a time."""

    def begin(self, description: str, total: float | None = None) -> None:
        """A stage starts; ``total`` is its amount of work when countable (else None).

        Parameters
        ----------
        description
            What the stage does.
        total
            Its amount of work, when countable.
        """

    def update(self, done: float) -> None:
        """Work done so far in the stage under way (absolute, not an increment).

        Parameters
        ----------
        done
            The work done so far in the stage (absolute).
        """

    def end(self) -> None:
        """The stage under way is finished (shown at 100 %, or removed)."""


def label(description: str, index: int | None = None, count: int | None = None) -> str:
    """'k/N: description' when the stage's place is known, else the description.

    Parameters
    ----------
    description
        What the stage does.
    index, count
        The stage's place, when known.

    Returns
    -------
    str
        "k/N: description", or the description.
    """
    if index is not None and count is not None:
        return f"{index}/{count}: {description}"
    return description


class Numbered:
    """A reporter that shows another's stages as "k/N: …": for a library call whose stage is
    one step of its caller's sequence (``reference_irradiance(..., progress=Numbered(p, 3,
    3))``)."""

    __slots__ = ("count", "index", "progress")

    def __init__(self, progress: Progress, index: int, count: int) -> None:
        self.progress, self.index, self.count = progress, int(index), int(count)

    def begin(self, description: str, total: float | None = None) -> None:
        self.progress.begin(label(description, self.index, self.count), total)

    def update(self, done: float) -> None:
        self.progress.update(done)

    def end(self) -> None:
        self.progress.end()


def numbered(progress: Progress | None, index: int, count: int) -> Progress | None:
    """``progress`` with its stages labelled "index/count: …" (None stays None).

    Parameters
    ----------
    progress
        A reporter, or None.
    index, count
        The place its stages are labelled with.

    Returns
    -------
    Progress or None
        The labelling reporter.
    """
    return None if progress is None else Numbered(progress, index, count)


class Prefixed:
    """A reporter that shows another's stages as "<prefix>: …": for a call that is one named
    part of its caller's job (one bake among several: "final bake: tracing rays")."""

    __slots__ = ("prefix", "progress")

    def __init__(self, progress: Progress, prefix: str) -> None:
        self.progress, self.prefix = progress, str(prefix)

    def begin(self, description: str, total: float | None = None) -> None:
        self.progress.begin(f"{self.prefix}: {description}", total)

    def update(self, done: float) -> None:
        self.progress.update(done)

    def end(self) -> None:
        self.progress.end()


def prefixed(progress: Progress | None, prefix: str) -> Progress | None:
    """``progress`` with its stages labelled "prefix: …" (None stays None).

    Parameters
    ----------
    progress
        The reporter, or None (quiet).
    prefix
        What every stage's description starts with.

    Returns
    -------
    Progress or None
        The labelling reporter, or None.
    """
    return None if progress is None else Prefixed(progress, prefix)


class Stage:
    """Handle on the stage under way: counts work done and forwards it to the reporter."""

    __slots__ = ("_done", "_progress")

    def __init__(self, progress: Progress | None) -> None:
        self._progress = progress
        self._done = 0.0

    def advance(self, amount: float = 1) -> None:
        """Add ``amount`` to the work done.

        Parameters
        ----------
        amount
            Work done since the last call.
        """
        self._done += amount
        if self._progress is not None:
            self._progress.update(self._done)

    def set(self, done: float) -> None:
        """Set the work done (for callers that know the absolute count).

        Parameters
        ----------
        done
            The work done so far (absolute).
        """
        self._done = float(done)
        if self._progress is not None:
            self._progress.update(self._done)


@contextmanager
def stage(progress: Progress | None, description: str, total: float | None = None, *,
          index: int | None = None, count: int | None = None) -> Iterator[Stage]:
    """Report one stage; the stage ends when the block does, also on an error.

    Parameters
    ----------
    progress
        A reporter, or None (nothing is reported).
    description
        What the stage does.
    total
        Its units of work, when known.
    index, count
        Its place among the job's stages.

    Yields
    ------
    Stage
        Advance it with ``update(done)``.
    """
    if progress is not None:
        progress.begin(label(description, index, count), total)
    try:
        yield Stage(progress)
    finally:
        if progress is not None:
            progress.end()


def track(items: Iterable[T], progress: Progress | None, description: str,
          total: int | None = None, *, index: int | None = None,
          count: int | None = None) -> Iterator[T]:
    """Yield ``items`` as one stage, one unit of work per item.

    Parameters
    ----------
    items
        The work items.
    progress
        A reporter, or None.
    description
        What the stage does.
    total
        The number of items, when ``items`` has no length.
    index, count
        Its place among the job's stages.

    Yields
    ------
    object
        The items, in order.
    """
    if total is None and hasattr(items, "__len__"):
        total = len(items)  # type: ignore[arg-type]
    with stage(progress, description, total, index=index, count=count) as bar:
        for item in items:
            yield item
            bar.advance(1)


class Steps:
    """The stages of one job in sequence, "1/N: …" to "N/N: …", for code that reads better as
    a list of steps than as nested blocks::

        with Steps(progress, 3) as step:
            step("reading the mesh")
            ...
            bar = step("tracing rays", total=n)
            ...

    Each call ends the stage before it and begins the next (returning its
    [`Stage`][shprobe.progress.Stage]); leaving the block ends the last one, also on an error.
    """

    def __init__(self, progress: Progress | None, count: int) -> None:
        self.progress, self.count, self.index = progress, int(count), 0
        self._open = False

    def __call__(self, description: str, total: float | None = None) -> Stage:
        self.close()
        self.index += 1
        if self.progress is not None:
            self.progress.begin(label(description, self.index, self.count), total)
            self._open = True
        return Stage(self.progress)

    def close(self) -> None:
        """End the stage under way, if any."""
        if self._open and self.progress is not None:
            self.progress.end()
        self._open = False

    def __enter__(self) -> Steps:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Recorder:
    """A reporter that keeps every call, for tests and for forwarding (the viewer)."""

    def __init__(self) -> None:
        self.events: list[tuple[str, object, object]] = []

    def begin(self, description: str, total: float | None = None) -> None:
        self.events.append(("begin", description, total))

    def update(self, done: float) -> None:
        self.events.append(("update", done, None))

    def end(self) -> None:
        self.events.append(("end", None, None))

    @property
    def stages(self) -> list[str]:
        """The descriptions of the stages begun, in order."""
        return [str(d) for kind, d, _ in self.events if kind == "begin"]


class Fraction:
    """A reporter that hands the fraction done of the outermost countable stage to
    ``report(fraction)``, for a display that shows one number (a server's task state)."""

    def __init__(self, report: Callable[[float], None]) -> None:
        self.report = report
        self._totals: list[float | None] = []

    def begin(self, description: str, total: float | None = None) -> None:
        self._totals.append(total)

    def update(self, done: float) -> None:
        if len(self._totals) == 1 and self._totals[0]:
            self.report(min(1.0, done / self._totals[0]))

    def end(self) -> None:
        if self._totals:
            self._totals.pop()
