"""Export and import of coefficients: shaders (GLSL/HLSL/WGSL), JSON, three.js, glTF, cmgen,
Condon–Shortley.

shprobe's coefficients are lighting (radiance) coefficients L_lm in the R&H basis (no
Condon–Shortley phase, see ``docs/conventions.md``), world frame +Y up. Each format, and what it
stores (every exported text repeats this in a comment or a field):

========== ================================================================================
format     content
========== ================================================================================
glsl/hlsl  functions of the world-space normal returning irradiance E(n) (not /π): eq. 11,
/wgsl      E = nᵀMn with the three 4×4 matrices M baked in (``shprobe_irradiance``), and the
           eq. 13 polynomial in the 9 L_lm (``shprobe_irradiance_poly``). l ≤ 2 only.
json       the ``shprobe prefilter --format json`` document (``lighting.document.coeffs_document``):
           ``coefficients`` L_lm `[k][rgb]`, ``irradiance_coefficients`` E_lm = Â_l L_lm,
           ``M`` (eq. 11–12), R&H signs, any lmax.
three      three.js ``SphericalHarmonics3`` / ``LightProbe.sh``: the flat array of
           ``toArray()`` (9 RGB triples, index k = l(l+1)+m). three.js stores radiance L_lm
           with the R&H basis constants and signs (``getAt``: 0.488603·y for k = 1) and
           applies Â_l in ``getIrradianceAt`` / the shader: so this is L, unchanged.
           Import also takes ``LightProbe.toJSON()`` (``object.sh`` × ``object.intensity``).
gltf       ``EXT_lights_image_based`` light with ``irradianceCoefficients`` (9×3): irradiance
           E_lm = Â_l L_lm (not /π) with Condon–Shortley signs (odd m negated), in the
           cube-map frame where the cube direction (x, y, z) is the glTF direction
           (x, y, −z) — the spec text fixes none of this; it is how its reference
           implementation, Babylon.js, reads them (CS-signed basis constants,
           ``convertIrradianceToLambertianRadiance`` ÷π, and ``REFLECTIONMAP_OPPOSITEZ``),
           proved against Babylon itself in ``tests/lighting/test_export_consumers.py``. The
           extension's required specular cube (``specularImages``, ``specularImageSize``)
           holds E/π of the same coefficients (8×8, 4 mips, RGBD PNG data URIs, bottom row
           first), a stand-in for a GGX-prefiltered map. The scene has no nodes: merge the
           light into an asset.
cmgen      Filament's ``sh.txt`` ("irradiance, pre-scaled base"): 9 RGB triples c_k such that
           E(n)/π = c0 + c1 y + c2 z + c3 x + c4 yx + c5 yz + c6 (3z² − 1) + c7 zx
           + c8 (x² − y²) (Filament's ``Irradiance_SphericalHarmonics``): Â_l/π and the basis
           constants K_lm baked in; the CS phase of Filament's basis cancels in c_k, so
           c_k = (Â_l/π) K_k L_lm with R&H's positive K_k. Frame: shprobe's world (+Y up),
           i.e. cmgen run with ``--no-mirror``. Import takes rows labelled "irradiance,
           pre-scaled base" (cmgen ``--sh-irradiance --sh-shader``) or unlabelled rows, and
           refuses other labelled forms.
cs-phase   L_lm with Condon–Shortley signs, L^CS_lm = (−1)^m L_lm, index l(l+1)+m — the
           order and signs of google/spherical-harmonics (``GetIndex``, ``EvalSH``), any lmax.
========== ================================================================================

[`import_coeffs`][shprobe.lighting.import_coeffs] reads every one of them back into shprobe's L_lm.
"""

from __future__ import annotations

import json
import os
import re
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._version import __version__
from ..errors import ShprobeError
from ..files import read_text
from ..sh import degrees, lmax_of
from ..sh.registry import convert
from .coeffs import RH_CONSTANTS, RH_LABELS, as_coeffs
from .document import coeffs_document, coeffs_from_document, parse_json
from .irradiance import quadratic_form

FORMATS = ("glsl", "hlsl", "wgsl", "json", "three", "gltf", "cmgen", "cs-phase")

#: suggested file suffix per format
SUFFIX = {"glsl": ".glsl", "hlsl": ".hlsl", "wgsl": ".wgsl", "json": ".json",
          "three": ".three.json", "gltf": ".gltf.json", "cmgen": "_sh.txt",
          "cs-phase": ".cs.json"}

__all__ = [
    "FORMATS",
    "SUFFIX",
    "export_coeffs",
    "import_coeffs",
    "parse_coeffs",
]

_CH = "RGB"


def _ahat(lmax: int) -> NDArray[np.float64]:
    from ..sh.zonal import clamped_cosine_factors

    return clamped_cosine_factors(lmax)[degrees(lmax)]


def _nine_rgb(c: NDArray, fmt: str) -> NDArray[np.float64]:
    """(9, 3) for the l ≤ 2 RGB formats (lower lmax zero-padded, 1 channel → grey)."""
    if c.shape[0] > 9:
        raise ShprobeError(f"format {fmt!r} holds only l <= 2 (9 coefficients); got "
                           f"lmax={lmax_of(c.shape[0])} — truncate first")
    if c.shape[1] not in (1, 3):
        raise ShprobeError(f"format {fmt!r} needs 1 or 3 channels, got {c.shape[1]}")
    out = np.zeros((9, 3))
    out[: c.shape[0]] = c
    return out


def _f(x: float) -> str:
    s = format(float(x), ".9g")
    return s if any(ch in s for ch in ".en") else s + ".0"


def _header(prefix: str, lines: list[str]) -> str:
    return "".join(f"{prefix} {ln}".rstrip() + "\n" for ln in lines)


def _shader_header(fmt: str, source: str | None) -> list[str]:
    return [
        f"shprobe {fmt} export" + (f" of {source}" if source else ""),
        "Convention: real SH, Ramamoorthi & Hanrahan 2001 signs (no Condon-Shortley phase),",
        "world frame +Y up; n is the unit world-space normal.",
        "Quantity: shprobe_irradiance(n) returns irradiance E(n), NOT divided by pi;",
        "diffuse radiance = albedo * E(n) / pi.",
        "shprobe_irradiance: R&H eq. 11, E = p^T M p with p = (n, 1) (M symmetric).",
        "shprobe_irradiance_poly: R&H eq. 13 in the lighting coefficients L_lm.",
    ]


def _shader(L9: NDArray, fmt: str, source: str | None) -> str:
    M = quadratic_form(L9)  # (3, 4, 4)
    c1, c2, c3, c4, c5 = (_f(c) for c in RH_CONSTANTS)
    if fmt == "glsl":
        mat = "const mat4 SHPROBE_M_{ch} = mat4({v});\n"
        arr_open, arr_close = "const vec3 SHPROBE_L[9] = vec3[9](\n", ");\n"
        vec3, vec4, flt = "vec3", "vec4", "float"
        fn_open = "vec3 {name}(vec3 n)"
        const = "const float"
        mul = "SHPROBE_M_{ch} * p"
    elif fmt == "hlsl":
        mat = "static const float4x4 SHPROBE_M_{ch} = float4x4({v});\n"
        arr_open, arr_close = "static const float3 SHPROBE_L[9] = {\n", "};\n"
        vec3, vec4, flt = "float3", "float4", "float"
        fn_open = "float3 {name}(float3 n)"
        const = "const float"
        mul = "mul(SHPROBE_M_{ch}, p)"
    else:  # wgsl
        mat = "const SHPROBE_M_{ch} = mat4x4<f32>({v});\n"
        arr_open, arr_close = "const SHPROBE_L = array<vec3<f32>, 9>(\n", ");\n"
        vec3, vec4, flt = "vec3<f32>", "vec4<f32>", "f32"
        fn_open = "fn {name}(n: vec3<f32>) -> vec3<f32>"
        const = "const"
        mul = "SHPROBE_M_{ch} * p"
    out = _header("//", _shader_header(fmt, source))
    for i, ch in enumerate(_CH):
        out += mat.format(ch=ch, v=", ".join(_f(x) for x in M[i].reshape(-1)))
    let = "let" if fmt == "wgsl" else vec4
    out += "\n" + fn_open.format(name="shprobe_irradiance") + " {\n"
    out += f"    {let} p = {vec4}(n, 1.0);\n"
    out += "    return {}({});\n}}\n\n".format(
        vec3, ", ".join(f"dot(p, {mul.format(ch=ch)})" for ch in _CH))
    out += arr_open
    out += "".join(f"    {vec3}({', '.join(_f(x) for x in L9[k])}){',' if k < 8 else ''}"
                   f"  // {RH_LABELS[k]}\n" for k in range(9))
    out += arr_close
    out += "\n" + fn_open.format(name="shprobe_irradiance_poly") + " {\n"
    for name, val in zip(("c1", "c2", "c3", "c4", "c5"), (c1, c2, c3, c4, c5), strict=True):
        out += f"    {const} {name}{': ' + flt if fmt == 'wgsl' else ''} = {val};\n"
    lt = "let" if fmt == "wgsl" else flt
    out += f"    {lt} x = n.x;\n    {lt} y = n.y;\n    {lt} z = n.z;\n"
    out += ("    return c1 * SHPROBE_L[8] * (x * x - y * y) + c3 * SHPROBE_L[6] * (z * z)\n"
            "        + c4 * SHPROBE_L[0] - c5 * SHPROBE_L[6]\n"
            "        + 2.0 * c1 * (SHPROBE_L[4] * (x * y) + SHPROBE_L[7] * (x * z)"
            " + SHPROBE_L[5] * (y * z))\n"
            "        + 2.0 * c2 * (SHPROBE_L[3] * x + SHPROBE_L[1] * y + SHPROBE_L[2] * z);\n")
    out += "}\n"
    return out


def export_coeffs(coeffs: ArrayLike, fmt: str, source: str | None = None) -> str:
    """Text of ``coeffs`` (L_lm, (K, C) or (K,)) in format ``fmt`` (one of
    [`FORMATS`][shprobe.lighting.FORMATS]; see the module doc for what each stores). ``source`` is
    named in the output.

    Parameters
    ----------
    coeffs
        (K, C) or (K,) lighting coefficients L_lm.
    fmt
        One of [`FORMATS`][shprobe.lighting.FORMATS].
    source
        What the coefficients came from, named in the output.

    Returns
    -------
    str
        The exported text.
    """
    c = as_coeffs(coeffs)
    if fmt not in FORMATS:
        raise ShprobeError(f"unknown export format {fmt!r}; choose from {', '.join(FORMATS)}")
    lmax = lmax_of(c.shape[0])
    if fmt in ("glsl", "hlsl", "wgsl"):
        return _shader(_nine_rgb(c, fmt), fmt, source)
    if fmt == "json":  # the document of `shprobe prefilter --format json`
        doc = coeffs_document(c, source=source)
        doc["quantity"] = ("coefficients: lighting (radiance) L_lm; irradiance_coefficients: "
                           "E_lm = A_l L_lm (E, not divided by pi); M: eq. 11-12 for E")
        return json.dumps(doc, indent=2) + "\n"
    if fmt == "three":
        L9 = _nine_rgb(c, fmt)
        doc = {
            "format": "three.SphericalHarmonics3",
            "convention": "three.js SphericalHarmonics3: R&H basis constants and signs "
                          "(no Condon-Shortley phase), order k = l(l+1)+m, world +Y up",
            "quantity": "L_lm radiance coefficients (three.js applies A_l in "
                        "getIrradianceAt and 1/pi in its Lambert BRDF)",
            "usage": "new THREE.LightProbe(new THREE.SphericalHarmonics3()"
                     ".fromArray(coefficients))",
            "coefficients": L9.reshape(-1).tolist()}
        if source:
            doc["source"] = source
        return json.dumps(doc, indent=2) + "\n"
    if fmt == "gltf":
        return _gltf(_nine_rgb(c, fmt), source)
    if fmt == "cmgen":
        ck = convert(_nine_rgb(c, fmt), to="filament")
        out = "".join(f"({', '.join(format(x, '.15f').rjust(18) for x in ck[k])}); "
                      f"// {RH_LABELS[k]}, irradiance, pre-scaled base\n" for k in range(9))
        return out + _header("//", [
            "shprobe cmgen export" + (f" of {source}" if source else ""),
            "Filament sh.txt: E(n)/pi = c0 + c1 y + c2 z + c3 x + c4 yx + c5 yz"
            " + c6 (3z^2-1) + c7 zx + c8 (x^2-y^2)",
            "(A_l/pi and K_lm baked in; Condon-Shortley phase cancels), world +Y up "
            "(cmgen --no-mirror)"])
    # cs-phase
    doc = {"format": "condon-shortley",
           "convention": "real SH with the Condon-Shortley phase: L_cs = (-1)^m L_rh; order "
                         "k = l(l+1)+m (google/spherical-harmonics GetIndex, EvalSH)",
           "quantity": "L_lm radiance coefficients (not convolved, not divided by pi)",
           "lmax": lmax, "channels": c.shape[1],
           "coefficients": convert(c, to="cs").tolist()}
    if source:
        doc["source"] = source
    return json.dumps(doc, indent=2) + "\n"


# ----------------------------------------------------------------------------- glTF

#: EXT_lights_image_based: edge of mip 0 of the specular cube and the number of mips written
_SPEC_SIZE, _SPEC_MIPS = 8, 4
#: Babylon.js RGBD: the largest range D may encode (``rgbdMaxRange``, helperFunctions.fx)
_RGBD_MAX_RANGE = 255.0


def _png_rgba8(img: NDArray[np.uint8]) -> bytes:
    """A PNG (colour type 6, 8 bits, no interlace, filter 0) of an (H, W, 4) uint8 image."""
    import struct
    import zlib

    h, w = img.shape[:2]

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    raw = b"".join(b"\x00" + img[r].tobytes() for r in range(h))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def _rgbd8(rgb: NDArray[np.float64]) -> NDArray[np.uint8]:
    """HDR linear RGB (..., 3) → RGBD bytes (..., 4) as Babylon.js ``toRGBD`` packs them
    (D = floor(255 / max(rgb)) / 255 clamped to [1/255, 1], rgb·D in gamma 1/2.2)."""
    v = np.maximum(rgb, 0.0)
    mx = np.maximum(v.max(axis=-1, keepdims=True), 1e-9)
    d = np.clip(np.floor(np.maximum(_RGBD_MAX_RANGE / mx, 1.0)) / 255.0, 1 / 255.0, 1.0)
    out = np.concatenate([np.clip(v * d, 0.0, 1.0) ** (1 / 2.2), d], axis=-1)
    return np.round(out * 255.0).astype(np.uint8)


def _gltf_factors() -> NDArray[np.float64]:
    """E_lm → ``irradianceCoefficients``: Â_l, Condon–Shortley signs, and the cube-map frame
    (Babylon.js looks its environment up at (x, y, −z) for the glTF direction (x, y, z))."""
    from ..sh.rotation import z_mirror_signs

    return _ahat(2) * convert(np.ones(9), to="gltf") * z_mirror_signs(2)


def _gltf(L9: NDArray[np.float64], source: str | None) -> str:
    import base64

    from ..probes.layouts import get_layout
    from .irradiance import irradiance

    E9 = L9 * _gltf_factors()[:, None]
    images: list[dict[str, str]] = []
    spec: list[list[int]] = []
    for level in range(_SPEC_MIPS):
        size = _SPEC_SIZE >> level  # faces +X −X +Y −Y +Z −Z, OpenGL orientation, row 0 on top
        faces = get_layout("cube").pixel_directions((6, size, size))
        row = []
        for face in faces:
            world = face * np.array([1.0, 1.0, -1.0])  # cube frame → glTF world
            # stored bottom row first ("flipped", as the extension says for glTF texture
            # space): Babylon.js uploads it so that memory row 0 is the face's top (tc = −1)
            png = _png_rgba8(_rgbd8(irradiance(L9, world) / np.pi)[::-1])
            row.append(len(images))
            images.append({"uri": "data:image/png;base64,"
                           + base64.b64encode(png).decode("ascii")})
        spec.append(row)
    light: dict[str, Any] = {"name": source or "shprobe", "intensity": 1.0,
                             "rotation": [0.0, 0.0, 0.0, 1.0],
                             "irradianceCoefficients": E9.tolist(),
                             "specularImageSize": _SPEC_SIZE, "specularImages": spec}
    doc = {"asset": {"version": "2.0", "generator": f"shprobe {__version__}"},
           "extensionsUsed": ["EXT_lights_image_based"],
           "extensions": {"EXT_lights_image_based": {"lights": [light]}},
           "images": images,
           "scene": 0,
           "scenes": [{"extensions": {"EXT_lights_image_based": {"light": 0}}}],
           "extras": {"shprobe": {
               "convention": "Condon-Shortley signs (odd m negated), order k = l(l+1)+m, in "
                             "the cube-map frame: cube direction (x, y, z) is the glTF "
                             "direction (x, y, -z), as Babylon.js reads them",
               "quantity": "irradiance coefficients E_lm = A_l L_lm, not divided by pi",
               "specular": "specularImages hold the diffuse radiance E/pi of the same "
                           "coefficients (RGBD PNG, every mip): a stand-in, not a GGX-"
                           "prefiltered environment; replace them for glossy materials"}}}
    return json.dumps(doc, indent=2) + "\n"


# ----------------------------------------------------------------------------- import

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def _from_M(M: NDArray) -> NDArray[np.float64]:
    """Invert R&H eq. 12: the 9 L_lm of one channel from its 4×4 M."""
    c1, c2, c3, c4, c5 = RH_CONSTANTS
    L20 = M[2, 2] / c3
    return np.array([(M[3, 3] + c5 * L20) / c4, M[1, 3] / c2, M[2, 3] / c2, M[0, 3] / c2,
                     M[0, 1] / c1, M[1, 2] / c1, L20, M[0, 2] / c1, M[0, 0] / c1])


def parse_coeffs(text: str, name: str | None = None) -> tuple[NDArray[np.float64], str]:
    """(L_lm (K, C), format) from the text of any export format (detected from content)."""
    where = name
    stripped = text.lstrip()
    if stripped.startswith("{"):
        doc = parse_json(text, where)
        return _parse_json(doc, where)
    if "SHPROBE_M_R" in text:
        fmt = ("hlsl" if "float4x4" in text else "wgsl" if "mat4x4<f32>" in text else "glsl")
        L = np.empty((9, 3))
        for i, ch in enumerate(_CH):
            m = re.search(rf"SHPROBE_M_{ch}\s*=\s*[\w<>]+\(([^)]*)\)", text)
            if not m:
                raise ShprobeError(f"shader has no matrix SHPROBE_M_{ch}", where)
            vals = [float(v) for v in re.findall(_NUM, m.group(1))]
            if len(vals) != 16:
                raise ShprobeError(f"SHPROBE_M_{ch} must have 16 numbers, has {len(vals)}",
                                   where)
            L[:, i] = _from_M(np.array(vals).reshape(4, 4))
        return L, fmt
    rows = re.findall(rf"^\s*\(\s*({_NUM})\s*,\s*({_NUM})\s*,\s*({_NUM})\s*\)", text, re.M)
    if rows:
        labels = re.findall(r"^\s*\([^)]*\)\s*;?\s*//(.*)$", text, re.M)
        if any("pre-scaled base" not in lb or "irradiance" not in lb for lb in labels):
            raise ShprobeError("cmgen sh.txt holds another form than 'irradiance, pre-scaled "
                               "base' (run cmgen with --sh-irradiance --sh-shader)", where)
        if len(rows) not in (1, 4, 9):
            raise ShprobeError(f"cmgen sh.txt must have 1, 4 or 9 rows, has {len(rows)}",
                               where)
        ck = np.zeros((9, 3))
        ck[: len(rows)] = np.array(rows, dtype=np.float64)
        return convert(ck, from_="filament"), "cmgen"
    raise ShprobeError("not a coefficient file shprobe can read (json, three, gltf, cmgen, "
                       "cs-phase, or a shprobe shader)", where)


def _number(x: Any, what: str, where: Any) -> float:
    """A finite JSON number (not a bool, string or structure)."""
    if isinstance(x, bool) or not isinstance(x, int | float):
        raise ShprobeError(f"{what} must be a number, got {type(x).__name__}", where)
    try:
        v = float(x)
    except OverflowError:
        v = float("inf")
    if not np.isfinite(v):
        raise ShprobeError(f"{what} must be finite", where)
    return v


def _flat27(x: Any, what: str, where: Any) -> NDArray[np.float64]:
    if not isinstance(x, list):
        raise ShprobeError(f"{what} must be a list of 27 numbers", where)
    try:
        flat = np.array(x, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        raise ShprobeError(f"{what} must be 27 numbers", where) from None
    if not np.all(np.isfinite(flat)):
        raise ShprobeError(f"{what} must be finite numbers", where)
    if flat.size != 27:
        raise ShprobeError(f"{what} must be 27 numbers, got {flat.size}", where)
    return flat


def _parse_json(doc: Any, where: Any) -> tuple[NDArray[np.float64], str]:
    """Every JSON format shprobe writes or reads, each field type-checked (a structure of the
    wrong type is one line, never an internal error)."""
    if not isinstance(doc, dict):
        raise ShprobeError("JSON coefficient file must hold an object", where)
    fmt = doc.get("format")
    if fmt in (None, "shprobe-coeffs") and "coefficients" in doc:
        return coeffs_from_document(doc, where), "json"
    if fmt == "condon-shortley":
        c = as_coeffs(doc.get("coefficients"), where, "coefficients")
        return convert(c, from_="cs"), "cs-phase"
    obj = doc.get("object")  # three.js LightProbe.toJSON(): {"metadata", "object": {"sh"}}
    if isinstance(obj, dict) and "sh" in obj:
        flat = _flat27(obj["sh"], "three.js LightProbe sh", where)
        scale = _number(obj.get("intensity", 1.0), "three.js LightProbe intensity", where)
        return flat.reshape(9, 3) * scale, "three"
    if fmt == "three.SphericalHarmonics3" or (isinstance(doc.get("sh"), list)
                                               and len(doc["sh"]) == 27):
        flat = _flat27(doc.get("coefficients", doc.get("sh")), "three.js coefficients", where)
        return flat.reshape(9, 3), "three"
    exts = doc.get("extensions")
    ext = exts.get("EXT_lights_image_based") if isinstance(exts, dict) else None
    if ext is not None:
        if not isinstance(ext, dict):
            raise ShprobeError("EXT_lights_image_based must be an object", where)
        lights = ext.get("lights") or ext.get("ibls") or []
        if (not isinstance(lights, list) or not lights or not isinstance(lights[0], dict)
                or "irradianceCoefficients" not in lights[0]):
            raise ShprobeError("EXT_lights_image_based has no irradianceCoefficients", where)
        E = as_coeffs(lights[0]["irradianceCoefficients"], where, "irradianceCoefficients")
        if E.shape != (9, 3):
            raise ShprobeError(f"irradianceCoefficients must be 9x3, got {E.shape}", where)
        E = E * _number(lights[0].get("intensity", 1.0), "light intensity", where)
        return E / _gltf_factors()[:, None], "gltf"
    raise ShprobeError("JSON file holds no coefficients shprobe recognises", where)


def import_coeffs(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Read lighting coefficients L_lm (K, C) back from any export format (detected from the
    file's content), or from a NumPy ``.npy`` / ``.npz`` array (`read_coeffs_array`).

    Parameters
    ----------
    path
        A file in any export format, or a ``.npy`` / ``.npz`` array.

    Returns
    -------
    ndarray of shape (K, C)
        The lighting coefficients L_lm in shprobe's convention.
    """
    p = os.fspath(path)
    if p.lower().endswith((".npy", ".npz")):
        return read_coeffs_array(p)
    return parse_coeffs(read_text(p, "text coefficient file"), p)[0]


def read_coeffs_array(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """SH coefficients (K, C) from an ``.npy`` array, or from an ``.npz`` archive's array ``L``,
    else ``coeffs``, else its first array (an ``shprobe hbasis bake`` file gives its probe's
    ``L``); npz headers and sizes are checked before anything is inflated."""
    from ..files import load_npz

    p = os.fspath(path)
    if not os.path.isfile(p):
        raise ShprobeError("no such file", p)
    try:
        if p.lower().endswith(".npy"):
            c = np.load(p, allow_pickle=False)
        else:
            data = load_npz(p, what="file of SH coefficients")
            key = next((k for k in ("L", "coeffs") if k in data), None)
            if key is None and not data:
                raise ShprobeError("holds no array of SH coefficients", p)
            c = data[key or next(iter(data))]
    except ShprobeError:
        raise
    except Exception as e:  # numpy/zipfile raise many types on bad files
        raise ShprobeError(f"cannot read SH coefficients: {' '.join(str(e).split())[:200]}",
                           p) from None
    return as_coeffs(c, p, "SH coefficients")
