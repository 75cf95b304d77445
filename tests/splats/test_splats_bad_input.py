"""Bad splat input: one line naming the file and the problem, a non-zero exit, nothing
written (no output, no temporary file)."""

from __future__ import annotations

import gzip
import struct

import numpy as np
import pytest

from shprobe.cli.main import main
from tests.splats import splat_reference as ref


def _good(path, n=50, degree=1, **kw):
    ref.write_trainer_ply(path, ref.random_splats(n, degree, seed=3, **kw))
    return path


def _replace_header(path, old: bytes, new: bytes):
    data = path.read_bytes()
    end = data.index(b"end_header\n")
    path.write_bytes(data[:end].replace(old, new) + data[end:])
    return path


def _truncated(p):
    data = _good(p).read_bytes()
    p.write_bytes(data[:-100])


def _wrong_type(p):
    s = ref.random_splats(50, 1, seed=3)
    ref.write_trainer_ply(p, s)
    # same record size: 'opacity' declared uchar, and the record shrinks by three bytes
    data = p.read_bytes()
    end = data.index(b"end_header\n")
    head = data[:end].replace(b"property float opacity", b"property uchar opacity")
    p.write_bytes(head + data[end:])


def _nan(p):
    s = ref.random_splats(50, 1, seed=3)
    s["sh"][17, 2, 1] = np.nan
    ref.write_trainer_ply(p, s)


def _inf(p):
    s = ref.random_splats(50, 1, seed=3)
    s["log_scales"][3, 0] = -np.inf
    ref.write_trainer_ply(p, s)


def _degree4(p):
    s = ref.random_splats(20, 3, seed=3)
    s["sh"] = np.zeros((20, 25, 3), np.float32)
    ref.write_trainer_ply(p, s)


def _zero(p):
    s = ref.random_splats(1, 1, seed=3)
    ref.write_trainer_ply(p, {k: v[:0] for k, v in s.items()})


def _mesh(p):
    p.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                  b"property float y\nproperty float z\nelement face 1\n"
                  b"property list uchar int vertex_indices\nend_header\n"
                  + np.zeros(9, "<f4").tobytes() + b"\x03" + np.arange(3, dtype="<i4").tobytes())


def _ascii(p):
    p.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n")


def _huge_count(p):
    _replace_header(_good(p), b"element vertex 50", b"element vertex 4000000000")


def _not_ply(p):
    p.write_bytes(b"hello")


def _spz_huge(p):
    head = struct.pack("<IIIBBBB", 0x5053474E, 3, 2_000_000_000, 1, 12, 0, 0)
    p.write_bytes(gzip.compress(head + b"\0" * 64))


def _spz_truncated(p):
    head = struct.pack("<IIIBBBB", 0x5053474E, 3, 100, 1, 12, 0, 0)
    p.write_bytes(gzip.compress(head + b"\0" * 64))


def _spz_degree4(p):
    head = struct.pack("<IIIBBBB", 0x5053474E, 3, 10, 4, 12, 0, 0)
    p.write_bytes(gzip.compress(head))


CASES = {
    "truncated": (".ply", _truncated, "truncated"),
    "wrong-type": (".ply", _wrong_type, "'opacity' is uchar, expected float"),
    "nan": (".ply", _nan, "splat 17 has a non-finite value"),
    "inf": (".ply", _inf, "splat 3 has a non-finite value"),
    "degree-4": (".ply", _degree4, "degree 4"),
    "zero-splats": (".ply", _zero, "no splats"),
    "mesh": (".ply", _mesh, "a mesh (vertices and faces), not Gaussian splats"),
    "ascii": (".ply", _ascii, "format 'ascii' is not supported"),
    "huge-count": (".ply", _huge_count, "declares 4000000000 splats"),
    "not-ply": (".ply", _not_ply, "not a PLY"),
    "spz-huge": (".spz", _spz_huge, "over the limit"),
    "spz-truncated": (".spz", _spz_truncated, "truncated"),
    "spz-degree-4": (".spz", _spz_degree4, "degree 4"),
}


@pytest.mark.parametrize("out_suffix", [".ply", ".glb"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_splat_file_is_one_line_and_leaves_nothing(case, out_suffix, tmp_path, capfd,
                                                       monkeypatch):
    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "2G")
    suffix, make, phrase = CASES[case]
    src = tmp_path / f"in{suffix}"
    make(src)
    out = tmp_path / "out" / f"result{out_suffix}"
    rc = main(["splat", "transform", str(src), "-o", str(out), "--rotate", "0,0,1:30"])
    err = capfd.readouterr().err.strip().splitlines()
    assert rc != 0
    assert len(err) == 1 or (len(err) > 1 and not err[-1].startswith("Traceback")), err
    line = [ln for ln in err if ln.startswith("shprobe: error:")]
    assert len(line) == 1, err
    assert str(src) in line[0] and phrase in line[0], line[0]
    assert not out.exists()
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


@pytest.mark.parametrize("argv,phrase", [
    (["--matrix", "1,0.2,0,0,0,1,0,0,0,0,1,0,0,0,0,1"], "not a similarity (shear"),
    (["--matrix", "1,0,0,0,0,3,0,0,0,0,1,0,0,0,0,1"], "non-uniform scale"),
    (["--scale", "-2"], "positive"),
    (["--frame", "colmap:up"], "unknown frame"),
    (["--sh-degree", "3"], "above the file's SH degree 1"),
])
def test_bad_options_are_one_line_and_leave_nothing(argv, phrase, tmp_path, capfd):
    src = _good(tmp_path / "in.ply")
    out = tmp_path / "out.ply"
    rc = main(["splat", "transform", str(src), "-o", str(out), *argv])
    err = capfd.readouterr().err.strip().splitlines()
    assert rc != 0 and len(err) == 1 and err[0].startswith("shprobe: error:"), err
    assert phrase in err[0], err[0]
    assert not out.exists()


def test_existing_output_is_kept_without_force(tmp_path, capfd):
    src = _good(tmp_path / "in.ply")
    out = tmp_path / "out.ply"
    out.write_bytes(b"keep")
    assert main(["splat", "transform", str(src), "-o", str(out)]) != 0
    assert "already exists" in capfd.readouterr().err
    assert out.read_bytes() == b"keep"
    assert main(["-q", "splat", "transform", str(src), "-o", str(out), "--force"]) == 0
    assert out.read_bytes()[:3] == b"ply"


def test_info_refuses_the_same_way(tmp_path, capfd):
    src = tmp_path / "in.ply"
    _mesh(src)
    assert main(["splat", "info", str(src)]) == 1
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not Gaussian splats" in err[0]
