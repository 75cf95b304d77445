"""Hostile meshes and small error paths: a NaN or infinite vertex is refused by every command
that reads a mesh (not silently dropped), a mesh far from the origin is not "zero extent", a
FIFO named as a mesh is "not a regular file" (not "no such mesh file"); the batch's full disk
and the names in error messages. Each case prints the one line the command gives."""

from __future__ import annotations

import errno
import os
import subprocess
import sys

import numpy as np
import pytest

from shprobe.cli.main import main
from tests.conftest import data_file

pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

_TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv {x} {y} 1\nf 1 2 3\nf 1 2 4\n"


def _obj(path, x="0", y="0"):
    path.write_text(_TRI.format(x=x, y=y))
    return path


def _far_bunny(path, offset: float):
    import trimesh

    from shprobe.scene.mesh import bunny_path

    m = trimesh.load(bunny_path(), process=False)
    with open(path, "w") as f:
        for v in m.vertices + offset:
            f.write("v " + " ".join(f"{x:.17g}" for x in v) + "\n")
        for t in m.faces + 1:
            f.write("f " + " ".join(str(i) for i in t) + "\n")
    return path


def _one_line(argv, capfd, named) -> str:
    rc = main(argv)
    err = [ln for ln in capfd.readouterr().err.splitlines() if ln.strip()]
    print(rc, err)
    assert rc == 1, (rc, err)
    assert len(err) == 1 and err[0].startswith("shprobe: error:"), err
    assert "Traceback" not in err[0] and str(named) in err[0], err
    return err[0]


def _commands(mesh, out_dir):
    return {
        "render": ["render", "--preset", "grace", "--mesh", str(mesh), "--size", "16x16",
                   "-o", str(out_dir / "r.png")],
        "prt bake": ["prt", "bake", str(mesh), "-o", str(out_dir / "t.npz")],
        "grid bake": ["grid", "bake", str(mesh), "--preset", "grace", "--resolution",
                      "2,2,2", "--samples", "64", "--bounces", "0", "-o",
                      str(out_dir / "g.npz")],
        "hbasis bake": ["hbasis", "bake", str(mesh), str(data_file('probes', 'grace.hdr')), "-o",
                        str(out_dir / "h.npz")],
    }


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
@pytest.mark.parametrize("command", ["render", "prt bake", "grid bake", "hbasis bake"])
def test_non_finite_vertex_is_refused_by_every_mesh_reader(command, value, tmp_path, capfd):
    mesh = _obj(tmp_path / "m.obj", x=value)
    argv = _commands(mesh, tmp_path)[command]
    line = _one_line(argv, capfd, mesh)
    assert "non-finite vertex coordinates (vertex 4 of 4)" in line
    assert not any(p.suffix in (".png", ".npz") for p in tmp_path.iterdir())


@pytest.mark.parametrize("command", ["render", "prt bake", "grid bake"])
def test_mesh_far_from_the_origin_is_not_zero_extent(command, tmp_path, capfd):
    mesh = _far_bunny(tmp_path / "far.obj", 1e11)  # trimesh's merge used to collapse it
    rc = main(["-q", *_commands(mesh, tmp_path)[command]])
    err = capfd.readouterr().err
    print(rc, err)
    assert rc == 0 and "zero extent" not in err, err


def test_far_mesh_keeps_its_vertices(tmp_path):
    from shprobe.scene.mesh import load_mesh, packaged_bunny

    m = load_mesh(_far_bunny(tmp_path / "far.obj", 1e11))
    assert len(m.vertices) == len(packaged_bunny().vertices)
    big = load_mesh(_obj(tmp_path / "big.obj", x="1e99", y="1e99"))
    assert np.ptp(big.vertices, axis=0).max() == pytest.approx(1e99)


def test_fifo_named_as_a_mesh_is_not_missing(tmp_path):
    fifo = tmp_path / "scene.obj"
    os.mkfifo(fifo)
    for argv in (["render", "--preset", "grace", "--mesh", str(fifo), "-o",
                  str(tmp_path / "r.png")],
                 ["grid", "bake", str(fifo), "--preset", "grace", "--resolution", "2,2,2",
                  "-o", str(tmp_path / "g.npz")]):
        r = subprocess.run([sys.executable, "-m", "shprobe", *argv], capture_output=True,
                           text=True, timeout=60)
        err = r.stderr.strip().splitlines()
        print(err)
        assert r.returncode == 1 and len(err) == 1, r.stderr
        assert "is not a regular file" in err[0] and "no such" not in err[0]


# ----------------------------------------------------------------------------- batch, messages

def _probe(tmp_path):
    from shprobe.probes.env import write_env
    from shprobe.probes.environments import procedural_env

    lib = tmp_path / "lib"
    lib.mkdir()
    write_env(lib / "a.hdr", procedural_env(32, 16))
    write_env(lib / "b.hdr", procedural_env(64, 32))
    return lib


def test_batch_full_disk_is_said_before_work(tmp_path, capfd, monkeypatch):
    lib = _probe(tmp_path)
    out = tmp_path / "out" / "t.parquet"
    real = os.statvfs

    class Full:
        def __init__(self, st):
            self.f_bavail, self.f_frsize = 10, st.f_frsize

    monkeypatch.setattr(os, "statvfs", lambda p: Full(real(p)))
    line = _one_line(["batch", str(lib), "-o", str(out), "--scheduler", "inline"], capfd, out)
    assert "of disk" in line and "free" in line
    assert not out.exists() and not (tmp_path / "out" / "t.parquet.parts").exists()


def test_batch_disk_full_while_writing_leaves_no_parts_folder(tmp_path, capfd, monkeypatch):
    import pyarrow.parquet as pq

    lib = _probe(tmp_path)
    out = tmp_path / "t.parquet"

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pq, "write_table", full)
    rc = main(["batch", str(lib), "-o", str(out), "--scheduler", "inline"])
    err = [ln for ln in capfd.readouterr().err.splitlines() if ln.strip()]
    print(rc, err)  # a progress line may come first: the disk filled while it ran
    assert rc == 1 and err[-1] == f"shprobe: error: {out}: cannot write: No space left on device"
    assert sum("error" in ln for ln in err) == 1 and "Traceback" not in "".join(err)
    assert not out.exists() and not (tmp_path / "t.parquet.parts").exists()


def test_env_type_error_names_a_real_function():
    import shprobe
    from shprobe.errors import ShprobeError
    from shprobe.lighting.reference import check_env

    with pytest.raises(ShprobeError) as e:
        check_env(np.ones((4, 8, 3)))
    print(e.value)
    assert "shprobe.load_env(path)" in str(e.value) and callable(shprobe.load_env)


def test_in_memory_mesh_with_a_nan_vertex_is_refused_by_the_bake():
    import trimesh

    from shprobe.errors import ShprobeError
    from shprobe.grids import GridSettings, bake_grid

    m = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [np.nan, 0, 1]],
                        [[0, 1, 2], [0, 1, 3]], process=False)
    with pytest.raises(ShprobeError, match="non-finite vertex") as e:
        bake_grid(m, np.eye(9, 3), GridSettings(resolution=(2, 2, 2), samples=64,
                                                bounces=0))
    print(e.value)
