"""The page's lighting design: the edit-state JSON read as the library's
[`EditSpec`][shprobe.lighting.EditSpec] (`read_state`, the one check of what the page
sends) and applied by the library's edit pipeline — exactly (`design_coeffs`, what
exports use) or, during a drag, from a cache of everything the rotation does not change
(`Designer`)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..lighting.edits import Blend, EditSpec

__all__ = ["DESIGN_LMAX", "Designed", "Designer", "design_coeffs", "read_state"]

#: highest degree of a design: the page's menu offers 0..MAX_LMAX; a PRT transfer's baked
#: degree, capped at this, sets a higher one (drawn per pixel by a second generated GLSL
#: function to this degree)
DESIGN_LMAX = 8

#: (blend, lmax) → its coefficients (the session's presets and loaded probes)
Blends = Callable[[Blend, int], NDArray[np.float64]]
#: lmax → the coefficients the edits start from
Base = Callable[[int], NDArray[np.float64]]


def read_state(doc: Any) -> EditSpec:
    """The page's edit state (parsed JSON) as a spec, checked once: one-line
    [`ShprobeError`][shprobe.errors.ShprobeError] on anything malformed
    ([`EditSpec.from_json`][shprobe.lighting.EditSpec.from_json], degrees up to `DESIGN_LMAX`)."""
    spec = EditSpec.from_json(doc, max_lmax=DESIGN_LMAX)  # unknown keys, ranges: first
    _no_text_numbers(doc)
    return spec


#: where the edit-state JSON holds text: the window, a blend's preset or probe, an "l,m" to
#: negate; everywhere else a value is a JSON number (the command line's text forms, which
#: the edit language also reads, are not JSON's)
_TEXT_AT = {("window",), ("blends", "*", "preset"), ("blends", "*", "probe"), ("negate", "*")}


def _no_text_numbers(doc: Any, at: tuple[str, ...] = ()) -> None:
    """Refuse (one line) a string where the edit state wants a number: ``{"lmax": "2"}``."""
    from ..errors import ShprobeError

    if isinstance(doc, dict):
        for k, v in doc.items():
            # table keys ("l,m", "l") are text by design: their values are numbers
            _no_text_numbers(v, (*at, "*" if at and at[-1] in _TABLES else str(k)))
    elif isinstance(doc, list):
        for v in doc:
            _no_text_numbers(v, (*at, "*"))
    elif isinstance(doc, str) and at and at not in _TEXT_AT:
        name = ".".join(a for a in at if a != "*") or "value"
        shown = doc if len(doc) <= 20 else doc[:17] + "..."
        raise ShprobeError(f"edit state: {name} must be a JSON number, not the text "
                           f"{shown!r}")


#: the edit state's tables, keyed by text: {"l,m": value} or {"l": value}
_TABLES = ("scale", "set", "scale_band", "set_band")


def design_coeffs(base: NDArray[np.float64] | None, spec: EditSpec, blends: Blends
                  ) -> tuple[NDArray[np.float64], str | None]:
    """(L_lm (K, 3), window description): ``spec`` applied to ``base`` by the library's edit
    pipeline (`edit_lighting`), as ``shprobe edit`` applies
    it — so an export from the page equals the CLI's file."""
    from ..lighting.design import edit_lighting

    res = edit_lighting(base, spec, blends)
    return res.coeffs, res.window


@dataclass(frozen=True)
class Designed:
    """One design for the page: the coefficients, the window's description and factors, the
    min-E certificate, and the edits before the rotation (which the page turns itself while
    dragging at lmax ≤ 2)."""

    coeffs: NDArray[np.float64]
    window: str | None
    minimum: Any
    unrotated: NDArray[np.float64]
    factors: NDArray[np.float64] | None

    def __repr__(self) -> str:
        return f"Designed(K={self.coeffs.shape[0]}, window={self.window!r})"


def _auto_desc(ch: Any) -> str:
    """How the page names an ``auto_window`` choice."""
    return f"auto -> {ch.kind}" + (
        f" {ch.strength:.4g}, bias {100 * ch.bias:.2f}%" if ch.kind != "none" else "")


class Designer:
    """The page's designs, fast during a drag: everything but the rotation is cached per
    (source, spec without rotation) — the edits before it, the window factors (``auto``:
    chosen on the unrotated lighting) and [`min_irradiance`][shprobe.lighting.min_irradiance],
    all invariant under rotation — so a drag step is one Wigner rotation."""

    KEEP = 64

    def __init__(self) -> None:
        self._cache: dict[tuple[int, EditSpec], tuple[Any, ...]] = {}
        self._lock = threading.Lock()

    def design(self, source: object, base: Base, spec: EditSpec, blends: Blends) -> Designed:
        from ..lighting.design import edit_lighting, rotate_lighting
        from ..lighting.windows import apply_window, auto_window, min_irradiance, window_factors

        key = (id(source), spec.unrotated())
        with self._lock:
            hit = self._cache.get(key)
        if hit is None or hit[0] is not source:
            L0 = edit_lighting(base(spec.lmax), spec.unrotated(), blends).coeffs
            f, wdesc = None, None
            if spec.window == "auto":
                ch = auto_window(L0)
                f, wdesc = ch.factors, _auto_desc(ch)
            elif spec.window is not None:
                kind, strength = spec.window
                f = window_factors(kind, spec.lmax, strength)
                wdesc = f"{kind}:{strength!r}"
            cert = min_irradiance(L0 if f is None else apply_window(L0, f))
            hit = (source, L0, f, wdesc, cert)
            with self._lock:
                if len(self._cache) > self.KEEP:
                    self._cache.clear()
                self._cache[key] = hit
        _, L0, f, wdesc, cert = hit
        L = rotate_lighting(L0, spec.rotation_matrix()) if spec.rotations else L0
        return Designed(L if f is None else apply_window(L, f), wdesc, cert, L0, f)
