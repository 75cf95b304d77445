"""Every command over a corpus of bad files: exit ≠ 0, exactly one line on stderr that names
the file, no traceback, and nothing left at the target or beside it."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from shprobe.cli.main import main
from tests.conftest import data_file


def _pfm(path: Path, data: np.ndarray, scale: bytes = b"-1.0") -> Path:
    h, w = data.shape[:2]
    path.write_bytes(b"PF\n%d %d\n" % (w, h) + scale + b"\n"
                     + np.ascontiguousarray(data[::-1], "<f4").tobytes())
    return path


def _corpus(d: Path) -> dict[str, dict[str, Path]]:
    """Bad files by what they pretend to be."""
    probes = {}
    probes["empty.hdr"] = d / "empty.hdr"
    probes["empty.hdr"].write_bytes(b"")
    probes["text.exr"] = d / "text.exr"
    probes["text.exr"].write_text("not an image\n")
    # a 71-byte Radiance header declaring 100000 x 100000 pixels
    probes["huge.hdr"] = d / "huge.hdr"
    probes["huge.hdr"].write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n"
                                   + b"\x02\x02\x00\x00" * 4)
    good = data_file("probes", "grace.hdr").read_bytes()
    probes["cut.hdr"] = d / "cut.hdr"
    probes["cut.hdr"].write_bytes(good[: len(good) // 3])
    a = np.ones((16, 32, 3), np.float32)
    a[3, 4, 1] = np.nan
    probes["nan.pfm"] = _pfm(d / "nan.pfm", a)
    probes["scale.pfm"] = _pfm(d / "scale.pfm", np.ones((16, 32, 3), np.float32), b"-1.0.0x")
    probes["big.pfm"] = _pfm(d / "big.pfm", np.full((16, 32, 3), 3e38, np.float32))
    meshes = {}
    meshes["notmesh.obj"] = d / "notmesh.obj"
    meshes["notmesh.obj"].write_text("hello world\n")
    meshes["point.obj"] = d / "point.obj"
    meshes["point.obj"].write_text("v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n")
    meshes["nan.obj"] = d / "nan.obj"
    meshes["nan.obj"].write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    meshes["huge.obj"] = d / "huge.obj"
    meshes["huge.obj"].write_text("v 0 0 0\nv 1e308 0 0\nv 0 1e308 0\nf 1 2 3\n")
    coeffs = {}
    for name, text in (("nan.json", '{"coefficients": [[NaN, 0, 0]]}'),
                       ("deep.json", "[" * 50_000 + "]" * 50_000),
                       ("str.json", '{"coefficients": [["a", 1, 2]]}'),
                       ("five.json", '{"coefficients": [[1, 2, 3, 4, 5]]}'),
                       ("gltf.json", '{"extensions": {"EXT_lights_image_based": 3}}')):
        coeffs[name] = d / name
        coeffs[name].write_text(text)
    npz = {}
    npz["empty.npz"] = d / "empty.npz"
    npz["empty.npz"].write_bytes(b"")
    npz["cut.npz"] = d / "cut.npz"
    np.savez(npz["cut.npz"], vertices=np.zeros((100, 3)))
    npz["cut.npz"].write_bytes(npz["cut.npz"].read_bytes()[:200])
    npz["other.npz"] = d / "other.npz"
    np.savez(npz["other.npz"], a=np.zeros(3))
    return {"probe": probes, "mesh": meshes, "coeffs": coeffs, "npz": npz}


# (command line with {probe} / {mesh} / {coeffs} / {npz} / {out} / {good_mesh}, kind of bad
# file, output suffix)
COMMANDS = [
    ("prefilter {probe} --format json -o {out}", "probe", ".json"),
    ("irradiance {probe} -o {out}", "probe", ".exr"),
    ("error {probe}", "probe", None),
    ("render {probe} --sphere --size 16 -o {out}", "probe", ".png"),
    ("window {probe}", "probe", None),
    ("export {probe} --format glsl -o {out}", "probe", ".glsl"),
    ("edit {probe} --scale-band 1=0.5 -o {out}", "probe", ".json"),
    ("hbasis bake {good_mesh} {probe} -o {out}", "probe", ".npz"),
    ("prt render {npz_good} {probe} --size 16 -o {out}", "probe", ".png"),
    ("render --preset grace --mesh {mesh} --size 16 -o {out}", "mesh", ".png"),
    ("basis-images {mesh} --size 16 -o {out}", "mesh", "dir"),
    ("prt bake {mesh} --mode unshadowed --lmax 2 -o {out}", "mesh", ".npz"),
    ("hbasis bake {mesh} {good_probe} -o {out}", "mesh", ".npz"),
    ("prefilter --coeffs {coeffs} --format json -o {out}", "coeffs", ".json"),
    ("render --coeffs {coeffs} --sphere --size 16 -o {out}", "coeffs", ".png"),
    ("window --coeffs {coeffs}", "coeffs", None),
    ("edit --coeffs {coeffs} -o {out}", "coeffs", ".json"),
    ("prt render {npz} --preset grace --size 16 -o {out}", "npz", ".png"),
    ("hbasis render {good_mesh} {npz} --size 16 -o {out}", "npz", ".png"),
]


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad")
    c = _corpus(d)
    good_mesh = d / "tri.obj"
    good_mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\n"
                         "f 2 4 3\n")
    npz_good = d / "good.npz"
    assert main(["prt", "bake", str(good_mesh), "--mode", "unshadowed", "--lmax", "2", "-o",
                 str(npz_good)]) == 0
    return c, good_mesh, npz_good


def _cases():
    for cmd, kind, suffix in COMMANDS:
        for name in {"probe": ["empty.hdr", "text.exr", "huge.hdr", "cut.hdr", "nan.pfm",
                               "scale.pfm", "big.pfm"],
                     "mesh": ["notmesh.obj", "point.obj", "nan.obj", "huge.obj"],
                     "coeffs": ["nan.json", "deep.json", "str.json", "five.json", "gltf.json"],
                     "npz": ["empty.npz", "cut.npz", "other.npz"]}[kind]:
            yield pytest.param(cmd, kind, suffix, name, id=f"{cmd.split(' {')[0]}-{name}")


@pytest.mark.slow
@pytest.mark.parametrize(("cmd", "kind", "suffix", "name"), list(_cases()))
def test_bad_file_is_one_line_and_leaves_nothing(corpus, tmp_path, capfd, cmd, kind, suffix,
                                                 name):
    files, good_mesh, npz_good = corpus
    bad = files[kind][name]
    out = tmp_path / ("out" if suffix == "dir" else f"out{suffix or ''}")
    argv = cmd.format(**{kind: bad}, out=out, good_mesh=good_mesh, npz_good=npz_good,
                      good_probe=data_file("probes", "grace.hdr")).split()
    capfd.readouterr()
    with warnings.catch_warnings(record=True) as caught:  # a warning is stderr output too
        warnings.simplefilter("always")
        rc = main(argv)
    err = capfd.readouterr().err.strip().splitlines()
    assert rc != 0, f"{cmd} accepted {name}"
    assert not caught, [str(w.message) for w in caught]
    assert len(err) == 1, err
    assert "Traceback" not in err[0] and "internal error" not in err[0], err[0]
    assert bad.name in err[0], err[0]
    assert list(tmp_path.iterdir()) == [], list(tmp_path.iterdir())


def test_corpus_header_is_what_it_claims():
    hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n" + b"\x02\x02\x00\x00" * 4
    assert len(hdr) == 71  # the 71-byte file
