"""The lighting-edit language: one [`EditSpec`][shprobe.lighting.EditSpec] that ``shprobe edit`` /
``render`` read from their options ([`EditSpec.from_text`][shprobe.lighting.EditSpec.from_text]),
the viewer reads from its edit-state JSON
([`EditSpec.from_json`][shprobe.lighting.EditSpec.from_json]), and both write back
([`EditSpec.to_text`][shprobe.lighting.EditSpec.to_text]: the equivalent command-line arguments;
[`EditSpec.to_json`][shprobe.lighting.EditSpec.to_json]). `shprobe.lighting.design.edit_lighting`
applies it, in this order: blend, lights, set/scale/negate coefficients, then bands, rotate, window.

Every number is checked when a spec is made (finite, and at most `MAX_VALUE` in size:
a weight of 1e308 would overflow the lighting), every (l, m) against the spec's ``lmax``; a bad
value is one [`ShprobeError`][shprobe.errors.ShprobeError] line naming the option or key.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from .edit_parts import Blend, BlendResolver, Rotation
from .edit_values import (
    MAX_ITEMS,
    MAX_VALUE,
    Floats,
    colour,
    integer,
    items,
    lm_key,
    num_text,
    number,
    nums_text,
    obj,
    shown,
    vector,
)
from .windows import WindowSpec, parse_window, window_text

__all__ = ["MAX_VALUE", "Blend", "BlendResolver", "EditSpec", "Rotation"]

#: Highest degree an edit may have (``shprobe edit --lmax``).
MAX_EDIT_LMAX = 64

#: names of blended probes in JSON: ids the caller resolves, never a path
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")


# ----------------------------------------------------------------------------- the spec


@dataclass(frozen=True)
class EditSpec:
    """Lighting edits at degree ``lmax`` (the result's), in the order `edit_lighting` applies
    them. Colours and values are 1 or 3 numbers. Checked when made.

    Parameters
    ----------
    lmax
        The result's degree.
    weight
        The source's factor.
    blends
        Other lightings added, each with its weight.
    directional
        Lights as (direction, rgb irradiance).
    cones
        Lights as (axis, aperture in degrees, rgb radiance).
    sky
        (sky rgb, ground rgb, up), or None.
    sets, scales
        ((l, m), value or factor): one coefficient set or scaled.
    negates
        (l, m) of coefficients negated.
    set_bands, scale_bands
        (l, value or factor): a whole band set or scaled.
    negate_bands
        Bands negated.
    rotations
        Rotations applied in order.
    window
        None, 'auto' or (kind, strength).
    """

    lmax: int = 2
    weight: float = 1.0
    blends: tuple[Blend, ...] = ()
    directional: tuple[tuple[Floats, Floats], ...] = ()
    cones: tuple[tuple[Floats, float, Floats], ...] = ()
    sky: tuple[Floats, Floats, Floats] | None = None
    sets: tuple[tuple[tuple[int, int], Floats], ...] = ()
    scales: tuple[tuple[tuple[int, int], Floats], ...] = ()
    negates: tuple[tuple[int, int], ...] = ()
    set_bands: tuple[tuple[int, Floats], ...] = ()
    scale_bands: tuple[tuple[int, Floats], ...] = ()
    negate_bands: tuple[int, ...] = ()
    rotations: tuple[Rotation, ...] = ()
    window: WindowSpec = field(default=None)

    def __post_init__(self) -> None:
        if not isinstance(self.lmax, int) or not 0 <= self.lmax <= MAX_EDIT_LMAX:
            raise ShprobeError(f"lmax must be an integer 0..{MAX_EDIT_LMAX}, got "
                               f"{shown(self.lmax)}")
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, tuple) and f.name != "sky" and len(v) > MAX_ITEMS:
                raise ShprobeError(f"{f.name}: at most {MAX_ITEMS} entries")
        for _, ap, _ in self.cones:
            if not 0 < ap <= 180:
                raise ShprobeError(f"cone aperture must be in (0, 180] degrees, got {ap:g}")
        for what, lms in (("set", [k for k, _ in self.sets]),
                          ("scale", [k for k, _ in self.scales]),
                          ("negate", list(self.negates))):
            for l, m in lms:
                self._fits(l, what)
                if not -l <= m <= l:
                    raise ShprobeError(f"{what}: m = {m} is outside -{l}..{l}")
        for what, ls in (("set band", [k for k, _ in self.set_bands]),
                         ("scale band", [k for k, _ in self.scale_bands]),
                         ("negate band", list(self.negate_bands))):
            for l in ls:
                self._fits(l, what)

    def _fits(self, l: int, what: str) -> None:
        if not 0 <= l <= self.lmax:
            raise ShprobeError(f"{what}: l = {l} is outside 0..{self.lmax} (the edit's lmax)")

    # -- reading ----------------------------------------------------------------
    @classmethod
    def from_text(cls, args: Sequence[str]) -> EditSpec:
        """The spec of ``shprobe edit``'s edit options given as arguments (``['--lmax', '4',
        '--scale-band', '1=0.5', ...]``); [`from_options`][shprobe.lighting.EditSpec.from_options]
        reads each option.

        Parameters
        ----------
        args
            ``shprobe edit``'s edit options as command-line arguments.

        Returns
        -------
        EditSpec
            The spec.
        """
        opts: dict[str, Any] = {}
        it = iter(args)
        for a in it:
            name, eq, value = str(a).partition("=")
            key = name.removeprefix("--").replace("-", "_")
            if not name.startswith("--") or key not in _OPTIONS:
                raise ShprobeError(f"not an edit option: {shown(a)}")
            if not eq:
                value = next(it, None)
                if value is None:
                    raise ShprobeError(f"{name} needs a value")
            if _OPTIONS[key]:
                opts.setdefault(key, []).append(value)
            else:
                opts[key] = value
        return cls.from_options(opts)

    @classmethod
    def from_options(cls, opts: Mapping[str, Any]) -> EditSpec:
        """The spec of the CLI's edit options by name (click's parameter names without the
        dashes: ``lmax``, ``weight``, ``blend``, ``directional``, ``cone``, ``sky``, ``set``,
        ``scale``, ``negate``, ``set_band``, ``scale_band``, ``negate_band``, ``rotate``,
        ``window``); repeatable options take a sequence of their text values.

        Parameters
        ----------
        opts
            The edit options by name.

        Returns
        -------
        EditSpec
            The spec.
        """
        def many(k: str) -> list[str]:
            v = opts.get(k) or ()
            return [v] if isinstance(v, str) else [str(x) for x in v]

        def kv(text: str, what: str) -> tuple[str, str]:
            k, sep, v = text.partition("=")
            if not sep:
                raise ShprobeError(f"--{what} {shown(text)}: expected KEY=VALUE")
            return k, v

        def light(text: str, what: str) -> Floats:  # a light's colour: empty is white
            return colour(text or "1", what)

        blends = []
        for b in many("blend"):
            head, _, w = b.rpartition(":")
            if not head:
                raise ShprobeError(f"--blend {shown(b)}: expected FILE:WEIGHT or "
                                   "preset:NAME:WEIGHT")
            kind, name = ("preset", head[7:]) if head.startswith("preset:") else ("file", head)
            blends.append(Blend(kind, name, number(w, "blend weight")))
        cones = []
        for c in many("cone"):
            parts = c.split(":")
            if len(parts) != 3:
                raise ShprobeError(f"--cone {shown(c)}: expected DX,DY,DZ:APERTURE_DEG:R,G,B")
            cones.append((vector(parts[0], "cone direction"), number(parts[1], "aperture"),
                          light(parts[2], "colour")))
        sky = None
        if opts.get("sky"):
            parts = str(opts["sky"]).split(":")
            if len(parts) > 3:
                raise ShprobeError(f"--sky {shown(opts['sky'])}: expected SKY_R,G,B"
                                   "[:GROUND_R,G,B[:UX,UY,UZ]]")
            sky = (light(parts[0], "sky colour"),
                   light(parts[1], "ground colour") if len(parts) > 1 else (0.0,),
                   vector(parts[2], "up") if len(parts) > 2 else (0.0, 1.0, 0.0))
        lmax = opts.get("lmax")
        return cls(
            lmax=2 if lmax is None else integer(lmax if isinstance(lmax, str) else int(lmax),
                                             "lmax"),
            weight=number(opts.get("weight", 1.0), "weight"),
            blends=tuple(blends),
            directional=tuple((vector(d.partition(":")[0], "direction"),
                               light(d.partition(":")[2], "colour"))
                              for d in many("directional")),
            cones=tuple(cones), sky=sky,
            sets=tuple((lm_key(k, "coefficient 'l,m'"), colour(v, "value"))
                       for k, v in (kv(s, "set") for s in many("set"))),
            scales=tuple((lm_key(k, "coefficient 'l,m'"), colour(v, "factor"))
                         for k, v in (kv(s, "scale") for s in many("scale"))),
            negates=tuple(lm_key(s, "coefficient 'l,m'") for s in many("negate")),
            set_bands=tuple((integer(k, "band l"), colour(v, "value"))
                            for k, v in (kv(s, "set-band") for s in many("set_band"))),
            scale_bands=tuple((integer(k, "band l"), colour(v, "factor"))
                              for k, v in (kv(s, "scale-band") for s in many("scale_band"))),
            negate_bands=tuple(integer(s, "band l") for s in many("negate_band")),
            rotations=tuple(Rotation.parse(r) for r in many("rotate")),
            window=parse_window(opts.get("window")))

    @classmethod
    def from_json(cls, doc: Any, max_lmax: int = MAX_EDIT_LMAX) -> EditSpec:
        """The spec of an edit-state JSON object (the viewer's). Keys, all optional:

        ``lmax`` (0..``max_lmax``), ``weight``; ``blends``: [{"preset": NAME, "weight": w} |
        {"probe": ID, "weight": w}] (ID: a name the caller resolves, never a path);
        ``directional``: [{"dir": [x,y,z], "rgb": [r,g,b]}]; ``cone``: [{"dir",
        "aperture_deg", "rgb"}]; ``sky``: {"sky": rgb, "ground": rgb, "up": xyz} | null;
        ``scale``: {"l,m": f}; ``scale_band``: {"l": f}; ``set``: {"l,m": rgb};
        ``set_band``: {"l": rgb}; ``negate``: ["l,m"]; ``negate_band``: [l]; ``rotation``:
        null | {"axis": xyz, "degrees": d} | {"euler": [a,b,g]} | {"quat": [w,x,y,z]} | a list
        of these; ``window``: null | "none" | "auto" | "KIND:STRENGTH".

        Parameters
        ----------
        doc
            The edit-state JSON object.
        max_lmax
            The largest ``lmax`` accepted.

        Returns
        -------
        EditSpec
            The spec (a one-line error for anything malformed).
        """
        from ..probes.presets import PRESETS

        s = obj(doc, "edit state", _JSON_KEYS)
        lmax = integer(s.get("lmax", 2), "lmax")
        if not 0 <= lmax <= max_lmax:
            raise ShprobeError(f"lmax must be an integer 0..{max_lmax}, got {lmax}")
        blends = []
        for b in items(s.get("blends"), "blends"):
            b = obj(b, "blend", ("preset", "probe", "weight"))
            w = number(b.get("weight", 1.0), "blend weight")
            if isinstance(b.get("preset"), str) and b["preset"] in PRESETS and "probe" not in b:
                blends.append(Blend("preset", b["preset"], w))
            elif isinstance(b.get("probe"), str) and _NAME.fullmatch(b["probe"]) \
                    and "preset" not in b:
                blends.append(Blend("probe", b["probe"], w))
            else:
                raise ShprobeError(f"blend must name a preset ({', '.join(PRESETS)}) or a "
                                   f"probe this server loaded, got {shown(b)}")
        directional = []
        for d in items(s.get("directional"), "directional"):
            d = obj(d, "directional light", ("dir", "rgb"))
            directional.append((vector(d.get("dir"), "light direction"),
                                colour(d.get("rgb", [1, 1, 1]), "light colour")))
        cones = []
        for c in items(s.get("cone"), "cone"):
            c = obj(c, "cone light", ("dir", "aperture_deg", "rgb"))
            cones.append((vector(c.get("dir"), "cone direction"),
                          number(c.get("aperture_deg"), "cone aperture"),
                          colour(c.get("rgb", [1, 1, 1]), "cone colour")))
        sky = s.get("sky")
        if sky is not None:
            k = obj(sky, "sky", ("sky", "ground", "up"))
            sky = None if not k else (colour(k.get("sky", [1, 1, 1]), "sky colour"),
                                      colour(k.get("ground", [0, 0, 0]), "ground colour"),
                                      vector(k.get("up", [0, 1, 0]), "sky up"))
        rot = s.get("rotation")
        rots = [] if rot is None else items(rot, "rotation") if isinstance(rot, list) \
            else [rot]

        def table(key: str, what: str) -> list[tuple[str, Any]]:
            v = s.get(key)
            if v is None:
                return []
            if not isinstance(v, dict):
                raise ShprobeError(f"{key} must be an object {{{what}: value}}, got {shown(v)}")
            if len(v) > MAX_ITEMS:
                raise ShprobeError(f"{key}: at most {MAX_ITEMS} entries")
            return list(v.items())

        def band(k: str) -> int:
            if not re.fullmatch(r"[0-9]{1,4}", k):
                raise ShprobeError(f"band key must be a degree 'l', got {shown(k)}")
            return int(k)

        return cls(
            lmax=lmax, weight=number(s.get("weight", 1.0), "weight"), blends=tuple(blends),
            directional=tuple(directional), cones=tuple(cones), sky=sky,
            sets=tuple((lm_key(k, "coefficient key"), colour(v, "coefficient value"))
                       for k, v in table("set", '"l,m"')),
            scales=tuple((lm_key(k, "coefficient key"), colour(v, "coefficient factor"))
                         for k, v in table("scale", '"l,m"')),
            negates=tuple(lm_key(k, "coefficient key") for k in items(s.get("negate"),
                                                                     "negate")),
            set_bands=tuple((band(k), colour(v, "band value"))
                            for k, v in table("set_band", '"l"')),
            scale_bands=tuple((band(k), colour(v, "band factor"))
                              for k, v in table("scale_band", '"l"')),
            negate_bands=tuple(integer(k, "band l") for k in items(s.get("negate_band"),
                                                                  "negate_band")),
            rotations=tuple(Rotation.from_json(r) for r in rots),
            window=parse_window(s.get("window")))

    # -- writing ----------------------------------------------------------------
    def to_text(self, probe_names: Mapping[str, str] | None = None) -> list[str]:
        """The ``shprobe edit`` arguments doing the same edits (after the source);
        ``probe_names`` gives the file of each blended probe id.

        Parameters
        ----------
        probe_names
            The file of each blended probe id.

        Returns
        -------
        list of str
            The ``shprobe edit`` arguments.
        """
        a = ["--lmax", str(self.lmax)]
        if self.weight != 1.0:
            a += ["--weight", num_text(self.weight)]
        for b in self.blends:
            a += ["--blend", b.text(probe_names)]
        for d, rgb in self.directional:
            a += ["--directional", f"{nums_text(d)}:{nums_text(rgb)}"]
        for d, ap, rgb in self.cones:
            a += ["--cone", f"{nums_text(d)}:{num_text(ap)}:{nums_text(rgb)}"]
        if self.sky is not None:
            a += ["--sky", ":".join(nums_text(x) for x in self.sky)]
        a += [x for (l, m), v in self.sets for x in ("--set", f"{l},{m}={nums_text(v)}")]
        a += [x for (l, m), v in self.scales for x in ("--scale", f"{l},{m}={nums_text(v)}")]
        a += [x for l, m in self.negates for x in ("--negate", f"{l},{m}")]
        a += [x for l, v in self.set_bands for x in ("--set-band", f"{l}={nums_text(v)}")]
        a += [x for l, v in self.scale_bands for x in ("--scale-band", f"{l}={nums_text(v)}")]
        a += [x for l in self.negate_bands for x in ("--negate-band", str(l))]
        a += [x for r in self.rotations for x in ("--rotate", r.text())]
        if self.window is not None:
            a += ["--window", window_text(self.window)]
        return a

    def to_json(self) -> dict[str, Any]:
        """The edit-state JSON object of this spec
        ([`from_json`][shprobe.lighting.EditSpec.from_json] reads it back; a 'file' blend has no
        JSON form and is refused).

        Returns
        -------
        dict
            The edit-state JSON object.
        """
        if any(b.kind == "file" for b in self.blends):
            raise ShprobeError("a blend of a file has no edit-state form (the viewer blends "
                               "presets and the probes it loaded)")
        doc: dict[str, Any] = {
            "lmax": self.lmax, "weight": self.weight,
            "blends": [{b.kind: b.name, "weight": b.weight} for b in self.blends],
            "directional": [{"dir": list(d), "rgb": list(c)} for d, c in self.directional],
            "cone": [{"dir": list(d), "aperture_deg": ap, "rgb": list(c)}
                     for d, ap, c in self.cones],
            "sky": None if self.sky is None else dict(zip(("sky", "ground", "up"),
                                                           map(list, self.sky), strict=True)),
            "scale": {f"{l},{m}": _one(v) for (l, m), v in self.scales},
            "scale_band": {str(l): _one(v) for l, v in self.scale_bands},
            "rotation": (None if not self.rotations else self.rotations[0].json()
                         if len(self.rotations) == 1 else [r.json() for r in self.rotations]),
            "window": None if self.window is None else window_text(self.window)}
        if self.sets:
            doc["set"] = {f"{l},{m}": list(v) for (l, m), v in self.sets}
        if self.negates:
            doc["negate"] = [f"{l},{m}" for l, m in self.negates]
        if self.set_bands:
            doc["set_band"] = {str(l): list(v) for l, v in self.set_bands}
        if self.negate_bands:
            doc["negate_band"] = list(self.negate_bands)
        return doc

    # -- views ------------------------------------------------------------------
    def rotation_matrix(self) -> NDArray[np.float64]:
        """All the rotations as one 3×3 matrix (applied in order: R = Rₙ ⋯ R₁).

        Returns
        -------
        ndarray of shape (3, 3)
            R = Rₙ ⋯ R₁.
        """
        R = np.eye(3)
        for r in self.rotations:
            R = r.matrix() @ R
        return R

    def unrotated(self) -> EditSpec:
        """The edits before the rotation (no rotation, no window).

        Returns
        -------
        EditSpec
            The spec without its rotations and window.
        """
        return replace(self, rotations=(), window=None)

    def with_lmax(self, lmax: int) -> EditSpec:
        return replace(self, lmax=lmax)


def _one(v: Floats) -> float | list[float]:
    return v[0] if len(v) == 1 else list(v)


#: the CLI's edit options → repeatable?
_OPTIONS = {"lmax": False, "weight": False, "blend": True, "directional": True, "cone": True,
            "sky": False, "set": True, "scale": True, "negate": True, "set_band": True,
            "scale_band": True, "negate_band": True, "rotate": True, "window": False}
_JSON_KEYS = ("lmax", "weight", "blends", "directional", "cone", "sky", "scale", "scale_band",
              "set", "set_band", "negate", "negate_band", "rotation", "window")
