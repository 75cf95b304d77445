"""The one exception type shprobe raises for bad input."""

from __future__ import annotations

import os


class ShprobeError(ValueError):
    """Bad input or a refused operation.

    The CLI prints it as one line, ``shprobe: error: <path>: <message>``, and exits non-zero
    without a traceback. ``path`` names the file concerned, where there is one.

    Parameters
    ----------
    message
        One line saying what is wrong.
    path
        The file concerned, where there is one.
    """

    def __init__(self, message: str, path: str | os.PathLike[str] | None = None) -> None:
        self.message = message
        self.path = None if path is None else os.fspath(path)
        super().__init__(str(self))

    def __str__(self) -> str:
        return f"{self.path}: {self.message}" if self.path else self.message
