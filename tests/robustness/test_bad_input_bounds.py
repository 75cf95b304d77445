"""Class 1 of the bad-input issue: work and memory are estimated from the arguments and file
headers before anything large is allocated, and refused in one line naming the estimate and the
limit (SHPROBE_MAX_MEMORY lowers the limit, as `--max-memory` does)."""

from __future__ import annotations

import io
import tracemalloc
import zipfile

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.files import load_npz
from shprobe.limits import check_memory, format_bytes, memory_limit, parse_bytes
from tests.conftest import data_file


def test_parse_and_format_bytes():
    assert parse_bytes("512M") == 512 << 20 and parse_bytes("2g") == 2 << 30
    assert parse_bytes("1.5GiB") == int(1.5 * (1 << 30)) and parse_bytes("1000") == 1000
    with pytest.raises(ShprobeError, match="cannot parse"):
        parse_bytes("lots")
    assert format_bytes(2.5e9) == "2.5 GB" and format_bytes(12) == "12 B"


def test_env_limit_lowers_the_limit(monkeypatch):
    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "10M")
    assert memory_limit() == 10 << 20
    check_memory(9 << 20, "fine")
    with pytest.raises(ShprobeError, match=r"about 11\.5 MB, over the limit of 10\.5 MB"):
        check_memory(11 << 20, "a big thing")


def _refused_quickly(fn, match):
    """fn raises ShprobeError(match) having allocated < 200 MB (traced); the time it takes is
    measured in bench/bench_refusals.py, not asserted here."""
    tracemalloc.start()
    try:
        with pytest.raises(ShprobeError, match=match):
            fn()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 200 << 20, peak


def test_sh_basis_of_a_huge_request_is_refused_before_allocating():
    from shprobe.sh import sh_basis

    dirs = np.tile([0.0, 0.0, 1.0], (3000, 1))
    _refused_quickly(lambda: sh_basis(dirs, 1024), r"SH values of 3000 directions to lmax "
                                                   r"1024 would need about 25\.2 GB")


def test_projection_is_refused_up_front(monkeypatch):
    from shprobe.lighting import project
    from shprobe.probes.env import load_env

    env = load_env(data_file("probes", "grace.hdr"))
    _refused_quickly(lambda: project(env, 1024), "goes to lmax 256")
    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "1M")
    _refused_quickly(lambda: project(env, 64), r"grace\.hdr: projecting a 256x128 latlong map "
                                               r"to lmax 64 would need")


def test_irradiance_map_and_irradiance_are_bounded(monkeypatch):
    from shprobe.lighting import irradiance, irradiance_map
    from shprobe.probes.presets import get_preset

    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "50M")
    L = get_preset("grace")
    _refused_quickly(lambda: irradiance_map(L, "latlong", (40000, 20000)),
                     "an irradiance map of 800000000 pixels")
    _refused_quickly(lambda: irradiance(np.zeros((1089, 3)), np.tile([0, 0, 1.0], (10**5, 1))),
                     "irradiance at 100000 normals, lmax 32")


def test_subdivided_brute_force_is_bounded():
    from shprobe.lighting import reference_irradiance
    from shprobe.probes.env import env_from_function

    env = env_from_function(lambda d: np.ones((*d.shape[:-1], 3)), "angular", 64)
    _refused_quickly(lambda: reference_irradiance(env, [[0, 1.0, 0]], subdivide=1000),
                     "subdivide=1000 on a angular map")
    for bad in (0, -1, 2.5, True, None):
        with pytest.raises(ShprobeError, match="subdivide must be an integer"):
            reference_irradiance(env, [[0, 1.0, 0]], subdivide=bad)


def _npz_bomb(path, shape=(40000, 40000)):
    """A tiny .npz whose one member declares (and inflates to) a huge float64 array."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buf, {"descr": "<f8", "fortran_order": False, "shape": shape})
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z, z.open("traced.npy", "w") as f:
        f.write(buf.getvalue())
        zero = bytes(1 << 20)
        for _ in range(8):  # only 8 MB really there: the header is what must be believed
            f.write(zero)
    return path


def test_npz_sizes_are_checked_before_inflating(tmp_path, monkeypatch):
    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "4G")
    bomb = _npz_bomb(tmp_path / "bomb.npz")
    assert bomb.stat().st_size < 100_000
    _refused_quickly(lambda: load_npz(bomb, what="transfer file"),
                     r"bomb\.npz: reading the arrays of this transfer file would need about "
                     r"12\.8 GB")


def test_object_arrays_in_npz_are_refused(tmp_path):
    p = tmp_path / "obj.npz"
    np.savez(p, a=np.array([{"x": 1}], dtype=object))
    with pytest.raises(ShprobeError, match="Python objects"):
        load_npz(p)


def test_transfer_bomb_is_one_line_in_the_cli(tmp_path, capsys, monkeypatch):
    from shprobe.cli.main import main

    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "1G")
    bomb = _npz_bomb(tmp_path / "t.npz", (4000, 40000))
    rc = main(["prt", "render", str(bomb), "--preset", "grace", "-o", str(tmp_path / "x.png")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc != 0 and len(err) == 1 and "t.npz" in err[0] and "would need" in err[0]
    assert not (tmp_path / "x.png").exists()


def test_max_memory_option_is_one_line_and_holds_for_one_call(capsys, monkeypatch):
    import os

    from shprobe.cli.main import main

    monkeypatch.delenv("SHPROBE_MAX_MEMORY", raising=False)
    grace = str(data_file("probes", "grace.hdr"))
    rc = main(["--max-memory", "1M", "prefilter", grace, "--lmax", "8"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1
    assert "grace.hdr" in err[0] and "over the limit of 1.05 MB" in err[0]
    assert "SHPROBE_MAX_MEMORY" not in os.environ  # the next call is not limited
    assert main(["prefilter", grace, "--lmax", "8", "--format", "json"]) == 0


@pytest.mark.parametrize("argv", [
    ["prt", "bake", "{mesh}", "--lmax", "1024", "-o", "{out}/t.npz"],
    ["prt", "bake", "{mesh}", "--samples", "1000000000", "-o", "{out}/t.npz"],
    ["render", "--preset", "grace", "--sphere", "--size", "16000x16000", "-o", "{out}/r.png"],
    ["irradiance", "--preset", "grace", "--size", "16384x8192", "-o", "{out}/i.exr"],
    ["hbasis", "render", "{mesh}", "{probe}", "--size", "4096", "-o", "{out}/h.png"],
])
def test_commands_refuse_what_would_not_fit(tmp_path, capsys, monkeypatch, argv):
    from shprobe.cli.main import main

    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "2G")
    mesh = tmp_path / "tri.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n")
    rc = main([a.format(mesh=mesh, out=tmp_path, probe=data_file("probes", "grace.hdr"))
               for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1, err
    assert "would need about" in err[0] or "would take" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tri.obj"]
