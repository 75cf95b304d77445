"""lighting.glsl: the generated per-pixel SH irradiance function, any lmax.

The GLSL body is straight-line scalar code; it is run here by a literal transliteration to
numpy (float64 and float32) and compared with the library's irradiance (R&H eq. 7) evaluated by
sh_basis_scipy-checked sh_basis, at random normals; and compiled by glslangValidator as a
GLSL ES 3.00 fragment shader (the viewer's WebGL2 dialect) where that is installed.
"""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pytest

from shprobe.lighting.glsl import glsl_irradiance, glsl_uniform_values
from shprobe.lighting.irradiance import irradiance
from shprobe.sh import num_coeffs


def _run_glsl(src: str, n: np.ndarray, E: np.ndarray | None, dtype=np.float64) -> np.ndarray:
    """Execute the generated function's body on normals ``n`` (N, 3) with numpy."""
    body = src[src.index("{", src.index("vec3 shprobe_irradiance_sh")) + 1: src.rindex("}")]
    ns = {"x": n[:, :1].astype(dtype), "y": n[:, 1:2].astype(dtype),
          "z": n[:, 2:3].astype(dtype)}
    if E is None:  # the baked constant array
        m = re.search(r"const vec3 SHPROBE_E\[\d+\] = vec3\[\d+\]\((.*?)\n\);", src, re.S)
        E = np.array([[float(v) for v in row.split(",")]
                      for row in re.findall(r"vec3\(([^)]*)\)", m.group(1))])
    ns["SHPROBE_E"] = E.astype(dtype)
    out = None
    for line in body.strip().splitlines():
        s = line.split("//")[0].strip().rstrip(";")
        if not s or s.startswith(("float x", "float y", "float z")):
            continue
        if s.startswith("return"):
            out = eval(s[len("return"):], {}, ns)
            break
        s = re.sub(r"^(float|vec3) ", "", s)
        if dtype is np.float32:  # float literals (they all have a point) as float32
            s = re.sub(r"\b(\d+\.\d*(?:e[-+]?\d+)?)", r"np.float32(\1)", s)
        s = s.replace("vec3(np.float32(0.0))", "vec3(0.0)")
        s = s.replace("vec3(0.0)", "np.zeros((x.shape[0], 3), x.dtype)")
        exec(s, {"np": np}, ns)
    return np.broadcast_to(out, (len(n), 3))


@pytest.mark.parametrize("lmax", [0, 1, 2, 3, 4, 6])
def test_generated_glsl_is_the_library_irradiance(lmax):
    rng = np.random.default_rng(lmax)
    n = rng.normal(size=(200, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    L = rng.normal(size=(num_coeffs(lmax), 3))
    ref = irradiance(L, n)
    E = glsl_uniform_values(L)
    got = _run_glsl(glsl_irradiance(lmax), n, E)
    # the constants are written with 9 significant digits (exact for float32)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-8 * np.abs(ref).max())
    # float32 (the GPU's arithmetic): to single-precision rounding
    got32 = _run_glsl(glsl_irradiance(lmax), n, E, np.float32)
    np.testing.assert_allclose(got32, ref, rtol=0, atol=5e-6 * np.abs(ref).max())
    # baked constants: the same function of the normal
    np.testing.assert_allclose(_run_glsl(glsl_irradiance(lmax, L), n, None), ref, rtol=0,
                               atol=1e-7 * np.abs(ref).max())


def test_uniform_values_truncate_and_pad():
    rng = np.random.default_rng(1)
    L = rng.normal(size=(25, 3))
    n = np.array([[0.0, 0.6, 0.8]])
    E2 = glsl_uniform_values(L, 2)
    assert E2.shape == (9, 3)
    np.testing.assert_allclose(_run_glsl(glsl_irradiance(2), n, E2), irradiance(L[:9], n),
                               atol=1e-7)
    E6 = glsl_uniform_values(L, 6)  # zero above the coefficients' own degree
    assert E6.shape == (49, 3) and not E6[25:].any()
    np.testing.assert_allclose(_run_glsl(glsl_irradiance(6), n, E6), irradiance(L, n),
                               atol=1e-7)


GLSLANG = shutil.which("glslangValidator")


@pytest.mark.skipif(GLSLANG is None, reason="glslangValidator not installed")
@pytest.mark.parametrize("baked", [False, True])
def test_generated_glsl_compiles_as_webgl2(tmp_path, baked):
    L = np.ones((25, 3))
    src = ("#version 300 es\nprecision highp float;\n" + glsl_irradiance(4, L if baked else None)
           + "in vec3 nrm;\nout vec4 col;\n"
           "void main() { col = vec4(shprobe_irradiance_sh(normalize(nrm)), 1.0); }\n")
    p = tmp_path / "t.frag"
    p.write_text(src)
    r = subprocess.run([GLSLANG, str(p)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stdout + r.stderr
