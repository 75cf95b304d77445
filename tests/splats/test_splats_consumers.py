"""PlayCanvas splat-transform (npm, pinned in tests/consumers) and the Khronos glTF-Validator
as consumers of shprobe's splat files.

- its rotation of a file and ours agree coefficient by coefficient;
- our SPZ, read back by it, equals the PLY (to SPZ's quantisation) and what we read;
- its SPZ (version 4, zstd) read by us equals what it reads;
- our .glb holds what its own .glb of the same file holds, attribute by attribute;
- the validator finds no error in our .glb but the ones it raises for every
  ``KHR_gaussian_splatting`` file (it does not know the extension), and none at all once the
  extension's attributes are renamed to application-specific ``_`` names.
"""

from __future__ import annotations

import json
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from shprobe import splats as sp
from shprobe.cli.main import main
from shprobe.splats import gltf
from tests.splats import splat_reference as ref

pytestmark = pytest.mark.node

CONSUMERS = Path(__file__).resolve().parents[1] / "consumers"
CLI = CONSUMERS / "node_modules" / "@playcanvas" / "splat-transform" / "bin" / "cli.mjs"


@pytest.fixture(scope="module")
def node() -> str:
    exe = shutil.which("node")
    if exe is None:
        pytest.skip("node not installed (.ci/run installs the consumers with npm ci)")
    if not CLI.is_file():
        pytest.skip("npm package @playcanvas/splat-transform not installed "
                    "(cd tests/consumers && npm ci)")
    return exe


def _st(node: str, *args: str) -> None:
    res = subprocess.run([node, str(CLI), "-q", "-w", *args], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("splats")
    s = ref.random_splats(2000, 3, seed=11)
    s["sh"][:, 1:] = np.clip(s["sh"][:, 1:], -0.99, 0.99)  # SPZ's SH range
    ref.write_trainer_ply(d / "in.ply", s)
    return d, s


def _cov(x: dict) -> np.ndarray:
    return ref.covariance(x["rot"], x["log_scales"])


def test_its_rotation_and_ours_agree_coefficient_by_coefficient(node, scene):
    d, s = scene
    _st(node, str(d / "in.ply"), "-r", "0,90,0", str(d / "st_y90.ply"))
    # splat-transform turns in its engine frame, the PLY turned 180° about z: 90° about its
    # y is −90° about the PLY's y
    assert main(["-q", "splat", "transform", str(d / "in.ply"), "-o", str(d / "ours_y90.ply"),
                 "--rotate", "0,1,0:-90"]) == 0
    theirs, ours = ref.read_trainer_ply(d / "st_y90.ply"), ref.read_trainer_ply(d / "ours_y90.ply")
    assert np.abs(ours["pos"] - theirs["pos"]).max() < 1e-5
    assert np.abs(ours["sh"] - theirs["sh"]).max() < 1e-5
    assert np.abs(_cov(ours) - _cov(theirs)).max() < 1e-6

    # any Euler triple: the rotation it applied is read off its positions (Procrustes); the
    # SH must then agree coefficient by coefficient
    _st(node, str(d / "in.ply"), "-r", "30,-50,70", str(d / "st_e.ply"))
    theirs = ref.read_trainer_ply(d / "st_e.ply")
    u, _, vt = np.linalg.svd(theirs["pos"].astype(np.float64).T @ s["pos"].astype(np.float64))
    r = u @ vt
    assert np.linalg.det(r) > 0
    q = sp.transform.quat_from_matrix(r)
    assert main(["-q", "splat", "transform", str(d / "in.ply"), "-o", str(d / "ours_e.ply"),
                 "--rotate", "quat:" + ",".join(f"{v:.17g}" for v in q)]) == 0
    ours = ref.read_trainer_ply(d / "ours_e.ply")
    assert np.abs(ours["pos"] - theirs["pos"]).max() < 1e-5
    err = np.abs(ours["sh"] - theirs["sh"]).max(axis=(0, 2))
    assert err.max() < 1e-5, err
    assert np.abs(_cov(ours) - _cov(theirs)).max() < 1e-6


def test_our_spz_read_by_it_equals_the_ply(node, scene):
    d, s = scene
    assert main(["-q", "splat", "transform", str(d / "in.ply"), "-o", str(d / "ours.spz")]) == 0
    _st(node, str(d / "ours.spz"), str(d / "st_from_ours.ply"))
    theirs = ref.read_trainer_ply(d / "st_from_ours.ply")
    assert np.abs(theirs["pos"] - s["pos"]).max() < 2.5e-4  # 12 fraction bits
    assert np.abs(theirs["sh"][:, 1:] - s["sh"][:, 1:]).max() < 1 / 250  # 8-bit SH
    assert np.abs(theirs["sh"][:, 0] - s["sh"][:, 0]).max() < 0.014  # 8-bit colour
    assert np.abs(theirs["log_scales"] - s["log_scales"]).max() < 1 / 31
    ours = sp.read(d / "ours.spz")  # and it reads what we read
    assert np.abs(ours.positions - theirs["pos"]).max() < 1e-6
    assert np.abs(ours.sh - theirs["sh"]).max() < 1e-6
    assert np.abs(ref.covariance(ours.rotations, ours.log_scales) - _cov(theirs)).max() < 1e-6


def test_its_spz_v4_read_by_us_equals_what_it_reads(node, scene):
    pytest.importorskip("zstandard", reason="SPZ version 4 needs the zstandard package")
    d, _ = scene
    _st(node, str(d / "in.ply"), str(d / "st.spz"))
    assert (d / "st.spz").read_bytes()[:4] == b"NGSP"  # version 4
    _st(node, str(d / "st.spz"), str(d / "st_from_st.ply"))
    theirs = ref.read_trainer_ply(d / "st_from_st.ply")
    ours = sp.read(d / "st.spz")
    assert np.abs(ours.positions - theirs["pos"]).max() < 1e-6
    assert np.abs(ours.sh - theirs["sh"]).max() < 1e-6
    assert np.abs(ours.opacity - theirs["opacity"]).max() < 1e-4
    assert np.abs(ref.covariance(ours.rotations, ours.log_scales) - _cov(theirs)).max() < 1e-6


def _validate(node: str, *paths: Path) -> dict:
    res = subprocess.run([node, str(CONSUMERS / "validate_glb.mjs"), *map(str, paths)],
                         capture_output=True, text=True, timeout=300, cwd=CONSUMERS)
    assert res.returncode == 0, res.stderr[-2000:]
    return json.loads(res.stdout)


def _core_view(src: Path, dst: Path) -> None:
    """The same .glb with the extension's attributes renamed to application-specific
    ``_KHR_…`` names (what a validator without the extension can check)."""
    doc, binary = gltf.parse(src.read_bytes())
    prim = doc["meshes"][0]["primitives"][0]
    prim["attributes"] = {(k if ":" not in k else "_" + k.replace(":", "_")): v
                          for k, v in prim["attributes"].items()}
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    dst.write_bytes(struct.pack("<III", 0x46546C67, 2, total) + struct.pack("<II", len(js),
                    0x4E4F534A) + js + struct.pack("<II", len(binary), 0x004E4942) + binary)


def test_our_glb_holds_what_its_glb_holds_and_validates(node, scene):
    d, _ = scene
    assert main(["-q", "splat", "transform", str(d / "in.ply"), "-o", str(d / "ours.glb")]) == 0
    _st(node, str(d / "in.ply"), str(d / "st.glb"))
    d1, b1 = gltf.parse((d / "ours.glb").read_bytes())
    d2, b2 = gltf.parse((d / "st.glb").read_bytes())
    p1, p2 = d1["meshes"][0]["primitives"][0], d2["meshes"][0]["primitives"][0]
    assert sorted(p1["attributes"]) == sorted(p2["attributes"])
    assert len(p2["attributes"]) == 2 + 3 + 16
    assert p1["extensions"] == p2["extensions"] and p1["mode"] == p2["mode"] == 0
    for name, i2 in p2["attributes"].items():
        i1 = p1["attributes"][name]
        a1, a2 = d1["accessors"][i1], d2["accessors"][i2]
        for key in ("componentType", "type", "count", "normalized", "min", "max"):
            assert a1.get(key) == pytest.approx(a2.get(key)), (name, key)
        v1, v2 = gltf._accessor(d1, b1, i1, None), gltf._accessor(d2, b2, i2, None)
        if name.endswith(":ROTATION"):  # the extension requires unit quaternions; it copies
            v2 = v2 / np.linalg.norm(v2, axis=1, keepdims=True)  # the PLY's unnormalised ones
            assert np.allclose(np.linalg.norm(v1, axis=1), 1.0, atol=1e-6)
        assert np.abs(v1 - v2).max() <= 1e-6, name

    reports = _validate(node, d / "ours.glb", d / "st.glb")
    for name, rep in reports.items():
        errors = [m for m in rep["messages"] if m["severity"] == 0]
        unknown = [m for m in errors
                   if not (m["code"] == "MESH_PRIMITIVE_INVALID_ATTRIBUTE"
                           and "/attributes/KHR_gaussian_splatting:" in m["pointer"])]
        assert unknown == [], (name, unknown)
    assert reports["ours.glb"]["numErrors"] == reports["st.glb"]["numErrors"]
    _core_view(d / "ours.glb", d / "core.glb")
    core = _validate(node, d / "core.glb")["core.glb"]
    assert core["numErrors"] == 0, core["messages"]
    assert core["numWarnings"] == 0, core["messages"]
