"""Safe output files: written to a temporary name beside the target, then renamed.

Nothing is half-written and an existing file is only replaced when the caller asks.
"""

from __future__ import annotations

import json
import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ShprobeError


def read_text(path: str | os.PathLike[str], what: str = "text file") -> str:
    """The UTF-8 text of an input file, or one line naming it (missing, a folder, unreadable,
    not text)."""
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


def check_output_path(path: str | os.PathLike[str], overwrite: bool = False) -> Path:
    """Refuse an existing file unless ``overwrite``; refuse a missing parent folder."""
    p = Path(path)
    if p.is_dir():
        raise ShprobeError("is a directory, not a file", p)
    if p.exists() and not overwrite:
        raise ShprobeError("already exists (pass --force / overwrite=True to replace it)", p)
    if not p.parent.exists():
        raise ShprobeError(f"folder {p.parent} does not exist", p)
    return p


@contextmanager
def atomic_output(path: str | os.PathLike[str], overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (same suffix); rename it to ``path`` on success.

    On any error the temporary file is removed and ``path`` is left as it was.
    """
    p = check_output_path(path, overwrite)
    tmp = p.with_name(f".{p.stem}.tmp-{os.getpid()}-{secrets.token_hex(4)}{p.suffix}")
    try:
        yield tmp
        if not tmp.exists():
            raise ShprobeError("nothing was written", p)
        if p.exists() and not overwrite:  # appeared meanwhile
            raise ShprobeError("already exists (pass --force / overwrite=True to replace it)", p)
        os.replace(tmp, p)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_text(path: str | os.PathLike[str], text: str, overwrite: bool = False) -> Path:
    """Write ``text`` atomically."""
    with atomic_output(path, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_json(path: str | os.PathLike[str], obj: Any, overwrite: bool = False) -> Path:
    """Write ``obj`` as indented JSON atomically."""
    return write_text(path, json.dumps(obj, indent=2) + "\n", overwrite)


def save_npz(path: str | os.PathLike[str], overwrite: bool = False, **arrays: Any) -> Path:
    """``np.savez_compressed`` atomically."""
    with atomic_output(path, overwrite) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **arrays)
    return Path(path)
