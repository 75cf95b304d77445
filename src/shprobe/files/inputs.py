"""Input files checked before reading: text read as UTF-8, and inputs that must be regular
files (a FIFO, a device or a folder refused at once, never waited on)."""

from __future__ import annotations

import os
import stat

from ..errors import ShprobeError


def read_text(path: str | os.PathLike[str], what: str = "text file") -> str:
    """The UTF-8 text of an input file, or one line naming it (missing, folder, not text)."""
    p = os.fspath(path)
    try:
        with open(p, encoding="utf-8") as f:
            return f.read()
    except FileNotFoundError:
        raise ShprobeError("no such file", p) from None
    except IsADirectoryError:
        raise ShprobeError("is a directory, not a file", p) from None
    except UnicodeDecodeError:
        raise ShprobeError(f"not a {what}", p) from None
    except OSError as e:
        raise ShprobeError(f"cannot read: {e.strerror or e}", p) from None


def regular_file(path: str | os.PathLike[str], what: str = "file") -> os.stat_result:
    """The ``stat`` of an input that must be a regular file, or one line naming it: a FIFO,
    a device (``/dev/zero``), a socket or a folder is refused at once (reading one would
    block forever or never end).

    Parameters
    ----------
    path : str or os.PathLike
        The input file (links are followed).
    what : str
        What the file should be, for the messages ("splat file", "probe").

    Returns
    -------
    os.stat_result
        The file's status.
    """
    p = os.fspath(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise ShprobeError(f"no such {what}", p) from None
    except OSError as e:
        raise ShprobeError(f"cannot read: {e.strerror or e}", p) from None
    if stat.S_ISDIR(st.st_mode):
        raise ShprobeError("is a directory, not a file", p)
    if not stat.S_ISREG(st.st_mode):
        raise ShprobeError(f"is not a regular file (a device, pipe or socket): a {what} must "
                           "be a file", p)
    return st


def open_regular(path: str | os.PathLike[str], what: str = "file"):
    """Open an input for binary reading once [`regular_file`][shprobe.files.regular_file] accepts
    it, without blocking and checked again on the descriptor (a FIFO swapped in is never waited on).

    Parameters
    ----------
    path : str or os.PathLike
        The input file.
    what : str
        What the file should be, for the messages.

    Returns
    -------
    io.BufferedReader
        The open file.
    """
    p = os.fspath(path)
    regular_file(p, what)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as e:
        raise ShprobeError(f"cannot read: {e.strerror or e}", p) from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise ShprobeError(f"is not a regular file: a {what} must be a file", p)
    return open(fd, "rb")
