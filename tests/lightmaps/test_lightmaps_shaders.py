"""The lightmap shader functions (shprobe.lightmaps.shaders): their polynomials equal the
library's own bases, every language compiles (glslangValidator for GLSL ES 3.00, GLSL 4.50
and HLSL; Chromium's WebGPU for WGSL), and on the GPU (WebGL2 and WebGPU on SwiftShader, the
HLSL through glslang → SPIR-V → SPIRV-Cross → WebGL2) they give format.evaluate's irradiance
from RGBA16F coefficient textures, for the writer's packing and for a shuffled one."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.hbasis import get_basis, h_basis
from shprobe.lightmaps import format as fmt
from shprobe.lightmaps.shaders import MONOMIALS, basis_polynomials, lightmap_shader
from shprobe.sh import sh_basis

CONSUMERS = Path(__file__).resolve().parents[1] / "consumers"
GLSLANG, CROSS = shutil.which("glslangValidator"), shutil.which("spirv-cross")
N = 300  # texels per case
TOL = 2e-5  # of the case's peak |E|: float32 arithmetic on float16 inputs


def _normals(n=N, seed=3):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.05
    d[0] = (0, 0, 1)  # the unperturbed surface
    return (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)


def _poly_eval(a, d):
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    env = {"x": x, "y": y, "z": z}
    mono = np.stack([np.ones_like(x) if m == "1" else eval(m, env) for m in MONOMIALS], 1)
    return mono @ a.T


def test_polynomials_are_the_librarys_bases():
    d = _normals().astype(np.float64)
    np.testing.assert_allclose(_poly_eval(basis_polynomials("h6"), d), h_basis(d, 6), atol=1e-12)
    np.testing.assert_allclose(_poly_eval(basis_polynomials("h4"), d), h_basis(d, 4), atol=1e-12)
    np.testing.assert_allclose(_poly_eval(basis_polynomials("sh9"), d), sh_basis(d, 2), atol=2e-6)
    np.testing.assert_allclose(_poly_eval(basis_polynomials("hl2"), d),
                               get_basis("HL2").evaluate(d), atol=1e-12)
    assert basis_polynomials("plain").tolist() == [[1.0] + [0.0] * 9]


def test_bad_requests_are_one_line():
    with pytest.raises(ShprobeError, match="unknown shading language"):
        lightmap_shader("h6", "metal")
    with pytest.raises(ShprobeError, match="unknown lightmap encoding"):
        lightmap_shader("h7")
    with pytest.raises(ShprobeError, match="no coefficient of colour 2"):
        lightmap_shader("plain", layouts={"plain": [[(0, 0), (0, 1), None, None]]})


ALL = list(fmt.ENCODINGS)


@pytest.mark.skipif(GLSLANG is None, reason="glslangValidator not installed")
@pytest.mark.parametrize("target", ["es300", "glsl450", "hlsl"])
def test_every_encoding_compiles(tmp_path, target):
    calls = []
    for e in ALL:
        k = len(fmt.texture_layout(e))
        if target == "hlsl":
            calls.append(f"shprobe_lightmap_{e}_sample({', '.join(f't{i}' for i in range(k))}, "
                         "smp, uv, n)")
        else:
            calls.append(f"shprobe_lightmap_{e}_sample({', '.join(f't{i}' for i in range(k))}, "
                         "uv, n)")
    if target == "hlsl":
        src = ("".join(f"Texture2D t{i};\n" for i in range(9)) + "SamplerState smp;\n"
               + lightmap_shader(ALL, "hlsl")
               + "float4 main(float2 uv : TEXCOORD0, float3 nm : TEXCOORD1) : SV_Target {\n"
               "  float3 n = shprobe_lightmap_normal(nm, 1.0);\n"
               f"  return float4({' + '.join(calls)}, 1.0);\n}}\n")
        path = tmp_path / "t.hlsl"
        cmd = [GLSLANG, "-D", "-V", "-S", "frag", "-e", "main", "-o", str(tmp_path / "t.spv")]
    else:
        head = ("#version 300 es\nprecision highp float;\n" if target == "es300"
                else "#version 450\n")
        loc = "" if target == "es300" else "layout(location = {}) "
        binding = "" if target == "es300" else "layout(binding = {}) "
        src = (head + "".join(f"{binding.format(i)}uniform highp sampler2D t{i};\n"
                              for i in range(9))
               + lightmap_shader(ALL, "glsl") + f"{loc.format(0)}in vec2 uv;\n"
               f"{loc.format(1)}in vec3 nm;\n{loc.format(0)}out vec4 col;\n"
               "void main() {\n  vec3 n = shprobe_lightmap_normal(nm, 1.0);\n"
               f"  col = vec4({' + '.join(calls)}, 1.0);\n}}\n")
        path = tmp_path / "t.frag"
        cmd = [GLSLANG] + (["-G", "-o", str(tmp_path / "t.spv")] if target == "glsl450" else [])
    path.write_text(src)
    r = subprocess.run([*cmd, str(path)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stdout + r.stderr


def _case(e: str, shuffled: bool, seed: int):
    """Coefficients (N, n, 3) as float16, the textures' uint16 bit patterns, the layout."""
    n = fmt.N_COEFFS[e]
    rng = np.random.default_rng(seed)
    c = rng.uniform(-1.0, 3.0, size=(1, N, n, 3)).astype(np.float16)
    layout = fmt.texture_layout(e)
    if shuffled:  # every (coefficient, colour) somewhere else, colours mixed in one texture
        items = [ic for chans in layout for ic in chans if ic is not None]
        items = [items[i] for i in rng.permutation(len(items))]
        items += [None] * (-len(items) % 4)
        layout = [items[i:i + 4] for i in range(0, len(items), 4)]
    tex = fmt.pack(e, c.astype(np.float64), layout)
    halves = [t.reshape(-1).view(np.uint16).tolist() for t in tex]
    return c[0].astype(np.float64), halves, layout


HLSL_MAIN = """
Texture2D normals;
float4 main(float4 pos : SV_Position) : SV_Target {{
    int2 p = int2(pos.xy);
    float3 n = normals.Load(int3(p, 0)).xyz;
    float2 uv = (float2(p) + 0.5) / float2({N}.0, 1.0);
    return float4({call}({args}, smp, uv, n), 1.0);
}}
"""


def _hlsl_as_glsl_es(e: str, layout, tmp: Path) -> str:
    k = len(layout)
    src = ("".join(f"Texture2D t{i};\n" for i in range(k)) + "SamplerState smp;\n"
           + lightmap_shader(e, "hlsl", {e: layout})
           + HLSL_MAIN.format(N=N, call=f"shprobe_lightmap_{e}_sample",
                              args=", ".join(f"t{i}" for i in range(k))))
    (tmp / f"{e}.hlsl").write_text(src)
    r = subprocess.run([GLSLANG, "-D", "-V", "-S", "frag", "-e", "main", "-o",
                        str(tmp / f"{e}.spv"), str(tmp / f"{e}.hlsl")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    r = subprocess.run([CROSS, "--es", "--version", "300", str(tmp / f"{e}.spv")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout


@pytest.fixture(scope="module")
def gpu_results(tmp_path_factory):
    from tests.support.browser import ORIGIN, chromium_page

    tmp = tmp_path_factory.mktemp("hlsl")
    nrm = _normals()
    res: dict = {}
    with chromium_page(serve={"/": CONSUMERS}) as page:
        page.goto(ORIGIN + "/lightmap_shaders.html")
        page.wait_for_function("window.lightmapShadersReady === true", timeout=60_000)
        for i, e in enumerate(ALL):
            for shuffled in (False, True):
                c, halves, layout = _case(e, shuffled, 10 * i + shuffled)
                want = fmt.evaluate(e, c, nrm.astype(np.float64))
                call = f"shprobe_lightmap_{e}_sample"
                args = [halves, nrm.ravel().tolist()]
                for api in ("webgl2", "webgpu", "hlsl-webgl2"):
                    try:
                        if api == "webgl2":
                            got = page.evaluate(
                                "([s, c, k, h, n]) => window.lightmapShaders.webgl2(s, c, k, h, n,"
                                " false)", [lightmap_shader(e, "glsl", {e: layout}), call,
                                            len(layout), *args])
                        elif api == "webgpu":
                            got = page.evaluate(
                                "([s, c, k, h, n]) => window.lightmapShaders.webgpu(s, c, k, h, n)",
                                [lightmap_shader(e, "wgsl", {e: layout}), call, len(layout), *args])
                        else:
                            if GLSLANG is None or CROSS is None:
                                raise RuntimeError("skip: glslangValidator / spirv-cross missing")
                            got = page.evaluate(
                                "([s, c, k, h, n]) => window.lightmapShaders.webgl2(s, c, k, h, n,"
                                " true)", [_hlsl_as_glsl_es(e, layout, tmp), call, len(layout),
                                           *args])
                    except Exception as ex:  # reported by the test that needs it
                        got = {"error": str(ex)}
                    res[api, e, shuffled] = (got, want)
        res["console"] = list(page.shprobe_console)
    return res


@pytest.mark.browser
@pytest.mark.parametrize("api", ["webgl2", "webgpu", "hlsl-webgl2"])
@pytest.mark.parametrize("e", ALL)
def test_shaders_equal_the_reference_on_the_gpu(gpu_results, api, e):
    for shuffled in (False, True):
        got, want = gpu_results[api, e, shuffled]
        if isinstance(got, dict) and "error" in got:
            if api == "webgpu" and ("adapter" in got["error"] or "navigator.gpu" in got["error"]):
                pytest.skip(f"WebGPU unavailable: {got['error']}")
            if got["error"].startswith("skip: "):
                pytest.skip(got["error"][6:])
            raise AssertionError(got["error"])
        if api == "webgpu":
            assert got["messages"] == [], got["messages"]  # compiles without a warning
            got = got["values"]
        got = np.reshape(got, (-1, 3))
        err = np.abs(got - want).max() / np.abs(want).max()
        assert err < TOL, (api, e, shuffled, err)


@pytest.mark.browser
def test_no_console_errors(gpu_results):
    assert not [m for m in gpu_results["console"] if m.startswith(("error", "pageerror"))]


def test_the_shader_command(tmp_path, capsys):
    """``shprobe lightmap shader``: the functions for a file's own encoding and packing (its
    ``components``), or for named encodings; a mismatch is one line; outputs are kept."""
    from shprobe.cli.main import main
    from tests.lightmaps.lightmap_files import floor_lightmap

    glb = floor_lightmap(tmp_path / "floor.glb", "h6")
    out = tmp_path / "lm.glsl"
    assert main(["lightmap", "shader", str(glb), "-o", str(out)]) == 0
    assert out.read_text() == lightmap_shader("h6", "glsl")
    assert main(["lightmap", "shader", "--encoding", "sh4", "--encoding", "hl2", "--lang",
                 "wgsl"]) == 0
    assert capsys.readouterr().out == lightmap_shader(["sh4", "hl2"], "wgsl")
    assert main(["lightmap", "shader", str(glb), "--encoding", "sh9"]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "stores h6" in err
    assert main(["lightmap", "shader", str(glb), "-o", str(out)]) != 0
    assert "exists" in capsys.readouterr().err
