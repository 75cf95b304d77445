"""GLSL for per-pixel SH irradiance at any degree: E(n) = Σ_lm Â_l L_lm y_lm(n) (R&H 2001 eq. 7).

`shprobe.lighting.export` writes the l ≤ 2 shaders (the quadratic form, R&H eq. 11–13). Above l = 2
there is no 4×4 form; `glsl_irradiance` emits a GLSL ES 3.0 function that evaluates the basis in the
page's fragment shader by the library's own recurrence
([`shprobe.sh.basis.sh_basis_numpy`][shprobe.sh.sh_basis_numpy]: (x + iy)ᵐ for the azimuth, the
normalised associated-Legendre recurrence in z with the coefficients of
[`recurrence_tables`][shprobe.sh.recurrence_tables]), unrolled to ``lmax``, in shprobe's
conventions: real SH, R&H signs (no Condon–Shortley phase; y_1,−1 ∝ y, y_1,0 ∝ z, y_1,1 ∝ x), index
k = l(l+1)+m, world +Y up. Its data are the irradiance coefficients E_lm = Â_l L_lm
([`irradiance_coeffs`][shprobe.lighting.irradiance_coeffs]), baked in as constants or left as a
``uniform vec3 SHPROBE_E[K]`` for a viewer to set (`glsl_uniform_values`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..sh import check_lmax, num_coeffs
from ..sh.indexing import recurrence_tables
from .coeffs import as_coeffs, as_rgb, pad_coeffs
from .export import _f
from .irradiance import irradiance_coeffs

__all__ = ["glsl_irradiance", "glsl_uniform_values"]


def glsl_uniform_values(coeffs: ArrayLike, lmax: int | None = None) -> NDArray[np.float64]:
    """The values of ``SHPROBE_E`` for lighting ``coeffs`` (L_lm, (K, 3)): E_lm = Â_l L_lm,
    truncated or zero-padded to ``lmax`` (default: the coefficients' own), shape (K', 3)."""
    c = as_coeffs(coeffs)
    e = irradiance_coeffs(c)
    return e if lmax is None else pad_coeffs(e, lmax)


def glsl_irradiance(lmax: int, coeffs: ArrayLike | None = None,
                    name: str = "shprobe_irradiance_sh") -> str:
    """GLSL ES 3.0 source of ``vec3 NAME(vec3 n)``: irradiance E(n) (not /π) at the unit
    world-space normal ``n``, summed to degree ``lmax``.

    ``coeffs`` None: declares ``uniform vec3 SHPROBE_E[K]`` (K = (lmax+1)², E_lm = Â_l L_lm,
    see `glsl_uniform_values`; unset degrees read 0); else lighting coefficients L_lm
    (K', 3) whose E_lm are baked in as a constant array (truncated / zero-padded to lmax).
    """
    lmax = check_lmax(lmax, 16)
    K = num_coeffs(lmax)
    a, b = recurrence_tables(lmax)
    out = [f"// shprobe: E(n) = sum_lm E_lm y_lm(n), l <= {lmax}, E_lm = A_l L_lm (R&H 2001 "
           "eq. 7);",
           "// real SH, R&H signs (no Condon-Shortley phase), k = l(l+1)+m, world +Y up;",
           "// E is irradiance, NOT divided by pi: diffuse radiance = albedo * E(n) / pi."]
    if coeffs is None:
        out.append(f"uniform vec3 SHPROBE_E[{K}];")
    else:
        e = glsl_uniform_values(coeffs, lmax)
        if e.shape[1] == 1:
            e = as_rgb(e)
        rows = ",\n".join(f"    vec3({', '.join(_f(v) for v in e[k])})" for k in range(K))
        out.append(f"const vec3 SHPROBE_E[{K}] = vec3[{K}](\n{rows}\n);")
    out += [f"vec3 {name}(vec3 n) {{",
            "    float x = n.x;", "    float y = n.y;", "    float z = n.z;",
            "    vec3 e = vec3(0.0);",
            "    float c0 = 1.0;  // Re (x + iy)^m", "    float s0 = 0.0;  // Im (x + iy)^m",
            f"    float pmm0 = {_f(0.5 / np.sqrt(np.pi))};"]
    sqrt2 = _f(np.sqrt(2.0))

    def store(l: int, m: int, p: str) -> None:
        k0 = l * (l + 1)
        if m == 0:
            out.append(f"    e += SHPROBE_E[{k0}] * {p};")
        else:
            out.append(f"    e += SHPROBE_E[{k0 + m}] * ({sqrt2} * {p} * c{m})"
                       f" + SHPROBE_E[{k0 - m}] * ({sqrt2} * {p} * s{m});")

    for m in range(lmax + 1):
        if m > 0:
            out.append(f"    float c{m} = x * c{m - 1} - y * s{m - 1};")
            out.append(f"    float s{m} = x * s{m - 1} + y * c{m - 1};")
            out.append(f"    float pmm{m} = pmm{m - 1} * {_f(np.sqrt((2.0 * m + 1) / (2.0 * m)))};")
        store(m, m, f"pmm{m}")
        if m + 1 <= lmax:
            out.append(f"    float p{m + 1}_{m} = {_f(np.sqrt(2.0 * m + 3.0))} * z * pmm{m};")
            store(m + 1, m, f"p{m + 1}_{m}")
            prev2, prev1 = f"pmm{m}", f"p{m + 1}_{m}"
            for l in range(m + 2, lmax + 1):
                out.append(f"    float p{l}_{m} = {_f(a[l, m])} * (z * {prev1} - "
                           f"{_f(b[l, m])} * {prev2});")
                store(l, m, f"p{l}_{m}")
                prev2, prev1 = prev1, f"p{l}_{m}"
    out += ["    return e;", "}"]
    return "\n".join(out) + "\n"
