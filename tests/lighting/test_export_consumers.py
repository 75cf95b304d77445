"""Every export read by the program that consumes it, compared with shprobe's own numbers.

Consumers (installed by .ci/run: ``npm ci`` in tests/consumers/, Debian chromium, Playwright's
Python client): three.js (``three`` export), Babylon.js and the Khronos glTF-Validator
(``gltf``), Filament compiled to WebAssembly (``cmgen``), WebGL2 in Chromium (``glsl`` as
GLSL ES 3.00) and Chromium's WebGPU / Tint (``wgsl``). One node process per Node consumer and
one Chromium for the browser ones evaluate every normal of every lighting at once.

Lightings: the shared grace and ennis probes projected at lmax 2, grace turned by a rotation,
and grace edited (a directional light added, L10 negated). Normals: 1200 Fibonacci directions
plus the six axes. The figure reported for each consumer and lighting is
max |consumer − shprobe| / max |shprobe| over all normals and channels (relative to the peak:
a pointwise ratio is meaningless where E crosses 0, which ennis does). ``pytest -s`` prints them.

Each consumer also gets one deliberately corrupted export (one sign flipped in the exported
text) and must then disagree — the check can fail.
"""

from __future__ import annotations

import functools
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from shprobe.lighting import irradiance, irradiance_coeffs, project
from shprobe.lighting.design import directional_light, negate_coeff, rotate_lighting
from shprobe.lighting.export import export_coeffs, parse_coeffs
from shprobe.probes.env import load_env
from shprobe.sh import sh_basis
from shprobe.sh.rotation import from_axis_angle
from tests.conftest import REPO, shared_dir
from tests.support.npm_packages import ensure_npm_packages

pytestmark = pytest.mark.node

CONSUMERS = REPO / "tests" / "consumers"
TOL = 1e-5
FLIPPED = "grace_flipped"


def fibonacci_normals(n: int = 1200) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5 ** 0.5) * i
    r = np.sqrt(1 - z * z)
    d = np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)
    return np.concatenate([d, np.eye(3), -np.eye(3)])


NORMALS = fibonacci_normals()


@functools.cache
def lightings() -> dict[str, np.ndarray]:
    out = {}
    for name in ("grace", "ennis"):
        p = shared_dir() / "probes" / f"{name}.hdr"
        if not p.is_file():
            pytest.skip(f"test data {p} not found (set SHPROBE_TEST_DATA)")
        out[name] = project(load_env(p), 2)
    out["grace_rotated"] = rotate_lighting(out["grace"], from_axis_angle((1.0, 2.0, 3.0), 37.0))
    out["grace_edited"] = negate_coeff(
        out["grace"] + directional_light((0.3, -0.5, 0.8), (2.0, 1.0, 0.5)), 1, 0)
    return out


def rel(a, b) -> float:
    a, b = np.asarray(a, float).reshape(-1, 3), np.asarray(b, float).reshape(-1, 3)
    return float(np.abs(a - b).max() / np.abs(b).max())


def flip_first(text: str, pattern: str) -> str:
    """The export text with the sign of the first number after ``pattern`` flipped."""
    m = re.search(pattern + r"\s*([-+]?)(\d)", text)
    assert m, pattern
    sign = "" if m.group(1) == "-" else "-"
    return text[: m.start(1)] + sign + text[m.end(1):]


def cases(fmt: str, flip: str) -> list[dict[str, str]]:
    """Every lighting exported in ``fmt``, plus grace with one sign flipped at ``flip``."""
    out = [{"name": k, "text": export_coeffs(L, fmt, source=k)} for k, L in lightings().items()]
    out.append({"name": FLIPPED, "text": flip_first(out[0]["text"], flip)})
    return out


def record(consumer: str, name: str, value: float) -> float:
    """Print one figure (``pytest -s``) and return it."""
    print(f"{consumer:<34} {name:<14} max rel diff {value:.3g}")
    return value


def check(consumer: str, results: dict, key: str, expect) -> None:
    """Every lighting within TOL; the flipped export far outside."""
    for name in lightings():
        assert record(consumer, name, rel(results[name][key], expect(name))) <= TOL
    assert rel(results[FLIPPED][key], expect("grace")) > 1e-3, "sign flip went unnoticed"


# ----------------------------------------------------------------------------- Node consumers

def require_node(package: str) -> str:
    node = shutil.which("node")
    if node is None:
        pytest.skip("node not installed (.ci/run installs the consumers with npm ci)")
    if not (CONSUMERS / "node_modules" / package).is_dir() and not ensure_npm_packages():
        pytest.skip(f"npm package {package} not installed (cd tests/consumers && npm ci)")
    return node


def run_node(script: str, package: str, job: dict, tmp_path: Path) -> dict:
    node = require_node(package)
    p = tmp_path / f"{script}.job.json"
    p.write_text(json.dumps(job))
    r = subprocess.run([node, str(CONSUMERS / script), str(p)], capture_output=True, text=True,
                       timeout=300, cwd=CONSUMERS)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout)


def E(name: str) -> np.ndarray:
    return irradiance(lightings()[name], NORMALS)


def test_three_js(tmp_path):
    job = {"cases": cases("three", r'"coefficients": \['), "normals": NORMALS.ravel().tolist()}
    out = run_node("three.mjs", "three", job, tmp_path)["cases"]
    # getIrradianceAt: E(n) (three.js applies Â_l; 6-digit constants → ~1e-6)
    check("three.js getIrradianceAt", out, "irradiance", E)
    # getAt: the radiance Σ L_lm y_lm(n)
    check("three.js getAt", out, "radiance", lambda k: sh_basis(NORMALS, 2) @ lightings()[k])
    # LightProbe.toJSON() (sh/2 at intensity 2) read back by shprobe, and by three's own
    # ObjectLoader
    for name, L in lightings().items():
        back, fmt = parse_coeffs(json.dumps(out[name]["toJSON"]))
        assert fmt == "three"
        np.testing.assert_allclose(back, L, rtol=1e-12, atol=1e-14)
        loaded = out[name]["loaded"]
        assert loaded["type"] == "LightProbe" and loaded["intensity"] == 2.0
        np.testing.assert_allclose(np.reshape(loaded["sh"], (9, 3)) * 2.0, L, rtol=1e-12)


def test_gltf_validator(tmp_path):
    # the validator does see a broken document: the old export's empty scene nodes
    bad = json.loads(export_coeffs(lightings()["grace"], "gltf"))
    bad["scenes"][0]["nodes"] = []
    job = {"cases": [{"name": k, "text": export_coeffs(L, "gltf", source=k)}
                     for k, L in lightings().items()] + [{"name": "bad",
                                                          "text": json.dumps(bad)}]}
    out = run_node("validate_gltf.mjs", "gltf-validator", job, tmp_path)
    for name in lightings():
        rep = out[name]
        assert rep["numErrors"] == 0 and rep["numWarnings"] == 0, rep["messages"]
        # infos: the extension it cannot check, and the cube-map images only that extension uses
        for m in rep["messages"]:
            assert (m["code"] == "UNSUPPORTED_EXTENSION"
                    or (m["code"] == "UNUSED_OBJECT" and m["pointer"].startswith("/images/"))), m
    rep = out["bad"]
    assert rep["numErrors"] == 1
    assert [m["pointer"] for m in rep["messages"] if m["code"] == "EMPTY_ENTITY"] == [
        "/scenes/0/nodes"]


def test_filament_cmgen(tmp_path):
    job = {"cases": cases("cmgen", r"^\("), "normals": NORMALS.ravel().tolist()}
    out = run_node("filament.mjs", "filament", job, tmp_path)["cases"]
    # Filament clamps at 0 (getColorEstimate); float32 in WebAssembly
    check("Filament getColorEstimate", out, "irradiance", lambda k: np.maximum(E(k), 0.0))
    # band 1 read as Filament's (x, y, z): its dominant-light direction is minus the
    # luminance-weighted gradient of E
    lum = np.array([0.2126, 0.7152, 0.0722])
    for name, L in lightings().items():
        grad = (L[[3, 1, 2]] @ lum)
        np.testing.assert_allclose(out[name]["direction"], -grad / np.linalg.norm(grad),
                                   atol=1e-6)


# ----------------------------------------------------------------------------- browser

@pytest.fixture(scope="module")
def browser_results():
    """Babylon.js (left- and right-handed scenes), WebGL2 and WebGPU, in one Chromium."""
    from tests.support.browser import ORIGIN, chromium_page

    require_node("@babylonjs/core")
    gltf = cases("gltf", r'"irradianceCoefficients": \[\s*\[\s*[-0-9.e]+,\s*[-0-9.e]+,'
                         r'\s*[-0-9.e]+\s*\],\s*\[\s*[-0-9.e]+,\s*[-0-9.e]+,\s*[-0-9.e]+\s*\],'
                         r'\s*\[')  # flips L10's red: the z axis
    for c in gltf:  # merged into an asset with one node, as the export's note asks
        doc = json.loads(c["text"])
        doc["nodes"] = [{"name": "model"}]
        doc["scenes"][0]["nodes"] = [0]
        c["text"] = json.dumps(doc)
    n = NORMALS.ravel().tolist()
    res: dict = {}
    with chromium_page(serve={"/": CONSUMERS}) as page:
        page.goto(ORIGIN + "/browser.html")
        page.wait_for_function("window.consumersReady === true", timeout=120_000)
        for rh in (False, True):
            res["babylon", rh] = page.evaluate(
                "([c, n, rh]) => window.consumers.babylon(c, n, rh)", [gltf, n, rh])
        hlsl = hlsl_as_glsl_es(cases("hlsl", r"SHPROBE_M_R = float4x4\("))
        for fmt, fn, flip, complete in (
                ("glsl", "webgl2", r"SHPROBE_M_R = mat4\(", False),
                ("wgsl", "webgpu", r"SHPROBE_M_R = mat4x4<f32>\(", False),
                ("hlsl", "webgl2", None, True)):
            key = fn if fmt != "hlsl" else "hlsl-webgl2"
            res[key] = {}
            if complete and isinstance(hlsl, str):
                res[key] = {"skip": hlsl}
                continue
            for c in (hlsl if complete else cases(fmt, flip)):
                try:
                    res[key][c["name"]] = page.evaluate(
                        f"([s, n, f]) => window.consumers.{fn}(s, n, f)",
                        [c["text"], n, complete])
                except Exception as e:  # reported by the test that needs it
                    res[key][c["name"]] = {"error": str(e)}
        res["console"] = list(page.shprobe_console)
    return res


@pytest.mark.browser
def test_babylon_right_handed(browser_results):
    """Babylon.js, scene.useRightHandedSystem = true (glTF's own frame, no root transform):
    the environment's harmonics, evaluated as its PBR shader does, are E(n), with π (Babylon
    holds E/π), CS signs and the cube frame's z flip all accounted for."""
    r = browser_results["babylon", True]
    assert r["version"].startswith("9.") and r["webgl"] == 2
    check("Babylon.js (RH scene) harmonics", r["cases"], "harmonics", E)


@pytest.mark.browser
def test_babylon_left_handed(browser_results):
    """Default left-handed scene: the glTF loader turns the asset 180° about +Y (root node),
    the environment stays in the world: a normal n of the asset sees E(−x, y, −z)."""
    r = browser_results["babylon", False]
    turned = NORMALS * np.array([-1.0, 1.0, -1.0])
    check("Babylon.js (LH scene) harmonics", r["cases"], "harmonics",
          lambda k: irradiance(lightings()[k], turned))


@pytest.mark.browser
def test_babylon_polynomial_path(browser_results):
    """Babylon's other shader path (useSphericalHarmonics = false) evaluates its
    SphericalPolynomial, which applies Â_l/π once more (updateFromHarmonics' constants):
    what it shows is the irradiance of E/π, not E — a Babylon inconsistency, recorded so a
    change in Babylon is noticed. (Its constant 0.886277 for π·0.282095 = 0.886227 is off by
    5.6e-5, hence the looser tolerance.)"""
    r = browser_results["babylon", True]["cases"]
    for name, L in lightings().items():
        twice = irradiance(irradiance_coeffs(L), NORMALS) / np.pi
        assert rel(r[name]["polynomial"], twice) <= 1e-4


HLSL_MAIN = """
Texture2D<float4> normals : register(t0);
struct ShprobeOut { float4 irr : SV_Target0; float4 poly : SV_Target1; float4 nrm : SV_Target2; };
ShprobeOut main(float4 pos : SV_Position) {
    float3 n = normals.Load(int3(int2(pos.xy), 0)).xyz;
    ShprobeOut o;
    o.irr = float4(shprobe_irradiance(n), 1.0);
    o.poly = float4(shprobe_irradiance_poly(n), 1.0);
    o.nrm = float4(n, 1.0);
    return o;
}
"""


def hlsl_as_glsl_es(hlsl_cases: list[dict[str, str]]) -> list[dict[str, str]] | str:
    """Each HLSL export with a pixel-shader entry, compiled by glslang's HLSL front end to
    SPIR-V and turned into GLSL ES 3.00 by SPIRV-Cross, for WebGL2 to run; or why not."""
    import tempfile

    glslang, cross = shutil.which("glslangValidator"), shutil.which("spirv-cross")
    if glslang is None or cross is None:
        return "glslangValidator / spirv-cross not installed (.ci/run installs both)"
    out = []
    with tempfile.TemporaryDirectory() as d:
        for c in hlsl_cases:
            src, spv = Path(d) / f"{c['name']}.hlsl", Path(d) / f"{c['name']}.spv"
            src.write_text(c["text"] + HLSL_MAIN)
            r = subprocess.run([glslang, "-D", "-V", "-S", "frag", "-e", "main", "-o", str(spv),
                                str(src)], capture_output=True, text=True, timeout=120)
            assert r.returncode == 0, r.stdout + r.stderr
            r = subprocess.run([cross, "--es", "--version", "300", str(spv)],
                               capture_output=True, text=True, timeout=120)
            assert r.returncode == 0, r.stderr
            out.append({"name": c["name"], "text": r.stdout})
    return out


@pytest.mark.parametrize("fn", ["webgl2", "webgpu", "hlsl-webgl2"])
@pytest.mark.browser
def test_shaders_on_the_gpu(browser_results, fn):
    """GLSL export compiled by WebGL2 (GLSL ES 3.00, ANGLE on SwiftShader), WGSL by Chromium's
    WebGPU (Tint, SwiftShader adapter), HLSL by glslang's HLSL front end → SPIR-V →
    SPIRV-Cross → WebGL2: both functions run over the normals; the normals each invocation
    used are read back and E computed at those (float32) normals."""
    res = browser_results[fn]
    if "skip" in res:
        pytest.skip(res["skip"])
    for name in res:
        assert "error" not in res[name], res[name]
    for key in ("irradiance", "poly"):
        for name, L in lightings().items():
            used = np.reshape(res[name]["normals"], (-1, 3))
            np.testing.assert_allclose(used, NORMALS, atol=1e-7)
            assert record(f"{fn} shprobe_{key}", name,
                          rel(res[name][key], irradiance(L, used))) <= TOL
    used = np.reshape(res[FLIPPED]["normals"], (-1, 3))
    assert rel(res[FLIPPED]["irradiance"], irradiance(lightings()["grace"], used)) > 1e-3
    if fn == "webgpu":  # the bare export compiles without a message (error or warning)
        for name in lightings():
            assert res[name]["messages"] == [], res[name]["messages"]


@pytest.mark.browser
def test_babylon_specular_cube(browser_results):
    """The specular cube maps (RGBD PNGs, every mip, faces +X ... -Z) as Babylon.js decoded them
    into its float cube texture hold E/π (clamped at 0) of the glTF direction
    (x, y, −z) of each texel's cube direction — the same frame as the harmonics. 8-bit RGBD
    with gamma 1/2.2: within 1 % of the peak; the same faces upside down are far off."""
    from shprobe.probes.layouts import get_layout

    r = browser_results["babylon", True]["cases"]
    for name, L in lightings().items():
        cube = r[name]["cube"]
        levels = len(cube) // 6
        worst = 0.0
        for level in range(levels):
            size = 8 >> level
            dirs = get_layout("cube").pixel_directions((6, size, size))
            ref = np.maximum(irradiance(L, dirs * np.array([1.0, 1.0, -1.0])), 0.0) / np.pi
            got = np.array(cube[6 * level: 6 * level + 6], float).reshape(6, size, size, 4)
            worst = max(worst, rel(got[..., :3], ref))
            if level == 0:
                assert rel(got[:, ::-1, :, :3], ref) > 0.05  # upside down is noticed
        assert record("Babylon.js specular cube (RGBD)", name, worst) <= 1e-2
