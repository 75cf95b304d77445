"""Splat transforms keep every colour the 3DGS renderer computes.

The renderer is ``tests/splats/splat_reference.py``: its published SH constants (CS phase), its view
direction (camera → splat) and its +0.5 bias, written without shprobe. For random splats and
random cameras the colour after a transform (camera moved with the scene) must equal the
colour before, to float32 rounding; the covariance must be A Σ Aᵀ (the renderer's computeCov3D
on the written quaternion and scales).
"""

from __future__ import annotations

import numpy as np
import pytest

from shprobe import splats as sp
from shprobe.cli.main import main
from shprobe.progress import Recorder
from shprobe.sh.conventions import cs_signs
from shprobe.sh.rotation import from_axis_angle, from_euler_zyz, wigner_d
from shprobe.splats import transform as tf
from tests.splats import splat_reference as ref

TOL = 2e-6  # float32 rounding of colours of order 1


def _cloud(n=400, degree=3, seed=0, scales=3) -> sp.Splats:
    s = ref.random_splats(n, degree, seed, scales)
    return sp.Splats(s["pos"], s["log_scales"], s["rot"], s["opacity"], s["sh"])


def _errors(s: sp.Splats, sim: sp.Similarity, seed: int = 1) -> tuple[float, float]:
    """(largest colour change, largest relative covariance error) of ``sim`` on ``s``."""
    rng = np.random.default_rng(seed)
    cams = rng.normal(size=(s.count, 3)) * 6
    out = sp.apply(s, sim)
    a = sim.scale * sim.linear
    c0 = ref.colour(s.sh, s.positions, cams)
    c1 = ref.colour(out.sh, out.positions, cams @ a.T + sim.translation)
    cov0 = ref.covariance(s.rotations, s.log_scales)
    cov1 = ref.covariance(out.rotations, out.log_scales)
    cov_err = np.abs(a @ cov0 @ a.T - cov1).max() / np.abs(cov1).max()
    return float(np.abs(c0 - c1).max()), float(cov_err)


SIMILARITIES = {
    "rotate-axis": lambda: sp.rotation(from_axis_angle([1, 2, 3], 37)),
    "rotate-euler": lambda: sp.rotation(from_euler_zyz(0.3, 2.0, -1.1)),
    "rotate-quat": lambda: sp.rotation([0.2, -0.5, 0.7, 0.1]),
    "translate": lambda: sp.translation([3, -1, 0.5]),
    "scale": lambda: sp.uniform_scale(2.5),
    "mirror-x": lambda: sp.mirror("x"),
    "mirror-y": lambda: sp.mirror("y"),
    "mirror-z": lambda: sp.mirror("z"),
    "mirror-rotated": lambda: sp.mirror("y").then(sp.rotation(from_axis_angle([1, 1, 0], 70))),
    "all": lambda: sp.frame("colmap", "gltf").then(sp.mirror("x")).then(
        sp.rotation(from_axis_angle([0, 1, 1], -20))).then(sp.uniform_scale(0.3)).then(
        sp.translation([1, 2, 3])),
    "matrix": lambda: sp.Similarity.from_matrix(
        np.r_[np.c_[1.7 * from_axis_angle([2, -1, 1], 133) @ np.diag([1, 1, -1]),
                    [4, 5, 6]], [[0, 0, 0, 1]]]),
    "frame-unity": lambda: sp.frame("opencv", "unity"),
}


@pytest.mark.parametrize("name", sorted(SIMILARITIES))
@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_renderer_colour_and_covariance_unchanged(name, degree):
    colour, cov = _errors(_cloud(degree=degree), SIMILARITIES[name]())
    assert colour < TOL, colour
    assert cov < 1e-5, cov


def test_2dgs_surfels_keep_two_scales_and_their_covariance():
    s = _cloud(scales=2)
    for sim in (SIMILARITIES["mirror-rotated"](), SIMILARITIES["all"]()):
        out = sp.apply(s, sim)
        assert out.log_scales.shape == (s.count, 2)
        colour, cov = _errors(s, sim)
        assert colour < TOL and cov < 1e-5


def test_a_sign_flip_in_one_band_is_caught(monkeypatch):
    """The check above fails when one band's sign is wrong: the test can fail."""
    s, sim = _cloud(), SIMILARITIES["rotate-axis"]()
    good = tf._sh_matrix_cached.__wrapped__

    def flipped(key, degree):
        m = good(key, degree).copy()
        m[9:16, 9:16] *= -1  # band 3
        return m

    monkeypatch.setattr(tf, "_sh_matrix_cached", flipped)
    colour, _ = _errors(s, sim)
    assert colour > 1e-2


def test_sh_matrix_is_the_wigner_rotation_and_parity_for_a_mirror():
    s = cs_signs(3)
    r = from_axis_angle([0.3, -1, 2], 81)
    want = s[:, None] * wigner_d(r, 3) * s[None, :]
    assert np.abs(tf.sh_matrix(r, 3) - want).max() < 1e-12
    q = r @ np.diag([1.0, 1.0, -1.0])  # a reflection: −q is a rotation
    parity = np.repeat((-1.0) ** np.arange(4), 2 * np.arange(4) + 1)
    want = s[:, None] * (wigner_d(-q, 3) * parity[None, :]) * s[None, :]
    assert np.abs(tf.sh_matrix(q, 3) - want).max() < 1e-12


def test_quaternions_stay_unit_right_handed_after_a_mirror():
    s = _cloud()
    s.rotations[:] /= np.linalg.norm(s.rotations, axis=1, keepdims=True)
    out = sp.apply(s, SIMILARITIES["mirror-rotated"]())
    assert np.allclose(np.linalg.norm(out.rotations, axis=1), 1.0, atol=1e-6)
    assert np.allclose(np.linalg.det(ref.quat_matrix(out.rotations)), 1.0, atol=1e-5)
    assert np.array_equal(out.log_scales, s.log_scales)  # the reflection is in the axes


def test_view_colour_and_converters_match_the_renderer():
    s = _cloud(50)
    rng = np.random.default_rng(3)
    cams = rng.normal(size=(50, 3)) * 5
    d = s.positions - cams
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    assert np.abs(sp.view_colour(s.sh, d) - ref.colour(s.sh, s.positions, cams)).max() < 1e-9
    assert np.array_equal(sp.from_shprobe(sp.to_shprobe(s.sh)), s.sh)
    assert np.allclose(sp.colour_to_dc(sp.dc_to_colour(s.sh[:, 0])), s.sh[:, 0], atol=1e-6)


def test_similarity_refusals():
    shear = np.eye(4)
    shear[0, 1] = 0.3
    with pytest.raises(ValueError, match="shear"):
        sp.Similarity.from_matrix(shear)
    with pytest.raises(ValueError, match="non-uniform scale"):
        sp.Similarity.from_matrix(np.diag([1.0, 2.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="projective"):
        sp.Similarity.from_matrix(np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0],
                                            [0, 0, 0.1, 1]]))
    with pytest.raises(ValueError, match="frame"):
        sp.frame("colmap", "nowhere")


@pytest.fixture
def trainer_ply(tmp_path):
    s = ref.random_splats(3000, 3, seed=5)
    path = tmp_path / "in.ply"
    ref.write_trainer_ply(path, s)
    return path, s


def test_cli_transform_of_a_trainer_ply_keeps_every_colour(trainer_ply, tmp_path, monkeypatch):
    """Through the files: channel-major f_rest, w-first quaternions, several chunks."""
    monkeypatch.setattr(sp.ply, "CHUNK", 700)
    path, s = trainer_ply
    out = tmp_path / "out.ply"
    rc = main(["splat", "transform", str(path), "-o", str(out), "--frame", "colmap:gltf",
               "--mirror", "z", "--rotate", "1,1,0:40", "--scale", "1.5",
               "--translate", "1,-2,3"])
    assert rc == 0
    got = ref.read_trainer_ply(out)
    sim = (sp.frame("colmap", "gltf").then(sp.mirror("z"))
           .then(sp.rotation(from_axis_angle([1, 1, 0], 40))).then(sp.uniform_scale(1.5))
           .then(sp.translation([1, -2, 3])))
    a = sim.scale * sim.linear
    cams = np.random.default_rng(2).normal(size=(3000, 3)) * 5
    c0 = ref.colour(s["sh"], s["pos"], cams)
    c1 = ref.colour(got["sh"], got["pos"], cams @ a.T + sim.translation)
    assert np.abs(c0 - c1).max() < TOL
    assert np.allclose(got["pos"], s["pos"] @ a.T + sim.translation, atol=1e-5)
    assert got["names"] == ref.read_trainer_ply(path)["names"]  # the layout is kept


def test_sh_degree_truncates_and_big_endian_reads(tmp_path):
    s = ref.random_splats(100, 3, seed=2)
    path = tmp_path / "be.ply"
    ref.write_trainer_ply(path, s, fmt="binary_big_endian")
    out = tmp_path / "d1.ply"
    assert main(["splat", "transform", str(path), "-o", str(out), "--sh-degree", "1"]) == 0
    got = ref.read_trainer_ply(out)
    assert sum(n.startswith("f_rest_") for n in got["names"]) == 9
    assert np.array_equal(got["sh"], s["sh"][:, :4])
    assert np.array_equal(got["pos"], s["pos"])


def test_formats_round_trip(tmp_path):
    s = ref.random_splats(500, 3, seed=4)
    s["sh"][:, 1:] = np.clip(s["sh"][:, 1:], -0.99, 0.99)  # SPZ's SH range is [-1, 1]
    path = tmp_path / "in.ply"
    ref.write_trainer_ply(path, s)
    for suffix in (".glb", ".spz"):
        out = tmp_path / f"out{suffix}"
        sp.transform_file(path, out, sp.TransformSettings())
        back = sp.read(out)
        exact = suffix == ".glb"
        assert np.abs(back.positions - s["pos"]).max() < (1e-6 if exact else 2.5e-4)
        assert np.abs(back.sh[:, 1:] - s["sh"][:, 1:]).max() < (1e-6 if exact else 1 / 250)
        assert np.abs(back.sh[:, 0] - s["sh"][:, 0]).max() < (1e-6 if exact else 0.014)
        cov0 = ref.covariance(s["rot"], s["log_scales"])
        cov1 = ref.covariance(back.rotations, back.log_scales)
        rel = np.abs(cov0 - cov1).max(axis=(1, 2)) / np.abs(cov0).max(axis=(1, 2))
        assert rel.max() < (1e-5 if exact else 0.2)


def test_info_and_progress(trainer_ply):
    path, s = trainer_ply
    rec = Recorder()
    res = sp.info(path, progress=rec)
    assert res.count == 3000 and res.degree == 3 and res.kind == "3DGS"
    assert np.allclose(res.bounds_min, s["pos"].min(axis=0))
    want = [np.mean(np.sum(s["sh"][:, l * l:(l + 1) ** 2].astype(np.float64) ** 2,
                           axis=(1, 2))) for l in range(4)]
    assert np.allclose(res.band_energy, want, rtol=1e-6)
    assert rec.events[0] == ("begin", "reading splats", 3000)
    assert rec.events[-2] == ("update", 3000.0, None)


def test_a_ply_with_other_property_types_keeps_them(tmp_path):
    """The general (non all-float) path: an extra uchar property is carried through and
    truncation renumbers the channel-major f_rest."""
    s = ref.random_splats(300, 2, seed=9)
    path = tmp_path / "extra.ply"
    ref.write_trainer_ply(path, s)
    data = path.read_bytes()
    end = data.index(b"end_header\n")
    head = data[:end].decode().replace("property float rot_3\n", "property float rot_3\n"
                                       "property uchar label\n")
    rec = np.frombuffer(data[end + 11:], dtype=np.dtype([("r", "V", 4 * (9 + 24 + 8))]))
    label = np.arange(300, dtype=np.uint8)
    body = b"".join(r.tobytes() + bytes([lab]) for r, lab in zip(rec["r"], label, strict=True))
    path.write_bytes(head.encode() + b"end_header\n" + body)
    out = tmp_path / "out.ply"
    sim = sp.rotation(from_axis_angle([1, 0, 1], 50))
    res = sp.transform_file(path, out, sp.TransformSettings(sim, sh_degree=1))
    assert (res.count, res.degree_in, res.degree_out) == (300, 2, 1)
    back = sp.ply.read_layout(out)
    assert back.dtype["label"] == np.uint8
    got = next(sp.ply.records(back))
    assert np.array_equal(got["label"], label)
    moved = sp.apply(_cloud_from(s), sim).truncated(1)
    assert np.allclose(sp.ply.to_splats(got, back).sh, moved.sh, atol=1e-6)


def _cloud_from(s: dict) -> sp.Splats:
    return sp.Splats(s["pos"], s["log_scales"], s["rot"], s["opacity"], s["sh"])


def test_cli_reports_progress_and_what_it_wrote(trainer_ply, tmp_path, capfd, monkeypatch):
    monkeypatch.setattr(sp.ply, "CHUNK", 1000)
    path, _ = trainer_ply
    out = tmp_path / "o.glb"
    assert main(["splat", "transform", str(path), "-o", str(out), "--mirror", "x"]) == 0
    err = capfd.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"wrote {out} (3000 splats, SH degree 3, ")
    rec = Recorder()
    sp.transform_file(path, tmp_path / "o.ply", sp.TransformSettings(), progress=rec)
    assert rec.events[0] == ("begin", "transforming splats", 3000)
    assert [d for k, d, _ in rec.events if k == "update"] == [1000.0, 2000.0, 3000.0]
    assert main(["-q", "splat", "info", str(out), "--format", "json"]) == 0
    doc = __import__("json").loads(capfd.readouterr().out)
    assert doc["count"] == 3000 and doc["sh_degree"] == 3 and len(doc["band_energy"]) == 4


def test_glb_reader_takes_quantised_rotation_and_opacity(tmp_path):
    """KHR_gaussian_splatting allows normalised signed-short rotations and unsigned-byte
    opacities: a file rewritten so reads back to the quantisation step."""
    import json
    import struct

    s = _cloud(200, degree=1)
    s.rotations[:] /= np.linalg.norm(s.rotations, axis=1, keepdims=True)
    raw = sp.gltf.encode(s)
    doc, binary = sp.gltf.parse(raw)
    att = doc["meshes"][0]["primitives"][0]["attributes"]
    extra = bytearray(binary)
    for name, ctype, dt, scale in ((f"{sp.gltf.EXT}:ROTATION", 5122, "<i2", 32767),
                                   (f"{sp.gltf.EXT}:OPACITY", 5121, "u1", 255)):
        acc = doc["accessors"][att[name]]
        vals = sp.gltf._accessor(doc, binary, att[name], None)
        q = np.round(vals * scale).astype(dt).tobytes()
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(extra), "byteLength": len(q)})
        extra += q + b"\0" * (-len(q) % 4)
        acc.update(bufferView=len(doc["bufferViews"]) - 1, componentType=ctype, normalized=True)
    doc["buffers"][0]["byteLength"] = len(extra)
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    total = 12 + 8 + len(js) + 8 + len(extra)
    path = tmp_path / "q.glb"
    path.write_bytes(struct.pack("<III", 0x46546C67, 2, total) + struct.pack("<II", len(js),
                     0x4E4F534A) + js + struct.pack("<II", len(extra), 0x004E4942)
                     + bytes(extra))
    back = sp.read(path)
    cov0 = ref.covariance(s.rotations, s.log_scales)
    cov1 = ref.covariance(back.rotations, back.log_scales)
    assert np.abs(cov0 - cov1).max() / np.abs(cov0).max() < 1e-3
    a0 = 1 / (1 + np.exp(-s.opacity))
    a1 = 1 / (1 + np.exp(-back.opacity))
    assert np.abs(a0 - a1).max() < 0.5 / 255 + 1e-6
