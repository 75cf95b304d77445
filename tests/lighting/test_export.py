"""Export / import: round trips, each engine's convention checked by evaluating the exported
numbers the way that engine does, and the shader snippets compiled by glslangValidator."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.lighting.export import FORMATS, export_coeffs, import_coeffs, parse_coeffs
from shprobe.sh import sh_basis
from shprobe.sh.zonal import clamped_cosine_factors
from tests.conftest import random_dirs

L9 = np.random.default_rng(42).normal(size=(9, 3))
DIRS = random_dirs(200, seed=5)
A9 = clamped_cosine_factors(2)[[0, 1, 1, 1, 2, 2, 2, 2, 2]]


def E_true(L, n):
    return (sh_basis(n, 2) * A9) @ L


def poly9(n):
    """The unnormalised l ≤ 2 polynomials 1, y, z, x, xy, yz, 3z²−1, xz, x²−y²."""
    x, y, z = n.T
    return np.stack([np.ones_like(x), y, z, x, x * y, y * z, 3 * z * z - 1, x * z,
                     x * x - y * y], -1)


@pytest.mark.parametrize("fmt", FORMATS)
def test_round_trip(fmt, tmp_path):
    text = export_coeffs(L9, fmt, source="probe.hdr")
    p = tmp_path / f"out.{fmt}"
    p.write_text(text)
    back = import_coeffs(p)
    tol = 1e-8 if fmt in ("glsl", "hlsl", "wgsl") else 1e-13
    np.testing.assert_allclose(back, L9, atol=tol)
    assert parse_coeffs(text)[1] == fmt
    # every export says what it stores
    low = text.lower()
    assert "condon" in low or "r&h" in low or "no condon" in low
    assert "pi" in low or "π" in low


@pytest.mark.parametrize("fmt", ["json", "cs-phase"])
def test_round_trip_any_lmax(fmt, tmp_path):
    L = np.random.default_rng(1).normal(size=(25, 2))
    (tmp_path / "c.json").write_text(export_coeffs(L, fmt))
    np.testing.assert_allclose(import_coeffs(tmp_path / "c.json"), L, atol=1e-14)


def test_l2_formats_refuse_higher_lmax():
    with pytest.raises(ShprobeError):
        export_coeffs(np.zeros((16, 3)), "glsl")
    with pytest.raises(ShprobeError):
        export_coeffs(L9, "bogus")


def _eval_shader_poly(text):
    """Evaluate the eq. 13 function body of a GLSL export in numpy (transliteration)."""
    consts = dict(re.findall(r"const float (c\d) = ([-0-9.e]+);", text))
    arr = re.search(r"SHPROBE_L\[9\] = vec3\[9\]\((.*?)\);", text, re.S).group(1)
    Ls = np.array([[float(v) for v in re.findall(r"[-+]?[0-9.]+(?:e[-+]?\d+)?", row)]
                   for row in re.findall(r"vec3\(([^)]*)\)", arr)])
    body = re.search(r"vec3 shprobe_irradiance_poly\(vec3 n\).*?return (.*?);", text,
                     re.S).group(1)
    body = " ".join(re.sub(r"SHPROBE_L\[(\d)\]", r"Ls[\1]", body).split())
    out = []
    for x, y, z in DIRS:
        env = {"Ls": Ls, "x": x, "y": y, "z": z, **{k: float(v) for k, v in consts.items()}}
        out.append(eval(body, {}, env))
    return np.array(out)


def test_glsl_functions_compute_E():
    text = export_coeffs(L9, "glsl")
    np.testing.assert_allclose(_eval_shader_poly(text), E_true(L9, DIRS), atol=1e-7)
    # eq. 11 form: the baked matrices give E
    M = {ch: np.array([float(v) for v in re.findall(
        r"[-+]?[0-9.]+(?:e[-+]?\d+)?", re.search(rf"SHPROBE_M_{ch} = mat4\((.*?)\)", text)
        .group(1))]).reshape(4, 4) for ch in "RGB"}
    p = np.concatenate([DIRS, np.ones((len(DIRS), 1))], 1)
    got = np.stack([np.einsum("pi,ij,pj->p", p, M[ch], p) for ch in "RGB"], -1)
    np.testing.assert_allclose(got, E_true(L9, DIRS), atol=1e-7)


def test_three_js_convention():
    """three.js getIrradianceAt (R&H constants, rounded to 6 digits) on the exported array."""
    c = np.array(json.loads(export_coeffs(L9, "three"))["coefficients"]).reshape(9, 3)
    x, y, z = DIRS.T
    w = np.stack([0.886227 + 0 * x, 2 * 0.511664 * y, 2 * 0.511664 * z, 2 * 0.511664 * x,
                  2 * 0.429043 * x * y, 2 * 0.429043 * y * z, 0.743125 * z * z - 0.247708,
                  2 * 0.429043 * x * z, 0.429043 * (x * x - y * y)], -1)
    np.testing.assert_allclose(w @ c, E_true(L9, DIRS), rtol=1e-5, atol=2e-5)


def test_gltf_convention_as_babylon_reads_it():
    """Babylon: CS-signed basis constants, irradiance coefficients, then ÷π for radiance, in
    the cube-map frame where the glTF direction (x, y, z) is looked up at (x, y, −z)
    (proved against Babylon.js itself in test_export_consumers.py)."""
    doc = json.loads(export_coeffs(L9, "gltf"))
    E = np.array(doc["extensions"]["EXT_lights_image_based"]["lights"][0]
                 ["irradianceCoefficients"])
    assert E.shape == (9, 3)
    s3, s15 = np.sqrt(3 / (4 * np.pi)), np.sqrt(15 / (4 * np.pi))
    K_cs = np.array([np.sqrt(1 / (4 * np.pi)), -s3, s3, -s3, s15, -s15,
                     np.sqrt(5 / (16 * np.pi)), -s15, np.sqrt(15 / (16 * np.pi))])
    cube = DIRS * np.array([1.0, 1.0, -1.0])
    np.testing.assert_allclose((poly9(cube) * K_cs) @ E, E_true(L9, DIRS), atol=1e-12)


def test_cmgen_convention_is_E_over_pi_polynomial():
    text = export_coeffs(L9, "cmgen")
    rows = re.findall(r"^\(([^)]*)\);", text, re.M)
    assert len(rows) == 9 and "irradiance, pre-scaled base" in text
    c = np.array([[float(v) for v in r.split(",")] for r in rows])
    np.testing.assert_allclose(poly9(DIRS) @ c, E_true(L9, DIRS) / np.pi, atol=1e-13)


def test_cs_phase_matches_google_hardcoded_basis():
    """google/spherical-harmonics' hard-coded l ≤ 2 basis carries the CS phase."""
    c = np.array(json.loads(export_coeffs(L9, "cs-phase"))["coefficients"])
    x, y, z = DIRS.T
    Y = np.stack([0.282095 + 0 * x, -0.488603 * y, 0.488603 * z, -0.488603 * x,
                  1.092548 * x * y, -1.092548 * y * z, 0.315392 * (3 * z * z - 1),
                  -1.092548 * x * z, 0.546274 * (x * x - y * y)], -1)
    np.testing.assert_allclose(Y @ c, sh_basis(DIRS, 2) @ L9, rtol=2e-6, atol=2e-6)


def test_import_errors(tmp_path):
    cases = {"a.json": "{not json", "b.json": '{"format": "shprobe-coeffs", '
             '"coefficients": [[1], [2]]}', "c.txt": "hello", "d.glsl": "SHPROBE_M_R = mat4(1)"}
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(ShprobeError) as e:
            import_coeffs(tmp_path / name)
        assert name in str(e.value)
    with pytest.raises(ShprobeError):
        import_coeffs(tmp_path / "missing.json")


GLSLANG = shutil.which("glslangValidator")


@pytest.mark.skipif(GLSLANG is None, reason="glslangValidator not installed "
                    "(apt-get install glslang-tools)")
@pytest.mark.parametrize("fmt", ["glsl", "hlsl"])
def test_shader_compiles(fmt, tmp_path):
    snippet = export_coeffs(L9, fmt, source="test")
    if fmt == "glsl":
        src = ("#version 450\n" + snippet + "layout(location = 0) in vec3 nrm;\n"
               "layout(location = 0) out vec4 col;\n"
               "void main() { vec3 n = normalize(nrm);\n"
               "  col = vec4(shprobe_irradiance(n) + shprobe_irradiance_poly(n), 1.0); }\n")
        path = tmp_path / "t.frag"
        cmd = [GLSLANG, str(path)]
    else:
        src = (snippet + "float4 main(float3 nrm : TEXCOORD0) : SV_Target {\n"
               "  float3 n = normalize(nrm);\n"
               "  return float4(shprobe_irradiance(n) + shprobe_irradiance_poly(n), 1.0); }\n")
        path = tmp_path / "t.hlsl"
        cmd = [GLSLANG, "-D", "-V", "-S", "frag", "-e", "main", "-o", str(tmp_path / "t.spv"),
               str(path)]
    path.write_text(src)
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.mark.parametrize("fmt", FORMATS)
def test_every_command_reads_every_format_back(fmt, tmp_path, capsys):
    """`prefilter --format F -o FILE`, then `--coeffs FILE` in each command that takes it: the
    same lighting comes back (cs-phase signs and gltf/cmgen scalings undone)."""
    from shprobe.cli.main import main
    from shprobe.lighting.irradiance import irradiance, irradiance_map
    from shprobe.probes.images import read_image
    from shprobe.probes.presets import get_preset

    L = get_preset("grace")
    f = tmp_path / f"c.{fmt}"
    assert main(["prefilter", "--preset", "grace", "--format", fmt, "-o", str(f)]) == 0
    capsys.readouterr()
    assert main(["prefilter", "--coeffs", str(f), "--format", "json",
                 "-o", str(tmp_path / "p.json")]) == 0
    back = np.array(json.loads((tmp_path / "p.json").read_text())["coefficients"])
    np.testing.assert_allclose(back, L, atol=5e-6)
    assert main(["export", "--coeffs", str(f), "--format", "json",
                 "-o", str(tmp_path / "x.json")]) == 0
    np.testing.assert_allclose(import_coeffs(tmp_path / "x.json"), L, atol=5e-6)
    assert main(["irradiance", "--coeffs", str(f), "--size", "16x8",
                 "-o", str(tmp_path / "e.exr")]) == 0
    want = irradiance_map(L, "latlong", (16, 8)).radiance
    np.testing.assert_allclose(read_image(tmp_path / "e.exr"), want, rtol=1e-4, atol=1e-4)
    assert main(["render", "--coeffs", str(f), "--sphere", "--size", "16x16",
                 "-o", str(tmp_path / "r.exr")]) == 0
    img = read_image(tmp_path / "r.exr")
    assert img[8, 8] == pytest.approx(irradiance(L, [0.0, 0.0, 1.0]) / np.pi, rel=0.05)


def test_import_three_light_probe_json_cmgen_labels_and_gltf_document(tmp_path):
    """three.js LightProbe.toJSON() (object.sh × intensity); cmgen rows labelled otherwise
    than 'irradiance, pre-scaled base' are refused; the glTF export is a glTF 2.0 document
    whose scene refers to the light."""
    doc = {"metadata": {"version": 4.6, "type": "Object"},
           "object": {"uuid": "x", "type": "LightProbe", "layers": 1, "intensity": 2.0,
                      "sh": L9.reshape(-1).tolist()}}
    (tmp_path / "probe.json").write_text(json.dumps(doc))
    np.testing.assert_allclose(import_coeffs(tmp_path / "probe.json"), 2.0 * L9, atol=1e-12)
    good = export_coeffs(L9, "cmgen")
    np.testing.assert_allclose(parse_coeffs(good)[0], L9, atol=1e-12)
    bad = good.replace("irradiance, pre-scaled base", "radiance")
    with pytest.raises(ShprobeError, match="pre-scaled base"):
        parse_coeffs(bad, "sh.txt")
    unlabelled = "\n".join(line.split("//")[0] for line in good.splitlines()
                           if line.startswith("("))
    np.testing.assert_allclose(parse_coeffs(unlabelled)[0], L9, atol=1e-12)
    g = json.loads(export_coeffs(L9, "gltf"))
    assert g["asset"]["version"] == "2.0"
    assert g["scenes"][g["scene"]]["extensions"]["EXT_lights_image_based"]["light"] == 0
