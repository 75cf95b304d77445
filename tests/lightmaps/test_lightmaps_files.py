"""Lightmap files and the command: the .glb passes the Khronos glTF-Validator with no error,
load_lightmap gives back the baked coefficients, and bad input is one line before any work."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from shprobe.lightmaps import LightmapSettings, bake_lightmap, load_lightmap
from shprobe.lightmaps import format as fmt
from shprobe.lightmaps.scene import LightmapScene, Primitive

sys.path.insert(0, str(Path(__file__).parent))
from test_lightmaps_bake import SKY, _plane, _room

CONSUMERS = Path(__file__).resolve().parents[1] / "consumers"


def _validate(*paths: Path) -> dict:
    node = shutil.which("node")
    if node is None or not (CONSUMERS / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("node or gltf-validator not installed (cd tests/consumers && npm ci)")
    res = subprocess.run([node, str(CONSUMERS / "validate_glb.mjs"), *map(str, paths)],
                         capture_output=True, text=True, timeout=300, cwd=CONSUMERS)
    assert res.returncode == 0, res.stderr[-2000:]
    return json.loads(res.stdout)


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    lm = bake_lightmap(_room(), SKY, LightmapSettings(size=32, samples=16, bounces=1))
    out = tmp_path_factory.mktemp("lm") / "room.glb"
    lm.save(out)
    return lm, out


@pytest.mark.node
def test_the_glb_passes_the_validator_and_keeps_the_extension_optional(room):
    _, out = room
    report = _validate(out)[out.name]
    assert report["numErrors"] == 0, report["messages"]
    doc, _ = fmt.read_glb(out)
    assert fmt.EXTENSION in doc["extensionsUsed"]
    assert fmt.EXTENSION not in doc.get("extensionsRequired", [])
    for m, k in [(p["mesh"], p["primitive"]) for p in
                 doc["extensions"][fmt.EXTENSION]["primitives"]]:
        att = doc["meshes"][m]["primitives"][k]["attributes"]
        assert {"TEXCOORD_1", "TANGENT", "POSITION", "NORMAL"} <= set(att)


def test_load_lightmap_round_trip_equals_the_bake(room):
    lm, out = room
    back = load_lightmap(out)
    assert back.basis == lm.basis == "h6" and (back.width, back.height) == (32, 32)
    want = lm.coefficients()
    np.testing.assert_allclose(back.coefficients(), want, rtol=1e-3,
                               atol=1e-3 * np.abs(want).max())
    # the same irradiance from the file, at texels and (bilinearly) at UVs
    rc = np.argwhere(lm.valid)[:20]
    n = np.tile([0.3, 0.1, 0.95], (20, 1)) / np.linalg.norm([0.3, 0.1, 0.95])
    peak = np.abs(lm.irradiance(rc, n)).max()
    np.testing.assert_allclose(back.irradiance(rc, n), lm.irradiance(rc, n), atol=2e-3 * peak)
    uv = (rc[:, ::-1] + 0.5) / 32.0
    np.testing.assert_allclose(back.irradiance(uv, n), lm.irradiance(rc, n), atol=2e-3 * peak)


def test_the_baked_scene_reloads_with_its_texcoord_1(tmp_path):
    """A .glb written by the bake is itself a scene with TEXCOORD_1: baking it again uses
    those UVs (no new atlas), covers the same texels and gives the same lightmap to noise."""
    settings = LightmapSettings(size=32, samples=256, bounces=1)
    first = bake_lightmap(_room(), SKY, settings)
    first.save(tmp_path / "first.glb")
    again = bake_lightmap(tmp_path / "first.glb", SKY, settings)
    assert again.stats["atlas"] == "TEXCOORD_1" and again.stats["uv_overlap"] < 0.001
    both = first.valid & again.valid
    assert both.sum() >= 0.97 * first.valid.sum()
    a, b = first.coefficients("plain")[both], again.coefficients("plain")[both]
    assert np.sqrt(np.mean((a - b) ** 2)) < 0.05 * np.abs(a).mean()


# ----------------------------------------------------------------------------- the command

def _write_scene(path: Path, positions, faces, uv1=None, image: bytes | None = None) -> Path:
    doc: dict = {"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "scene": 0,
                 "nodes": [{"mesh": 0}], "buffers": [{}], "bufferViews": [], "accessors": []}
    binary = bytearray()

    def acc(a, kind, ctype=5126):
        a = np.ascontiguousarray(a, dtype=np.float32 if ctype == 5126 else np.uint32)
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(binary),
                                   "byteLength": a.nbytes})
        binary.extend(a.tobytes())
        doc["accessors"].append({"bufferView": len(doc["bufferViews"]) - 1,
                                 "componentType": ctype, "count": len(a), "type": kind})
        return len(doc["accessors"]) - 1

    att = {"POSITION": acc(positions, "VEC3")}
    if uv1 is not None:
        att["TEXCOORD_1"] = acc(uv1, "VEC2")
    prim = {"attributes": att, "indices": acc(np.ravel(faces), "SCALAR", 5125)}
    if image is not None:
        att["TEXCOORD_0"] = acc(np.full((len(positions), 2), 0.1), "VEC2")
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(binary),
                                   "byteLength": len(image)})
        binary.extend(image + b"\0" * (-len(image) % 4))
        doc["images"] = [{"bufferView": len(doc["bufferViews"]) - 1, "mimeType": "image/png"}]
        doc["textures"] = [{"source": 0}]
        doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
        prim["material"] = 0
    doc["meshes"] = [{"primitives": [prim]}]
    doc["buffers"][0]["byteLength"] = len(binary)
    path.write_bytes(fmt.encode_glb(doc, binary))
    return path


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "shprobe", "lightmap", "bake", *map(str, args)],
                          capture_output=True, text=True, timeout=300, cwd=cwd)


QUAD = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
TWO = np.array([[0, 1, 2], [0, 2, 3]])


@pytest.mark.parametrize("case, args, message", [
    ("empty", [], "no triangles"),
    ("nan", [], "NaN or infinite"),
    ("huge", [], "beyond"),
    ("flat-uv", [], "TEXCOORD_1 is degenerate"),
    ("bad-texture", [], "cannot be decoded"),
    ("ok", ["--size", "0"], "--size must be an integer from 4"),
    ("ok", ["--size", "65536"], "--size must be an integer from 4"),
    ("ok", ["--no-light"], "give exactly one lighting source"),
    ("ok", ["--coeffs", "x.npy"], "give exactly one lighting source"),
])
def test_bad_input_is_one_line_before_any_work(tmp_path, case, args, message):
    scene = tmp_path / "s.glb"
    if case == "empty":
        scene.write_bytes(fmt.encode_glb({"asset": {"version": "2.0"}}, b""))
    elif case == "nan":
        bad = QUAD.copy()
        bad[0, 0] = np.nan
        _write_scene(scene, bad, TWO)
    elif case == "huge":
        _write_scene(scene, QUAD * 1e30, TWO)
    elif case == "flat-uv":
        _write_scene(scene, QUAD, TWO, uv1=np.zeros((4, 2)))
    elif case == "bad-texture":
        _write_scene(scene, QUAD, TWO, image=b"\x89PNG not really a png")
    else:
        _write_scene(scene, QUAD, TWO)
    light = [] if "--no-light" in args else ["--preset", "grace"]
    args = [a for a in args if a != "--no-light"]
    res = _cli(scene, *light, *args, "-o", tmp_path / "out.glb", cwd=tmp_path)
    assert res.returncode != 0
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], res.stderr
    assert "Traceback" not in res.stderr
    assert not (tmp_path / "out.glb").exists()


def test_overlapping_texcoord_1_is_warned_with_its_share(tmp_path):
    pos = np.concatenate([QUAD, np.add(QUAD, [0, 0, 2])])
    uv = np.concatenate([QUAD[:, :2], QUAD[:, :2]]) * 0.5 + 0.25  # both quads on one region
    scene = _write_scene(tmp_path / "s.glb", pos, np.concatenate([TWO, TWO + 4]), uv1=uv)
    res = _cli(scene, "--preset", "grace", "--size", "16", "--samples", "4", "-o",
               tmp_path / "out.glb")
    assert res.returncode == 0, res.stderr
    warn = [ln for ln in res.stderr.splitlines() if "overlaps" in ln]
    assert len(warn) == 1 and "100.0 %" in warn[0], res.stderr


def test_an_existing_output_is_kept_and_an_interrupted_bake_leaves_nothing(tmp_path,
                                                                           monkeypatch):
    scene = _write_scene(tmp_path / "s.glb", QUAD, TWO)
    out = tmp_path / "out.glb"
    out.write_bytes(b"keep me")
    res = _cli(scene, "--preset", "grace", "-o", out)
    assert res.returncode != 0 and "already exists" in res.stderr
    assert out.read_bytes() == b"keep me"
    # an interruption while the file is being written: nothing is left, the old file stays
    from shprobe.lightmaps import glb

    def boom(*a, **k):
        raise KeyboardInterrupt

    lm = bake_lightmap(LightmapScene([_plane()]), SKY, LightmapSettings(size=8, samples=4))
    monkeypatch.setattr(glb, "encode_glb", lambda doc, b: b"partial" * 100)
    real_open = open

    def failing_open(path, mode="r", *a, **k):
        f = real_open(path, mode, *a, **k)
        if "w" in mode and str(path).endswith(".glb"):
            f.write(b"partial")
            boom()
        return f

    monkeypatch.setattr("builtins.open", failing_open)
    with pytest.raises(KeyboardInterrupt):
        lm.save(tmp_path / "new.glb")
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.glb", "s.glb"]


def test_the_command_bakes_and_says_what_it_wrote(tmp_path):
    scene = _write_scene(tmp_path / "s.glb", QUAD, TWO)
    res = _cli(scene, "--preset", "grace", "--size", "16", "--samples", "4", "--basis", "sh9",
               "-o", tmp_path / "out.glb")
    assert res.returncode == 0, res.stderr
    assert "wrote" in res.stderr and "sh9" in res.stderr
    assert load_lightmap(tmp_path / "out.glb").basis == "sh9"


def test_primitive_is_usable_without_glTF(tmp_path):
    """Scenes made in code (no glTF document) are written as fresh documents, textures as
    PNG images."""
    lm = bake_lightmap(_room(), SKY, LightmapSettings(size=16, samples=4, bounces=0))
    lm.save(tmp_path / "a.glb")
    doc, _ = fmt.read_glb(tmp_path / "a.glb")
    assert len(doc["images"]) == 1 and "normalTexture" in doc["materials"][0]
    assert isinstance(lm.texels, object) and isinstance(_room().primitives[0], Primitive)


def test_the_game_scene_bakes_to_a_valid_glb_that_keeps_its_materials(tmp_path):
    from shprobe.lightmaps.scenes import game_scene_path

    out = tmp_path / "game.glb"
    res = _cli(game_scene_path(), "--preset", "grace", "--sun", "0.3,1,0.2,2,2,2", "--size",
               "64", "--samples", "4", "--basis", "h4", "-o", out)
    assert res.returncode == 0, res.stderr
    report = _validate(out)["game.glb"]
    assert report["numErrors"] == 0, report["messages"]
    src, _ = fmt.read_glb(game_scene_path())
    doc, _ = fmt.read_glb(out)
    assert doc["materials"] == src["materials"] and len(doc["images"]) == len(src["images"])
    assert load_lightmap(out).coefficients().shape == (64, 64, 4, 3)


def test_a_bake_over_the_memory_limit_is_refused_in_one_line(tmp_path):
    import os

    scene = _write_scene(tmp_path / "s.glb", QUAD, TWO)
    env = {**os.environ, "SHPROBE_MAX_MEMORY": "2M"}
    res = subprocess.run([sys.executable, "-m", "shprobe", "lightmap", "bake", str(scene),
                          "--preset", "grace", "--size", "512", "-o", str(tmp_path / "o.glb")],
                         capture_output=True, text=True, timeout=300, env=env)
    assert res.returncode != 0
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "over the limit" in lines[0], res.stderr


def test_irradiance_at_world_points_reads_their_texel(room):
    lm, _ = room
    tx = lm.texels
    i = np.flatnonzero(tx.inside)[:10]
    n = np.tile([0.0, 0.0, 1.0], (10, 1))
    np.testing.assert_array_equal(lm.irradiance(tx.points[i] + 1e-6, n),
                                  lm.irradiance(tx.rc[i], n))


def test_an_obj_scene_bakes_to_a_valid_glb(tmp_path):
    obj = tmp_path / "corner.obj"
    obj.write_text("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nv -1 -1 1\nv 1 -1 1\n"
                   "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                   "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\nf 1/1 5/4 6/3\nf 1/1 6/3 2/2\n")
    res = _cli(obj, "--preset", "grace", "--size", "32", "--samples", "16", "-o",
               tmp_path / "corner.glb")
    assert res.returncode == 0, res.stderr
    assert _validate(tmp_path / "corner.glb")["corner.glb"]["numErrors"] == 0
    lm = load_lightmap(tmp_path / "corner.glb")
    assert np.isfinite(lm.coefficients()).all() and lm.coefficients()[..., 0, :].max() > 0
