"""The parts of a lighting edit (`shprobe.lighting.edits.EditSpec`): a blended lighting
(`Blend`) and a rotation (`Rotation`), each read from and written back to the command line's
text and the viewer's JSON."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from .edit_values import Floats, num_text, number, numbers, nums_text, obj, shown, vector

__all__ = ["Blend", "BlendResolver", "Rotation"]


@dataclass(frozen=True)
class Blend:
    """Another lighting added with ``weight``: ``kind`` 'preset' (an R&H preset name), 'file'
    (a probe image or coefficient file, command line only) or 'probe' (an id the caller
    resolves: the viewer's loaded probes)."""

    kind: str
    name: str
    weight: float = 1.0

    def text(self, probe_names: Mapping[str, str] | None = None) -> str:
        if self.kind == "preset":
            return f"preset:{self.name}:{num_text(self.weight)}"
        if self.kind == "probe":
            name = (probe_names or {}).get(self.name)
            if name is None:
                raise ShprobeError(f"blend probe {self.name} is not loaded (load it again)")
            return f"{name}:{num_text(self.weight)}"
        return f"{self.name}:{num_text(self.weight)}"


@dataclass(frozen=True)
class Rotation:
    """A rotation of the lighting: ``kind`` 'axis' (values AX, AY, AZ, DEGREES, right-hand
    rule), 'euler' (ZYZ, degrees) or 'quat' (W, X, Y, Z)."""

    kind: str
    values: Floats

    def matrix(self) -> NDArray[np.float64]:
        """The 3×3 rotation matrix (`shprobe.sh.rotation`)."""
        from ..sh.rotation import from_axis_angle, from_euler_zyz, from_quaternion, one_rotation

        v = self.values
        if self.kind == "axis":
            return np.asarray(from_axis_angle(v[:3], v[3]), np.float64)
        if self.kind == "euler":
            a, b, g = np.radians(v)
            return np.asarray(one_rotation(from_euler_zyz(a, b, g)), np.float64)
        return np.asarray(one_rotation(from_quaternion(v)), np.float64)

    def text(self) -> str:
        if self.kind == "axis":
            return f"{nums_text(self.values[:3])}:{num_text(self.values[3])}"
        return f"{self.kind}:{nums_text(self.values)}"

    def json(self) -> dict[str, Any]:
        if self.kind == "axis":
            return {"axis": list(self.values[:3]), "degrees": self.values[3]}
        return {self.kind: list(self.values)}

    @staticmethod
    def parse(text: str) -> Rotation:
        """One ``--rotate`` value: AX,AY,AZ:DEGREES, euler:A,B,G or quat:W,X,Y,Z."""
        kind, sep, rest = str(text).partition(":")
        k = kind.strip().lower()
        if sep and k == "euler":
            return Rotation("euler", numbers(rest, "ZYZ Euler angles", (3,)))
        if sep and k == "quat":
            q = numbers(rest, "quaternion (w,x,y,z)", (4,))
            if not any(q):
                raise ShprobeError("quaternion (w,x,y,z) must be non-zero")
            return Rotation("quat", q)
        if not sep or not rest:
            raise ShprobeError(f"rotation {shown(text)}: expected AX,AY,AZ:DEGREES (e.g. "
                               "0,1,0:90), euler:A,B,G or quat:W,X,Y,Z")
        return Rotation("axis", (*vector(kind, "rotation axis"),
                                 number(rest, "rotation angle")))

    @staticmethod
    def from_json(v: Any) -> Rotation:
        r = obj(v, "rotation", ("axis", "degrees", "euler", "quat"))
        if "euler" in r and len(r) == 1:
            return Rotation("euler", numbers(r["euler"], "ZYZ Euler angles", (3,)))
        if "quat" in r and len(r) == 1:
            return Rotation.parse("quat:" + nums_text(numbers(r["quat"], "quaternion", (4,))))
        return Rotation("axis", (*vector(r.get("axis"), "rotation axis"),
                                 number(r.get("degrees"), "rotation angle")))


#: (blend, lmax) → its coefficients at ``lmax`` (K, C)
BlendResolver = Callable[[Blend, int], NDArray[np.float64]]
