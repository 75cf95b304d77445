"""Cost estimates before work: every command and public function that could allocate a lot
estimates the bytes it needs from its arguments and file headers and refuses, in one line
naming the estimate and the limit, what would not fit.

The limit is a [`Limits`][shprobe.limits.Limits] object: its ``max_memory`` (bytes), else the
machine's available memory (``/proc/meminfo`` MemAvailable, else total physical memory) less a
margin, or ``SHPROBE_MAX_MEMORY`` (bytes, or with a K/M/G/T suffix) when that is lower. A workflow
takes its limits in its settings (``PrtSettings(limits=Limits(max_memory=2 << 30))``) and
applies them to everything it calls with [`Limits.applied`][shprobe.limits.Limits.applied]; the CLI
builds one from ``--max-memory``. Work that is naturally chunked stays under
[`CHUNK_BYTES`][shprobe.limits.CHUNK_BYTES] per chunk instead of being refused.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Any

from .errors import ShprobeError

__all__ = ["CHUNK_BYTES", "LONG_JOB_SECONDS", "MAX_PAIRS", "Cost", "Limits", "check_disk",
           "check_memory", "check_pairs",
           "cores", "format_bytes", "format_seconds", "memory_limit", "pairs_limit",
           "parse_bytes"]

#: Working-set target of one chunk of chunked work (samples, rows, normals).
CHUNK_BYTES = 64 << 20

_UNITS = {"": 1, "B": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}


def parse_bytes(text: str) -> int:
    """'512M', '2G', '1.5GiB', '1000000' → bytes.

    Parameters
    ----------
    text
        A size such as "512M", "2G", "1.5GiB" or "1000000".

    Returns
    -------
    int
        Bytes.
    """
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([KMGT]?)(?:i?B)?\s*", str(text), re.I)
    if not m:
        raise ShprobeError(f"cannot parse memory size {text!r}: expected e.g. 512M or 4G")
    return int(float(m.group(1)) * _UNITS[m.group(2).upper()])


def format_bytes(n: float) -> str:
    """Bytes for people: 1.5 GB, 300 MB, 12 kB.

    Parameters
    ----------
    n
        Bytes.

    Returns
    -------
    str
        e.g. "1.5 GB".
    """
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if abs(n) >= size:
            return f"{n / size:.3g} {unit}"
    return f"{int(n)} B"


def _available() -> int:
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return 8 << 30


@dataclass(frozen=True)
class Limits:
    """How much one operation may use: refused beforehand, in one line, when its estimate
    is over.

    Parameters
    ----------
    max_memory
        Bytes one operation may plan for; None: 80 % of the available memory (lowered by
        ``SHPROBE_MAX_MEMORY`` when set). A value above the available memory's 80 % does not
        raise the limit.
    """

    max_memory: int | None = None

    def __post_init__(self) -> None:
        m = self.max_memory
        if m is not None and (isinstance(m, bool) or not isinstance(m, int) or m <= 0):
            raise ShprobeError(f"max_memory must be a positive number of bytes, got {m!r}")

    @classmethod
    def parse(cls, max_memory: str | int | None) -> Limits:
        """Limits from a size as people write it ('2G', '512M', bytes) or None.

        Parameters
        ----------
        max_memory
            The memory limit ('512M', '2G', a number of bytes) or None (the default).

        Returns
        -------
        Limits
            The limits.
        """
        return cls(None if max_memory is None else parse_bytes(str(max_memory)))

    def memory(self) -> int:
        """Bytes one operation may allocate.

        Returns
        -------
        int
            80 % of the available memory, or ``max_memory`` / ``SHPROBE_MAX_MEMORY`` when
            set and lower.
        """
        limit = int(0.8 * _available())
        env = os.environ.get("SHPROBE_MAX_MEMORY")
        if env:
            limit = min(limit, parse_bytes(env))
        if self.max_memory is not None:
            limit = min(limit, int(self.max_memory))
        return limit

    @contextmanager
    def applied(self) -> Iterator[Limits]:
        """Apply these limits to every check made inside the block (in this thread or task),
        also by the functions a workflow calls without passing them on.

        Returns
        -------
        contextmanager
            A context manager yielding these limits.
        """
        token = _ACTIVE.set(self)
        try:
            yield self
        finally:
            _ACTIVE.reset(token)

    def as_dict(self) -> dict[str, Any]:
        """The limits as JSON-able values.

        Returns
        -------
        dict
            ``{"max_memory": bytes or None}``.
        """
        return {"max_memory": self.max_memory}


#: The limits in force (:meth:`Limits.applied`): a context variable, so a limit applied by
#: one call or thread never reaches another.
_ACTIVE: ContextVar[Limits | None] = ContextVar("shprobe_limits", default=None)


def active_limits() -> Limits:
    """The limits applied by the innermost [`Limits.applied`][shprobe.limits.Limits.applied] block,
    else the defaults.

    Returns
    -------
    Limits
        The limits in force.
    """
    return _ACTIVE.get() or Limits()


def memory_limit(limits: Limits | None = None) -> int:
    """Bytes one operation may allocate ([`Limits.memory`][shprobe.limits.Limits.memory] of
    ``limits``, else of the limits in force).

    Parameters
    ----------
    limits
        The limits to read; None: `active_limits`.

    Returns
    -------
    int
        The limit in bytes.
    """
    return (limits or active_limits()).memory()


def check_memory(nbytes: float, what: str, where: Any = None,
                 limits: Limits | None = None) -> None:
    """Refuse ``what`` when its estimated ``nbytes`` exceed
    [`memory_limit`][shprobe.limits.memory_limit].

    Parameters
    ----------
    nbytes
        The estimate, in bytes.
    what
        The work, as the refusal names it.
    where
        The file concerned, if any.
    limits
        The limits to check against; None: the limits in force.
    """
    limit = memory_limit(limits)
    if nbytes > limit:
        raise ShprobeError(
            f"{what} would need about {format_bytes(nbytes)}, over the limit of "
            f"{format_bytes(limit)} (available memory, or the max_memory limit)",
            where)


def check_disk(folder: str | os.PathLike[str], nbytes: float, what: str,
               where: Any = None) -> None:
    """Refuse ``what`` when the file system of ``folder`` (or of its nearest existing parent:
    folders are made later) has less than ``nbytes`` free, before any work or output.

    Parameters
    ----------
    folder : str or os.PathLike
        Where the output goes.
    nbytes : float
        The output's estimated size in bytes.
    what : str
        The output, for the message.
    where : str or os.PathLike, optional
        The file named in the message.
    """
    path = os.path.abspath(os.fspath(folder))
    while not os.path.isdir(path) and os.path.dirname(path) != path:
        path = os.path.dirname(path)
    try:
        st = os.statvfs(path)
    except (OSError, AttributeError):  # cannot tell: the write itself will say
        return
    free = st.f_bavail * st.f_frsize
    if nbytes > free:
        raise ShprobeError(f"{what} needs about {format_bytes(nbytes)} of disk, and {path} has "
                           f"{format_bytes(free)} free", where)


#: Brute-force work one call starts unasked, in normal × sample products (the exact
#: irradiance's hemisphere sums): minutes on the 2-core box's numba kernel.
#: ``SHPROBE_MAX_PAIRS`` raises (or lowers) it.
MAX_PAIRS = 2e11
#: Normal–sample products per second and core of the brute-force kernel (grace 256×128 and
#: 8000 normals: 0.37·10⁹ /s on 2 cores of a busy machine, so 2·10⁸ per core is the cautious
#: figure every time estimate uses).
PAIRS_PER_CORE_SECOND = 2e8


def pairs_limit() -> float:
    """Normal × sample products one call may start: [`MAX_PAIRS`][shprobe.limits.MAX_PAIRS], or
    ``SHPROBE_MAX_PAIRS`` (a number, e.g. 1e12) when set.

    Returns
    -------
    float
        Normal × sample products one call may start.
    """
    env = os.environ.get("SHPROBE_MAX_PAIRS")
    if env:
        try:
            value = float(env)
        except ValueError:
            raise ShprobeError(f"SHPROBE_MAX_PAIRS={env!r} is not a number (e.g. 1e12)") from None
        if not value > 0:
            raise ShprobeError(f"SHPROBE_MAX_PAIRS={env!r} must be positive")
        return value
    return MAX_PAIRS


def check_pairs(pairs: float, what: str, where: Any = None, smaller: str = "") -> None:
    """Refuse brute-force work of ``pairs`` normal × sample products over
    [`pairs_limit`][shprobe.limits.pairs_limit], in one line with the estimated time, what to make
    ``smaller`` and how to raise the limit.

    Parameters
    ----------
    pairs
        Normal × sample products.
    what
        The work, named in the error.
    where
        The file concerned, named in the error.
    smaller
        What to make smaller, said in the error.
    """
    limit = pairs_limit()
    if pairs > limit:
        raise ShprobeError(
            f"{what} would take {pairs:.2g} normal x sample products (about "
            f"{format_seconds(pairs / (PAIRS_PER_CORE_SECOND * cores()))}), "
            f"over the limit of {limit:.2g}: {smaller + ', or ' if smaller else ''}raise the "
            "limit with SHPROBE_MAX_PAIRS=N", where)


# ----------------------------------------------------------------------------- time

#: A job estimated to take longer than this says its estimate before it starts.
LONG_JOB_SECONDS = 30.0


def cores() -> int:
    """The cores this process may run on (the parallel kernels' threads).

    Returns
    -------
    int
        The cores available to this process.
    """
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def format_seconds(s: float) -> str:
    """Seconds for people: '40 s', '1½ min', '12 min', '2.5 h'.

    Parameters
    ----------
    s
        Seconds.

    Returns
    -------
    str
        e.g. "1½ min".
    """
    if s < 60:
        return f"{max(1, round(s))} s"
    if s < 600:
        halves = max(2, round(s / 30))
        whole, half = divmod(halves, 2)
        return f"{whole}{'½' if half else ''} min"
    if s < 3600 * 2:
        return f"{round(s / 60)} min"
    return f"{s / 3600:.1f} h"


@dataclass(frozen=True)
class Cost:
    """A job's estimate before it starts: seconds on this machine and peak bytes (the bytes
    are the figure the job's memory check refuses on).

    Attributes
    ----------
    seconds
        The estimated time on this machine.
    nbytes
        The estimated peak bytes.
    """

    seconds: float
    nbytes: float

    @property
    def long(self) -> bool:
        """Over [`LONG_JOB_SECONDS`][shprobe.limits.LONG_JOB_SECONDS]: say it before starting."""
        return self.seconds > LONG_JOB_SECONDS

    def __str__(self) -> str:
        return (f"about {format_seconds(self.seconds)} and {format_bytes(self.nbytes)} on "
                f"this machine ({cores()} cores)")
