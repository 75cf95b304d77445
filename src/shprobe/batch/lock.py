"""One batch per output at a time, and a Ctrl-C that always ends a batch.

Two batches writing one table would each merge their own rows and the last to finish would
drop the other's: `output_lock` lets one hold the output and refuses the other in one
line. `interruptible` records SIGINT so that the batch loop ends even when a library on
the way (Dask's client) caught the KeyboardInterrupt.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ..errors import ShprobeError

__all__ = ["interruptible", "lock_path", "output_lock"]


def lock_path(output: str | os.PathLike[str]) -> Path:
    """The lock file of ``output`` while a batch writes it: ``<output>.lock``."""
    p = Path(output)
    return p.with_name(p.name + ".lock")


@contextmanager
def output_lock(output: Path | None) -> Iterator[None]:
    """Hold ``output`` for this batch: an exclusive ``flock`` on `lock_path` (released by
    the kernel when the process ends, however it ends, so a killed batch leaves no stale
    lock); another batch on the same output is refused in one line naming the process that
    holds it. Nothing for ``None``."""
    if output is None:
        yield
        return
    try:
        import fcntl
    except ImportError:  # not POSIX (Windows): no advisory locks; one batch per output by hand
        yield
        return
    lock = lock_path(output)
    try:
        lock.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ShprobeError(f"cannot make folder {lock.parent}: {e.strerror or e}",
                           output) from None
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
        except OSError as e:
            raise ShprobeError(f"cannot make its lock file {lock.name}: {e.strerror or e}",
                               output) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.read(fd, 32).decode("ascii", "replace").strip() or "?"
            os.close(fd)
            raise ShprobeError(f"is being written by another shprobe batch (process {holder}, "
                               f"lock {lock.name}); wait for it or choose another output",
                               output) from None
        try:  # the holder before us may have removed the file we opened: lock the one there
            if os.path.samestat(os.fstat(fd), os.stat(lock, follow_symlinks=False)):
                break
        except FileNotFoundError:
            pass
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        yield
    finally:
        try:
            os.unlink(lock)
        except OSError:
            pass
        os.close(fd)


@contextmanager
def interruptible() -> Iterator[list[int]]:
    """Ctrl-C (SIGINT) raises KeyboardInterrupt as usual and is also recorded in the yielded
    list, which the batch loop checks after every row: an interrupt that Dask's client code
    caught on its way (in a callback, a thread) still ends the batch (the CLI exits 130)."""
    import signal
    import threading

    got: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield got
        return

    def on_int(signum: int, frame: Any) -> None:
        got.append(signum)
        raise KeyboardInterrupt

    try:
        prev = signal.signal(signal.SIGINT, on_int)
    except ValueError:
        yield got
        return
    try:
        yield got
    finally:
        signal.signal(signal.SIGINT, prev)
