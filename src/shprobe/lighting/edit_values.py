"""The values of the lighting-edit language (`shprobe.lighting.edits`): numbers, vectors,
colours, (l, m) keys and lists, read alike from command-line text and from JSON, each checked
(finite, at most `MAX_VALUE` in size, the right count) with one-line errors."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import ShprobeError

#: Largest magnitude of any number in an edit (weights, factors, colours, angles): large
#: enough for any lighting, small enough that a chain of edits stays finite.
MAX_VALUE = 1e9
#: Most entries of one repeatable edit (lights, scales, blends, rotations).
MAX_ITEMS = 256

Floats = tuple[float, ...]


def number(v: Any, what: str) -> float:
    """One finite number of at most `MAX_VALUE` in size (JSON number or text)."""
    if isinstance(v, bool) or not isinstance(v, int | float | str | np.floating | np.integer):
        raise ShprobeError(f"{what} must be a number, got {shown(v)}")
    try:
        x = float(v)
    except (ValueError, OverflowError):
        raise ShprobeError(f"{what} must be a number, got {shown(v)}") from None
    if not math.isfinite(x) or abs(x) > MAX_VALUE:
        raise ShprobeError(f"{what} must be a finite number of at most {MAX_VALUE:g} in size, "
                           f"got {shown(v)}")
    return x


def numbers(v: Any, what: str, counts: tuple[int, ...]) -> Floats:
    """A list of numbers (JSON list, a single number, or 'a,b,c' text) whose length is one of
    ``counts``."""
    if isinstance(v, str):
        parts: Sequence[Any] = [s for s in v.split(",")] if v.strip() else []
    elif isinstance(v, list | tuple):
        parts = v
    else:
        parts = [v]
    if len(parts) not in counts:
        want = " or ".join(str(c) for c in counts)
        raise ShprobeError(f"{what} must be {want} numbers, got {shown(v)}")
    return tuple(number(x.strip() if isinstance(x, str) else x, what) for x in parts)


def vector(v: Any, what: str) -> Floats:
    d = numbers(v, what, (3,))
    if not any(d):
        raise ShprobeError(f"{what} must be a non-zero vector")
    return d


def colour(v: Any, what: str) -> Floats:
    return numbers(v, what, (1, 3))


def shown(v: Any) -> str:
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


def integer(v: Any, what: str) -> int:
    """An integer (JSON integer, or short text of digits)."""
    if isinstance(v, str):
        t = v.strip()
        if not re.fullmatch(r"[-+]?[0-9]{1,4}", t):
            raise ShprobeError(f"{what} must be an integer, got {shown(v)}")
        return int(t)
    if isinstance(v, bool) or not isinstance(v, int | np.integer) or abs(int(v)) > 9999:
        raise ShprobeError(f"{what} must be an integer, got {shown(v)}")
    return int(v)


def lm_key(v: Any, what: str) -> tuple[int, int]:
    parts = str(v).split(",") if isinstance(v, str) else None
    if parts is None or len(parts) != 2:
        raise ShprobeError(f"{what} must be 'l,m', got {shown(v)}")
    return integer(parts[0], what), integer(parts[1], what)


def items(v: Any, what: str) -> list[Any]:
    if v is None:
        return []
    if not isinstance(v, list | tuple):
        raise ShprobeError(f"{what} must be a list, got {shown(v)}")
    if len(v) > MAX_ITEMS:
        raise ShprobeError(f"{what}: at most {MAX_ITEMS} entries, got {len(v)}")
    return list(v)


def obj(v: Any, what: str, keys: Sequence[str]) -> dict[str, Any]:
    if not isinstance(v, dict):
        raise ShprobeError(f"{what} must be an object, got {shown(v)}")
    unknown = [str(k)[:20] for k in v if k not in keys]
    if unknown:
        raise ShprobeError(f"{what} has unknown keys: {', '.join(sorted(unknown))}")
    return v


def num_text(x: float) -> str:
    return repr(float(x))


def nums_text(xs: Sequence[float]) -> str:
    return ",".join(num_text(x) for x in xs)
