"""The names of exported lighting files: ``<source>-<edit>-lmax<N><suffix>``, one function for
``shprobe edit`` / ``shprobe export`` (their file when ``-o`` is left out or names a folder) and
the viewer's downloads, so that the same export has the same name wherever it is made.

* ``<source>``: the lighting's name without folder or extension (``grace`` for
  ``probes/grace.hdr``), ``preset-NAME`` for a preset, ``darkness`` for none.
* ``<edit>``: ``sh`` for the projection unedited; else the edit steps present, in the order the
  pipeline applies them (``weight``, ``blend``, ``lights``, ``coeffs``, ``rotated``, ``window``),
  then six hex digits of the SHA-256 of the equivalent ``shprobe edit`` arguments (blended files
  by their file name alone, the degree left out): two different edits get different names, the
  same edit the same name, wherever it is made.
* ``lmax<N>``: the degree of the result; ``<suffix>`` the format's
  (`shprobe.lighting.export.SUFFIX`).

Only ``[A-Za-z0-9._-]`` reach the name (anything else becomes ``-``): it is safe in every file
system, shell and HTTP header.
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Mapping
from dataclasses import replace

from ..errors import ShprobeError
from .edits import Blend, EditSpec
from .export import SUFFIX

__all__ = ["edit_tag", "export_name", "source_stem"]

#: longest ``<source>`` part kept
MAX_STEM = 48


def source_stem(source: str | None) -> str:
    """The ``<source>`` part: the lighting's name as `resolve_lighting` and the viewer give it (a
    path, ``preset:NAME``, six cube faces as ``FIRST … LAST (cube faces)``), reduced to a file-name
    stem."""
    s = (source or "").strip()
    if not s:
        return "darkness"
    if s.startswith("preset:"):
        return _safe("preset-" + s[7:])
    first, sep, _ = s.partition(" … ")  # six cube faces: named by the first
    stem = os.path.basename(first.replace("\\", "/"))
    stem, ext = os.path.splitext(stem)
    if ext.lower() in (".gz", ".bz2", ".xz", ".zst"):
        stem = os.path.splitext(stem)[0]
    return _safe(stem + ("-cube" if sep else "")) or "lighting"


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._]+", "-", text).strip("-.")[:MAX_STEM].strip("-.")


def edit_tag(spec: EditSpec, probe_names: Mapping[str, str] | None = None) -> str:
    """The ``<edit>`` part of ``spec``: ``sh`` when it edits nothing, else its steps and six hex
    digits of its canonical command-line form (``probe_names``: the files of the viewer's
    blended probe ids)."""
    steps = [name for name, on in (
        ("weight", spec.weight != 1.0),
        ("blend", bool(spec.blends)),
        ("lights", bool(spec.directional or spec.cones or spec.sky is not None)),
        ("coeffs", bool(spec.sets or spec.scales or spec.negates or spec.set_bands
                        or spec.scale_bands or spec.negate_bands)),
        ("rotated", bool(spec.rotations)),
        ("window", spec.window is not None)) if on]
    if not steps:
        return "sh"
    blends = tuple(Blend("file", os.path.basename(_blend_file(b, probe_names)), b.weight)
                   if b.kind != "preset" else b for b in spec.blends)
    args = replace(spec, blends=blends).to_text()[2:]  # without "--lmax N"
    digest = hashlib.sha256("\0".join(args).encode()).hexdigest()[:6]
    return "_".join([*steps, digest])


def _blend_file(b: Blend, probe_names: Mapping[str, str] | None) -> str:
    if b.kind == "probe":
        name = (probe_names or {}).get(b.name)
        if name is None:
            raise ShprobeError(f"blend probe {b.name} is not loaded (load it again)")
        return name
    return b.name


def export_name(source: str | None, spec: EditSpec, fmt: str,
                probe_names: Mapping[str, str] | None = None) -> str:
    """``<source>-<edit>-lmax<N><suffix>``: the file name of ``spec`` applied to ``source``
    exported as ``fmt`` (module docstring)."""
    if fmt not in SUFFIX:
        raise ShprobeError(f"unknown export format {fmt!r}; choose one of {', '.join(SUFFIX)}")
    return f"{source_stem(source)}-{edit_tag(spec, probe_names)}-lmax{spec.lmax}{SUFFIX[fmt]}"
