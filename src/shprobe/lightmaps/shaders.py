"""GLSL, HLSL and WGSL functions that shade with an ``SHPROBE_lightmap``: the lightmap's
coefficient textures evaluated at the normal-map normal (Habel & Wimmer 2010 eq. 15).

The lightmap's texel frame is the normal map's tangent frame (H&W §4.3), so a pixel shader
needs no matrix: it decodes the normal map into a tangent-space unit normal n, samples the
coefficient textures at ``TEXCOORD_1`` and returns E(n) = Σᵢ cᵢ Bᵢ(n) per colour channel.
The diffuse colour is then ``baseColor / π · E · scale`` (``scale`` from the extension
object; see `shprobe.lightmaps.format`).

Every basis of [`shprobe.lightmaps.format.ENCODINGS`][shprobe.lightmaps.ENCODINGS] is a polynomial
of degree ≤ 2 in (x, y, z), and the code here is generated from
[`shprobe.lightmaps.format.basis_values`][shprobe.lightmaps.basis_values] itself: its monomial
coefficients are recovered by a least-squares fit at points off the sphere (exact, since the
reference does not normalise its input; a basis that were not such a polynomial would be refused),
so the shaders and the reference cannot drift apart.

For an encoding ``E`` with ``k`` textures (``len(format.texture_layout(E))``, or the layout a
file names), each language gets::

    shprobe_lightmap_normal(rgb, scale)           // normal-map texel (0..1) -> unit n
    shprobe_lightmap_basis_E_j(n)                 // B_4j .. B_4j+3 (a vec4 per 4 terms)
    shprobe_lightmap_E(s0, ..., s{k-1}, n)        // the textures' texel values -> E(n)
    shprobe_lightmap_E_sample(t0, ..., [sampler,] uv1, n)   // sampled at LOD 0, then the above

GLSL is GLSL ES 3.00 / GLSL 4.50 (``texture`` samplers as ``sampler2D`` arguments), HLSL
Shader Model 5 (``Texture2D`` + ``SamplerState``), WGSL as WebGPU accepts it
(``texture_2d<f32>`` + ``sampler``, ``textureSampleLevel`` so it may run in any stage).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from . import format as fmt

#: the shading languages
LANGUAGES = ("glsl", "hlsl", "wgsl")
#: the monomials of degree ≤ 2 the bases are written in, as shader expressions
MONOMIALS = ("1", "x", "y", "z", "x * y", "y * z", "x * z", "x * x", "y * y", "z * z")
_T = {"glsl": ("float", "vec3", "vec4"), "hlsl": ("float", "float3", "float4"),
      "wgsl": ("f32", "vec3<f32>", "vec4<f32>")}


def _monomials(p: NDArray[np.float64]) -> NDArray[np.float64]:
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    return np.stack([np.ones_like(x), x, y, z, x * y, y * z, x * z, x * x, y * y, z * z], 1)


def basis_polynomials(encoding: str) -> NDArray[np.float64]:
    """The encoding's basis functions as coefficients on `MONOMIALS`.

    Parameters
    ----------
    encoding : str
        One of [`shprobe.lightmaps.format.ENCODINGS`][shprobe.lightmaps.ENCODINGS].

    Returns
    -------
    ndarray, shape (n, 10)
        Row i: Bᵢ(x, y, z) = Σₘ a[i, m] · monomial m (entries below 1e-12 set to 0).
    """
    e = fmt.check_encoding(encoding)
    p = np.random.default_rng(0).uniform(-2.0, 2.0, size=(64, 3))  # off the sphere
    A = _monomials(p)
    B = fmt.basis_values(e, p)
    a, *_ = np.linalg.lstsq(A, B, rcond=None)
    if np.abs(A @ a - B).max() > 1e-9 * max(1.0, np.abs(B).max()):
        raise ShprobeError(f"the {e} basis is not a polynomial of degree <= 2 in n")
    a = np.array([[float(format(v, ".12g")) for v in row] for row in a.T])  # fit noise off
    a[np.abs(a) < 1e-12] = 0.0
    return a


def _num(v: float) -> str:
    s = format(float(v), ".9g")
    return s if any(ch in s for ch in ".en") else s + ".0"


def _poly(row: NDArray[np.float64]) -> str:
    terms = []
    for c, m in zip(row, MONOMIALS, strict=True):
        if c == 0.0:
            continue
        mag = _num(abs(c))
        t = mag if m == "1" else (m if abs(c) == 1.0 else f"{mag} * {m}")
        terms.append(("- " if c < 0 else "+ ") + t)
    if not terms:
        return "0.0"
    s = " ".join(terms)
    return s[2:] if s.startswith("+ ") else "-" + s[2:]


def _fn(lang: str, ret: str, name: str, params: list[tuple[str, str]]) -> str:
    if lang == "wgsl":
        ps = ", ".join(f"{n}: {t}" for t, n in params)
        return f"fn {name}({ps}) -> {ret} {{"
    return f"{ret} {name}({', '.join(f'{t} {n}' for t, n in params)}) {{"


def _let(lang: str, typ: str, name: str, value: str) -> str:
    return f"    let {name} = {value};" if lang == "wgsl" else f"    {typ} {name} = {value};"


def _normal(lang: str) -> str:
    f, v3, _ = _T[lang]
    return "\n".join([
        "// The normal-map texel (glTF normalTexture, 0..1, +X right, +Y up) as the unit",
        "// tangent-space normal, with glTF's normalTexture.scale on x and y.",
        _fn(lang, v3, "shprobe_lightmap_normal", [(v3, "rgb"), (f, "scale")]),
        f"    return normalize((rgb * 2.0 - 1.0) * {v3}(scale, scale, 1.0));", "}"])


def _encoding(lang: str, e: str, layout: list) -> str:
    f, v3, v4 = _T[lang]
    a = basis_polynomials(e)
    n = len(a)
    groups = -(-n // 4)
    uses = {m for row in a for m, c in zip(MONOMIALS, row, strict=True) if c != 0.0}
    out = [f"// {e}: {n} coefficient(s) per colour, Bi(n) in the texel's tangent frame "
           "(z = surface normal)."]
    for j in range(groups):
        out.append(_fn(lang, v4, f"shprobe_lightmap_basis_{e}_{j}", [(v3, "n")]))
        for var in "xyz":
            if any(var in m for m in uses):
                out.append(_let(lang, f, var, f"n.{var}"))
        vals = [_poly(a[i]) if i < n else "0.0" for i in range(4 * j, 4 * j + 4)]
        out.append(f"    return {v4}(\n        " + ",\n        ".join(vals) + ");")
        out.append("}")
    k = len(layout)
    tex = [(v4, f"s{t}") for t in range(k)]
    out.append(f"// E(n) = sum_i c_i Bi(n) (Habel & Wimmer 2010 eq. 15) from the {k} texture(s)'")
    out.append("// texel values; multiply by the SHPROBE_lightmap scale.")
    out.append(_fn(lang, v3, f"shprobe_lightmap_{e}", [*tex, (v3, "n")]))
    for j in range(groups):
        out.append(_let(lang, v4, f"b{j}", f"shprobe_lightmap_basis_{e}_{j}(n)"))
    sums: list[list[str]] = [[], [], []]
    for t, chans in enumerate(layout):
        for c in range(3):
            idx = [ic[0] if ic is not None and ic[1] == c else None for ic in chans]
            if all(i is None for i in idx):
                continue
            comps = [f"b{i // 4}.{'xyzw'[i % 4]}" if i is not None else "0.0" for i in idx]
            sums[c].append(f"dot(s{t}, {v4}({', '.join(comps)}))")
    for c in range(3):
        if not sums[c]:
            raise ShprobeError(f"the {e} layout holds no coefficient of colour {c}")
    out.append(f"    return {v3}(\n        " + ",\n        ".join(
        " + ".join(s) for s in sums) + ");")
    out.append("}")
    out.append("// The same, sampled at TEXCOORD_1 (bilinear, clamp to edge, LOD 0).")
    if lang == "glsl":
        params = [("sampler2D", f"t{t}") for t in range(k)]
        fetch = [f"textureLod(t{t}, uv1, 0.0)" for t in range(k)]
        v2 = "vec2"
    elif lang == "hlsl":
        params = [*[("Texture2D", f"t{t}") for t in range(k)], ("SamplerState", "smp")]
        fetch = [f"t{t}.SampleLevel(smp, uv1, 0.0)" for t in range(k)]
        v2 = "float2"
    else:
        params = [*[("texture_2d<f32>", f"t{t}") for t in range(k)], ("sampler", "smp")]
        fetch = [f"textureSampleLevel(t{t}, smp, uv1, 0.0)" for t in range(k)]
        v2 = "vec2<f32>"
    out.append(_fn(lang, v3, f"shprobe_lightmap_{e}_sample", [*params, (v2, "uv1"), (v3, "n")]))
    out.append(f"    return shprobe_lightmap_{e}(\n        " + ",\n        ".join(fetch)
               + ",\n        n);")
    out.append("}")
    return "\n".join(out)


def lightmap_shader(encodings: str | Sequence[str], language: str = "glsl",
                    layouts: dict[str, list] | None = None) -> str:
    """Shader source evaluating ``SHPROBE_lightmap`` encodings with a normal-map normal.

    Parameters
    ----------
    encodings : str or sequence of str
        One or more of [`shprobe.lightmaps.format.ENCODINGS`][shprobe.lightmaps.ENCODINGS]; each
        gets its functions (module docstring), the normal-map decoder is emitted once.
    language : str
        ``"glsl"``, ``"hlsl"`` or ``"wgsl"``.
    layouts : dict, optional
        Per encoding, the textures' ``components`` as a file names them (lists of 4 items,
        each ``(coefficient, colour)`` or None); default `shprobe.lightmaps.format.texture_layout`.

    Returns
    -------
    str
        Functions only (no version line, no entry point), to be pasted into a shader.
    """
    lang = str(language).lower()
    if lang not in LANGUAGES:
        raise ShprobeError(f"unknown shading language {language!r}; known: "
                           f"{', '.join(LANGUAGES)}")
    names = [encodings] if isinstance(encodings, str) else list(encodings)
    names = [fmt.check_encoding(e) for e in names]
    if not names:
        raise ShprobeError("no lightmap encoding given")
    head = ["// shprobe: SHPROBE_lightmap evaluation (Habel & Wimmer 2010, eq. 15), generated",
            "// from shprobe.lightmaps.format. E is irradiance, NOT divided by pi:",
            "// diffuse colour = baseColor / pi * E * scale."]
    parts = ["\n".join(head), _normal(lang)]
    for e in dict.fromkeys(names):
        lay = (layouts or {}).get(e) or fmt.texture_layout(e)
        lay = [[tuple(ic) if ic is not None else None for ic in chans] for chans in lay]
        parts.append(_encoding(lang, e, lay))
    return "\n\n".join(parts) + "\n"


__all__ = ["LANGUAGES", "MONOMIALS", "basis_polynomials", "lightmap_shader"]
