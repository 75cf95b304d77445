"""A lighting edit as Python: the code that reproduces an [`EditSpec`][shprobe.lighting.EditSpec]
applied to a source with shprobe's public API — the viewer's "Copy as Python", beside the
equivalent ``shprobe edit`` command.

The code resolves the source as ``shprobe edit`` does
(`resolve_lighting`: a probe projected to the edit's degree, at
least 2, R&H 2001 eq. 10; presets and coefficient files as they are), builds the spec with its
fields written out (every number by ``repr``, so it round-trips exactly) and applies it with the
one edit pipeline (`edit_lighting`): it gives the same
coefficients as the command and the viewer, to the last bit. Blended probes are named by their
file (``probe_names``); the paths are as the caller gave them.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace

from ..errors import ShprobeError
from ..sh import num_coeffs
from .edits import Blend, EditSpec
from .filenames import export_name

__all__ = ["SnippetSource", "python_snippet"]


@dataclass(frozen=True)
class SnippetSource:
    """Where the snippet's lighting comes from: ``name`` as
    `resolve_lighting` names a source (a probe or coefficient
    file's path, ``preset:NAME``; None: darkness); ``image`` whether a file is a probe image
    (None: by its extension, as ``--blend`` decides); ``layout`` the probe's layout (None:
    detected); ``code`` a Python expression of the base coefficients at degree ``{lmax}``
    instead (a source with no file, such as the viewer's procedural sky)."""

    name: str | None = None
    image: bool | None = None
    layout: str | None = None
    code: str | None = None


def _is_image(name: str) -> bool:
    from ..probes.images import READ_EXTENSIONS

    return os.path.splitext(name)[1].lower() in READ_EXTENSIONS


def _base(src: SnippetSource, lmax: int) -> tuple[str, str]:
    """(the line setting ``base``, its comment)."""
    degree = max(lmax, 2)
    if src.code is not None:
        return f"base = {src.code.format(lmax=degree)}", f"{src.name or 'the source'}"
    if not src.name:
        return "base = None", "darkness: the edits start from zero"
    if src.name.startswith("preset:"):
        return (f"base = resolve_lighting(preset={src.name[7:]!r}, lmax=None).coeffs",
                "an R&H 2001 preset (lmax 2; cut or zero-padded by the edit)")
    if " … " in src.name:
        raise ShprobeError("the six cube faces of this source are not known by name: load "
                           "them as one file, or write resolve_lighting([...six paths...])")
    image = _is_image(src.name) if src.image is None else src.image
    if not image:
        return (f"base = resolve_lighting(coeffs={src.name!r}, lmax=None).coeffs",
                "coefficients from a file (cut or zero-padded by the edit)")
    layout = "" if src.layout in (None, "auto") else f", layout={src.layout!r}"
    return (f"base = resolve_lighting({src.name!r}{layout}, lmax={degree}).coeffs",
            f"the probe projected to lmax {degree} (R&H 2001 eq. 10)")


def _spec_lines(spec: EditSpec) -> list[str]:
    """``EditSpec(...)`` with every field that differs from its default."""
    default = EditSpec()
    out = ["spec = EditSpec("]
    for f in fields(spec):
        v = getattr(spec, f.name)
        if f.name == "lmax" or v != getattr(default, f.name):
            out.append(f"    {f.name}={v!r},")
    out.append(")")
    return out


def python_snippet(spec: EditSpec, source: SnippetSource,
                   probe_names: Mapping[str, str] | None = None,
                   fmt: str | None = None) -> str:
    """Python code that reproduces ``spec`` applied to ``source`` with the library (module
    docstring); ``probe_names`` the files of the viewer's blended probe ids; ``fmt`` an export
    format: the code also writes that export under the viewer's download name."""
    names = probe_names or {}
    if any(b.kind == "probe" and b.name not in names for b in spec.blends):
        raise ShprobeError("a blended probe is not loaded (load it again)")
    spec = replace(spec, blends=tuple(Blend("file", names[b.name], b.weight)
                                      if b.kind == "probe" else b for b in spec.blends))
    blends = spec.blends
    base, why = _base(source, spec.lmax)
    layout = source.layout not in (None, "auto") and any(b.kind == "file" for b in blends)
    resolver = (f", lambda b, lmax: blend_lighting(b, lmax, {source.layout!r})"
                if layout else "")
    body = [
        f"# {why}",
        base,
        "# the edits, applied in this order: blend, lights, coefficients, bands, rotations, "
        "window",
        *_spec_lines(spec),
        f"L = edit_lighting(base, spec{resolver}).coeffs",
        f"# L: the lighting's coefficients L_lm, ({num_coeffs(spec.lmax)}, 3), shprobe's real "
        "SH (docs/conventions.md)",
    ]
    if fmt is not None:
        name = export_name(source.name, spec, fmt, names)
        body += [f"with open({name!r}, 'w') as f:",
                 f"    f.write(shprobe.export_coeffs(L, {fmt!r}, "
                 f"source={(source.name or 'shprobe edit')!r}))"]
    text = "\n".join(body)

    def used(module: str, *names: str) -> list[str]:  # the import line of what the code calls
        got = [n for n in names if f"{n}(" in text]
        return [f"from {module} import {', '.join(got)}"] if got else []

    imports = [*(["import shprobe"] if "shprobe." in text else []),
               *used("shprobe.lighting.design", "edit_lighting"),
               *used("shprobe.lighting.edits", "Blend", "EditSpec", "Rotation"),
               *used("shprobe.lighting.source", "blend_lighting", "resolve_lighting")]
    head = [f"# {_command(source, spec)}: the same lighting with shprobe's library", *imports,
            ""]
    return "\n".join([*head, *body]) + "\n"


def _command(source: SnippetSource, spec: EditSpec) -> str:
    """The equivalent ``shprobe edit`` command (without its output), for the comment."""
    import shlex

    name = source.name
    if source.code is not None:
        return (f"{name or 'the source'} edited as `shprobe edit` "
                f"{shlex.join(spec.to_text())} edits")
    if not name:
        src = []
    elif name.startswith("preset:"):
        src = ["--preset", name[7:]]
    elif (_is_image(name) if source.image is None else source.image):
        src = [name] + ([] if source.layout in (None, "auto") else ["--layout", source.layout])
    else:
        src = ["--coeffs", name]
    return "shprobe edit " + shlex.join([*src, *spec.to_text()])
