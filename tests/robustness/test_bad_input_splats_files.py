"""Hostile splat files and writes: each class is one line naming the file, a non-zero exit, no
traceback, nothing written; and no numpy RuntimeWarning anywhere (they are errors here)."""

from __future__ import annotations

import gzip
import json
import os
import struct
import subprocess
import sys

import numpy as np
import pytest

import shprobe.splats as sp
from shprobe.cli.main import main
from tests.splats import splat_reference as ref

pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")


def _splats(n=20, degree=1, seed=3) -> sp.Splats:
    r = ref.random_splats(n, degree, seed=seed)
    return sp.Splats(r["pos"], r["log_scales"], r["rot"], r["opacity"], r["sh"])


def _one_line(argv, capfd, named) -> str:
    rc = main(argv)
    err = [ln for ln in capfd.readouterr().err.splitlines() if ln.strip()]
    print(rc, err)
    assert rc not in (0, 70), (rc, err)
    assert len(err) == 1 and err[0].startswith("shprobe: error:"), err
    assert "Traceback" not in err[0] and str(named) in err[0], err
    return err[0]


# ----------------------------------------------------------------------------- non-regular files

def _cli(*argv, timeout=60):
    env = {**os.environ, "PYTHONWARNINGS": "error::RuntimeWarning"}
    return subprocess.run([sys.executable, "-m", "shprobe", *argv], capture_output=True,
                          text=True, timeout=timeout, env=env)


@pytest.mark.parametrize("suffix", [".ply", ".spz", ".glb"])
@pytest.mark.parametrize("kind", ["fifo", "/dev/zero", "/dev/urandom"])
def test_non_regular_splat_files_are_refused_at_once(kind, suffix, tmp_path):
    src = tmp_path / f"in{suffix}"
    if kind == "fifo":
        os.mkfifo(src)  # nobody writes to it: opening it for reading would block forever
    else:
        os.symlink(kind, src)  # endless
    for argv in (["splat", "info", str(src)],
                 ["splat", "transform", str(src), "-o", str(tmp_path / "o.ply")]):
        r = _cli(*argv)
        err = r.stderr.strip().splitlines()
        print(err)
        assert r.returncode == 1 and len(err) == 1, r.stderr
        assert "is not a regular file" in err[0] and str(src) in err[0]
    assert not (tmp_path / "o.ply").exists()


# ----------------------------------------------------------------------------- glb JSON

def _glb(tmp_path, edit=None, text_edit=None, name="in.glb"):
    """A good .glb whose JSON is changed by ``edit(doc)`` (may return a new document) or
    ``text_edit(text)``."""
    raw = sp.gltf.encode(_splats())
    doc, binary = sp.gltf.parse(raw)
    if edit is not None:
        doc = edit(doc) or doc
    text = json.dumps(doc, separators=(",", ":"))
    if text_edit is not None:
        text = text_edit(text)
    js = text.encode() + b" " * (-len(text.encode()) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    p = tmp_path / name
    p.write_bytes(struct.pack("<III", 0x46546C67, 2, total) + struct.pack("<II", len(js),
                  0x4E4F534A) + js + struct.pack("<II", len(binary), 0x004E4942) + binary)
    return p


def _att(doc, name):
    return doc["meshes"][0]["primitives"][0]["attributes"][name]


def _acc(doc, name):
    return doc["accessors"][_att(doc, name)]


E = sp.gltf.EXT


def _set(path_fn, key, value):
    def edit(doc):
        path_fn(doc)[key] = value
    return edit


GLB_CASES = {
    "document-list": (lambda d: [d], None, "JSON is a list, not an object"),
    "document-string": (lambda d: "splats", None, "JSON is a string, not an object"),
    "count-string": (_set(lambda d: _acc(d, "POSITION"), "count", "abc"), None,
                     "'count' is a string"),
    "count-1e400": (None, lambda t: t.replace('"count":20', '"count":1e400', 1),
                    "'count' is a number (inf), not an integer"),
    "count-huge": (_set(lambda d: _acc(d, "POSITION"), "count", 10**30), None,
                   "count 1000000000000000000000000000000 is not between 1"),
    "count-float": (_set(lambda d: _acc(d, "POSITION"), "count", 20.5), None,
                    "not an integer"),
    "negative-byteOffset": (_set(lambda d: _acc(d, f"{E}:SCALE"), "byteOffset", -12), None,
                            "negative byteOffset"),
    "negative-byteStride": (_set(lambda d: d["bufferViews"][_acc(d, f"{E}:SCALE")[
        "bufferView"]], "byteStride", -12), None, "negative"),
    "rotation-vec3": (_set(lambda d: _acc(d, f"{E}:ROTATION"), "type", "VEC3"), None,
                      "is VEC3, expected VEC4"),
    "scale-scalar": (_set(lambda d: _acc(d, f"{E}:SCALE"), "type", "SCALAR"), None,
                     "is SCALAR, expected VEC3"),
    "sh-vec4": (_set(lambda d: _acc(d, f"{E}:SH_DEGREE_1_COEF_0"), "type", "VEC4"), None,
                "is VEC4, expected VEC3"),
    "nesting-5000": (_set(lambda d: d, "extras", 0), lambda t: t.replace(
        '"extras":0', '"extras":' + "[" * 5000 + "]" * 5000), "nested too deeply"),
    "meshes-object": (_set(lambda d: d, "meshes", {"primitives": []}), None,
                      "'meshes' is a object"),
    "primitives-string": (_set(lambda d: d["meshes"][0], "primitives", "x"), None,
                          "'primitives' is a string"),
    "attributes-list": (_set(lambda d: d["meshes"][0]["primitives"][0], "attributes", [0]),
                        None, "'attributes' is a list"),
    "extensions-list": (_set(lambda d: d["meshes"][0]["primitives"][0], "extensions", [E]),
                        None, "'extensions' is a list"),
    "accessor-index-minus-1": (_set(lambda d: d["meshes"][0]["primitives"][0]["attributes"],
                                    "POSITION", -1), None, "-1 is out of range"),
    "accessor-index-string": (_set(lambda d: d["meshes"][0]["primitives"][0]["attributes"],
                                   "POSITION", "0"), None, "is a string"),
    "accessor-past-view": (_set(lambda d: d["bufferViews"][_acc(d, "POSITION")["bufferView"]],
                                "byteLength", 12), None, "runs past its buffer view"),
    "view-past-buffer": (_set(lambda d: d["bufferViews"][_acc(d, "POSITION")["bufferView"]],
                              "byteOffset", 1 << 40), None, "runs past its buffer"),
    "accessor-not-object": (lambda d: d["accessors"].__setitem__(_att(d, "POSITION"), 7),
                            None, "is a number, not an object"),
    "component-unknown": (_set(lambda d: _acc(d, "POSITION"), "componentType", 5130), None,
                          "componentType 5130"),
}


@pytest.mark.parametrize("case", sorted(GLB_CASES))
def test_glb_json_is_checked_before_reading(case, tmp_path, capfd):
    edit, text_edit, phrase = GLB_CASES[case]
    src = _glb(tmp_path, edit, text_edit)
    for argv in (["splat", "info", str(src)],
                 ["splat", "transform", str(src), "-o", str(tmp_path / "o.ply")]):
        line = _one_line(argv, capfd, src)
        assert phrase in line, line
    assert not (tmp_path / "o.ply").exists()


def test_good_glb_still_reads(tmp_path):
    s = sp.read(_glb(tmp_path))
    assert s.count == 20 and s.degree == 1


# ----------------------------------------------------------------------------- SPZ headers

def _spz(tmp_path, count=None, fbits=None, name="in.spz"):
    raw = bytearray(sp.spz.pack(_splats()))
    if count is not None:
        struct.pack_into("<I", raw, 8, count)
    if fbits is not None:
        raw[13] = fbits
    p = tmp_path / name
    p.write_bytes(gzip.compress(bytes(raw)))
    return p


@pytest.mark.parametrize("count,fbits,phrase", [
    (19, None, "holds more data than its header's 19 splats"),
    (1, None, "holds more data than its header's 1 splats"),
    (21, None, "truncated"),
    (None, 255, "fractionalBits 255 is outside 1–23"),
    (None, 0, "fractionalBits 0 is outside 1–23"),
    (None, 24, "fractionalBits 24 is outside 1–23"),
])
def test_spz_header_is_checked_against_the_data(count, fbits, phrase, tmp_path, capfd):
    src = _spz(tmp_path, count, fbits)
    line = _one_line(["splat", "info", str(src)], capfd, src)
    assert phrase in line, line


def test_spz_written_here_reads_back(tmp_path):
    s = sp.read(_spz(tmp_path))
    assert s.count == 20


# ----------------------------------------------------------------------------- writers

@pytest.mark.parametrize("suffix", [".glb", ".spz", ".ply"])
def test_zero_quaternion_is_refused_by_every_writer(suffix, tmp_path, capfd):
    r = ref.random_splats(20, 1, seed=3)
    r["rot"][7] = 0.0
    src = tmp_path / "in.ply"
    ref.write_trainer_ply(src, r)
    out = tmp_path / f"o{suffix}"
    line = _one_line(["splat", "transform", str(src), "-o", str(out), "--rotate", "0,0,1:30"],
                     capfd, src if suffix == ".ply" else out)
    assert "splat 7 has a zero rotation quaternion" in line
    assert not out.exists()


def test_glb_scale_overflow_is_refused(tmp_path, capfd):
    r = ref.random_splats(20, 1, seed=3)
    r["log_scales"][5, 1] = 89.0  # exp(89) is beyond float32
    src = tmp_path / "in.ply"
    ref.write_trainer_ply(src, r)
    out = tmp_path / "o.glb"
    line = _one_line(["splat", "transform", str(src), "-o", str(out)], capfd, out)
    assert "splat 5 has a log-scale of 89" in line and "overflows" in line
    assert not out.exists()
    r["log_scales"][5, 1] = 88.0  # still finite: written, read back
    ref.write_trainer_ply(src, r)
    assert main(["-q", "splat", "transform", str(src), "-o", str(out)]) == 0
    back = sp.read(out)
    assert np.all(np.isfinite(back.log_scales)) and abs(back.log_scales.max() - 88.0) < 1e-3


@pytest.mark.parametrize("suffix", [".glb", ".spz"])
def test_extreme_opacity_writes_without_warnings(suffix, tmp_path):
    r = ref.random_splats(20, 1, seed=3)
    r["opacity"][:3] = [-1000.0, 1000.0, -3e38]
    src = tmp_path / "in.ply"
    ref.write_trainer_ply(src, r)
    out = tmp_path / f"o{suffix}"
    assert main(["-q", "splat", "transform", str(src), "-o", str(out)]) == 0
    back = sp.read(out)
    assert np.all(np.isfinite(back.opacity))
    assert back.opacity[0] < -5 and back.opacity[1] > 5  # clamped inside the format


def test_integer_normals_are_written_as_float(tmp_path):
    r = ref.random_splats(4, 0, seed=3)
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    dt = np.dtype([(n, "u1" if n in ("nx", "ny", "nz") else "<f4") for n in names])
    rec = np.zeros(4, dt)
    for i, c in enumerate("xyz"):
        rec[c] = r["pos"][:, i]
    rec["nz"] = 1
    for c in range(3):
        rec[f"f_dc_{c}"] = r["sh"][:, 0, c]
    rec["opacity"] = r["opacity"]
    for i in range(3):
        rec[f"scale_{i}"] = r["log_scales"][:, i]
    rec["rot_0"] = 1.0
    head = ["ply", "format binary_little_endian 1.0", "element vertex 4"]
    head += [f"property {'uchar' if dt[n] == np.uint8 else 'float'} {n}" for n in names]
    src = tmp_path / "in.ply"
    src.write_bytes(("\n".join([*head, "end_header"]) + "\n").encode() + rec.tobytes())
    out = tmp_path / "o.ply"
    assert main(["-q", "splat", "transform", str(src), "-o", str(out), "--mirror", "z"]) == 0
    back = ref.read_trainer_ply(out)
    assert "nz" in back["names"]
    data = out.read_bytes()
    assert b"property float nz" in data and b"uchar" not in data
    end = data.index(b"end_header\n") + 11
    nz = np.frombuffer(data, dtype=[(n, "<f4") for n in back["names"]], offset=end)["nz"]
    np.testing.assert_array_equal(nz, -1.0)  # mirrored, not wrapped to 255


@pytest.mark.parametrize("argv,phrase", [
    (["--matrix", ""], "matrix must be a finite 4×4 (or 3×4), got shape (0,)"),
    (["--matrix", "1e300,0,0,0,0,1e300,0,0,0,0,1e300,0,0,0,0,1"], "within ±1e+30"),
    (["--translate", "1e300,0,0"], "within ±1e+30"),
    (["--scale", "1e300"], "from 1e-30 to 1e+30"),
])
def test_matrix_options_are_refused_not_ignored(argv, phrase, tmp_path, capfd):
    src = tmp_path / "in.ply"
    ref.write_trainer_ply(src, ref.random_splats(20, 1, seed=3))
    out = tmp_path / "o.ply"
    rc = main(["splat", "transform", str(src), "-o", str(out), *argv])
    err = [ln for ln in capfd.readouterr().err.splitlines() if ln.strip()]
    print(rc, err)
    assert rc == 1 and len(err) == 1 and phrase in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("suffix", [".ply", ".glb", ".spz"])
def test_overflowing_transform_is_refused_without_warnings(suffix, tmp_path, capfd):
    r = ref.random_splats(20, 1, seed=3)
    r["pos"][2] = [1e10, 0, 0]
    src = tmp_path / "in.ply"
    ref.write_trainer_ply(src, r)
    out = tmp_path / f"o{suffix}"
    line = _one_line(["splat", "transform", str(src), "-o", str(out), "--scale", "1e30"],
                     capfd, src if suffix == ".ply" else out)
    assert "non-finite" in line
    assert not out.exists()


@pytest.mark.parametrize("suffix", [".ply", ".glb"])
def test_sh_overflowing_under_a_rotation_is_refused_without_warnings(suffix, tmp_path, capfd):
    r = ref.random_splats(20, 1, seed=3)
    r["sh"][4, 1:] = 3.3e38  # a rotation mixes three of them: beyond float32
    src = tmp_path / "in.ply"
    ref.write_trainer_ply(src, r)
    out = tmp_path / f"o{suffix}"
    line = _one_line(["splat", "transform", str(src), "-o", str(out), "--rotate", "1,1,1:50"],
                     capfd, src if suffix == ".ply" else out)
    assert "splat 4 has a non-finite value" in line
    assert not out.exists()
