"""The packaged game scene (tools/make_game_scene.py): the committed file is the script's
output, the Khronos glTF-Validator finds no error, trimesh loads it, and its normal maps and
tangents follow glTF's conventions (checked from the geometry and the height field's
known slopes, not from the script's own formulas)."""

from __future__ import annotations

import importlib.util
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from shprobe.lightmaps import format as fmt
from shprobe.lightmaps.scenes import game_scene_path
from tests.packaging.test_packaging import dists  # noqa: F401  (the built sdist and wheels, once per run)

REPO = Path(__file__).resolve().parents[2]
CONSUMERS = REPO / "tests" / "consumers"


def _script():
    spec = importlib.util.spec_from_file_location("make_game_scene",
                                                  REPO / "tools" / "make_game_scene.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _accessor(doc: dict, binary: bytes, i: int) -> np.ndarray:
    a = doc["accessors"][i]
    v = doc["bufferViews"][a["bufferView"]]
    dt = {5126: np.float32, 5123: np.uint16, 5125: np.uint32}[a["componentType"]]
    n = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[a["type"]]
    off = v.get("byteOffset", 0) + a.get("byteOffset", 0)
    return np.frombuffer(binary, dt, a["count"] * n, off).reshape(a["count"], n)


def test_the_committed_scene_is_the_scripts_output():
    assert game_scene_path().read_bytes() == _script().make()


def test_the_scene_is_small_and_has_what_a_game_scene_has():
    raw = game_scene_path().read_bytes()
    assert len(raw) < 1_500_000
    doc, _ = fmt.parse_glb(raw)
    assert {n["name"] for n in doc["nodes"]} == {"floor", "walls", "arcade", "pillars", "crates"}
    tris = 0
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            assert {"POSITION", "NORMAL", "TANGENT", "TEXCOORD_0"} <= set(prim["attributes"])
            assert "TEXCOORD_1" not in prim["attributes"]  # the bake makes the atlas
            mat = doc["materials"][prim["material"]]
            assert "baseColorTexture" in mat["pbrMetallicRoughness"] and "normalTexture" in mat
            tris += doc["accessors"][prim["indices"]]["count"] // 3
    assert 2000 <= tris <= 5000


def test_trimesh_loads_it_with_its_textures():
    trimesh = pytest.importorskip("trimesh")
    sc = trimesh.load(game_scene_path())
    assert len(sc.geometry) == 5
    for g in sc.geometry.values():
        m = g.visual.material
        assert g.visual.uv.shape == (len(g.vertices), 2)
        assert m.baseColorTexture.size == (256, 256) and m.normalTexture.size == (256, 256)
    lo, hi = sc.bounds
    np.testing.assert_allclose(lo, [-8.5, 0, -8.5], atol=1e-6)
    np.testing.assert_allclose(hi, [8.5, 6, 8.5], atol=1e-6)


def test_tangent_frames_follow_gltf():
    """TANGENT is unit, orthogonal to NORMAL, along increasing u; cross(N, T)·w points up the
    image (decreasing v), which on the walls is world up (v = −height / 2 m)."""
    doc, binary = fmt.parse_glb(game_scene_path().read_bytes())
    for mesh in doc["meshes"]:
        at = mesh["primitives"][0]["attributes"]
        p, n = _accessor(doc, binary, at["POSITION"]), _accessor(doc, binary, at["NORMAL"])
        t, uv = _accessor(doc, binary, at["TANGENT"]), _accessor(doc, binary, at["TEXCOORD_0"])
        f = _accessor(doc, binary, mesh["primitives"][0]["indices"]).reshape(-1, 3)
        np.testing.assert_allclose(np.linalg.norm(t[:, :3], axis=1), 1, atol=1e-5)
        assert np.abs(np.sum(t[:, :3] * n, 1)).max() < 1e-5
        b = np.cross(n, t[:, :3]) * t[:, 3:]
        # on every triangle, moving along T raises u and moving along B lowers v
        e1, e2 = p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]
        d1, d2 = uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]
        g = np.linalg.pinv(np.stack([e1, e2], 1))  # (F, 3, 2): world step → edge weights
        grad_u = np.einsum("fij,fj->fi", g, np.stack([d1[:, 0], d2[:, 0]], 1))
        grad_v = np.einsum("fij,fj->fi", g, np.stack([d1[:, 1], d2[:, 1]], 1))
        assert (np.sum(grad_u * t[f[:, 0], :3], 1) > 0).all()
        assert (np.sum(grad_v * b[f[:, 0]], 1) < 0).all()
        if mesh["name"] == "walls":
            side = np.abs(n[:, 1]) < 0.5
            np.testing.assert_allclose(b[side], np.broadcast_to([0, 1, 0], b[side].shape),
                                       atol=1e-6)


def test_normal_maps_are_opengl_style():
    """A brick's top edge (just below the mortar above it in the image) slopes down toward
    image up, so its normal leans up the image: green > 128; its left edge leans left: red
    < 128 (glTF: +X right, +Y up, 8-bit unsigned)."""
    mod = _script()
    _, nmap = mod.brick(np.random.default_rng(12))
    row, col = 3, 32  # the first course: mortar at rows 0-1, the brick's middle column
    assert nmap[row, col, 1] > 160 and abs(int(nmap[row, col, 0]) - 128) < 20
    assert nmap[16, 2, 0] < 96 and abs(int(nmap[16, 2, 1]) - 128) < 20
    assert (nmap[..., 2] > 128).all()  # every normal points out of the surface


@pytest.mark.node
def test_gltf_validator_finds_no_issue():
    node = shutil.which("node")
    if node is None or not (CONSUMERS / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("node or tests/consumers' npm packages missing (npm ci in tests/consumers)")
    res = subprocess.run([node, str(CONSUMERS / "validate_glb.mjs"), str(game_scene_path())],
                         capture_output=True, text=True, timeout=300, cwd=CONSUMERS)
    assert res.returncode == 0, res.stderr[-2000:]
    report = json.loads(res.stdout)["courtyard.glb"]
    assert report["numErrors"] == 0 and report["numWarnings"] == 0, report["messages"]


@pytest.mark.slow
def test_the_wheel_ships_the_game_scene(dists):  # noqa: F811
    from tests.packaging.test_packaging import wheel_files

    files = wheel_files(dists["wheel"])
    assert files["shprobe/lightmaps/data/courtyard.glb"] == game_scene_path().read_bytes()
    viewer = {"shprobe/viewer/static/lightmap.html", "shprobe/viewer/static/lightmap.js",
              "shprobe/viewer/static/lightmap_gl.js", "shprobe/viewer/static/lightmap_glb.js",
              "shprobe/viewer/static/lightmap.css"}
    assert viewer <= set(files)
