"""Hostile and broken input to PRT: every array of a transfer validated on load, zip bombs
refused from the headers before anything is inflated, NaN lighting or transfers in relight, and
absurd turntables refused before work (one line each, never a traceback)."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
import trimesh

from shprobe.cli.main import main
from shprobe.errors import ShprobeError
from shprobe.prt import bake, load_transfer, relight
from tests.conftest import fails_with_one_line


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    d = tmp_path_factory.mktemp("prt_bad")
    mesh = d / "s.obj"
    trimesh.creation.icosphere(subdivisions=1, radius=0.5).export(mesh)
    t = bake(str(mesh), mode="unshadowed", lmax=2)
    t.save(d / "t.npz")
    return d / "t.npz", t


def rewrite(src, dst, **changes):
    with np.load(src) as d:
        arrays = {k: d[k] for k in d.files}
    arrays.update(changes)
    np.savez(dst, **arrays)
    return dst


@pytest.mark.parametrize("name", ["albedo", "normals"])
def test_short_albedo_or_normals_is_one_line(tmp_path, capsys, sphere, name):
    path, t = sphere
    bad = rewrite(path, tmp_path / "short.npz", **{name: getattr(t, name)[:-3]})
    with pytest.raises(ShprobeError, match=name):
        load_transfer(bad)
    fails_with_one_line(capsys, ["prt", "render", str(bad), "--cone", "0,1,0:30", "--mode",
                            "unshadowed", "--size", "16x16", "-o", str(tmp_path / "x.png")],
                   "short.npz", name)


def npy_header(shape, dtype="<f8"):
    """An .npy v1.0 header declaring ``shape`` (the data itself left out)."""
    text = repr({"descr": dtype, "fortran_order": False, "shape": tuple(shape)})
    text += " " * (63 - (len(text) + 10) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + len(text).to_bytes(2, "little") + text.encode()


def zip_bomb(path, n, layers=3, k=49):
    """A small .npz whose members declare a consistent scene of ``n`` vertices (gigabytes
    inflated) but hold only their headers."""
    meta = json.dumps({"format": "shprobe-prt", "version": 2, "mode": "interreflected",
                       "lmax": 6, "bounces": layers - 1, "mesh_hash": "x"})
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name, shape, dtype in (("vertices", (n, 3), "<f8"), ("normals", (n, 3), "<f8"),
                                   ("albedo", (n, 3), "<f8"), ("faces", (2 * n, 3), "<i8"),
                                   ("traced", (layers, n, k, 3), "<f4"),
                                   ("bounce_counts", (layers,), "<i8")):
            z.writestr(f"{name}.npy", npy_header(shape, dtype))
        m = np.array(meta)
        z.writestr("metadata.npy", npy_header((), m.dtype.str) + m.tobytes())
    return path


def test_zip_bomb_is_refused_before_inflating(tmp_path, capsys, monkeypatch):
    def no_inflating(*a, **k):
        raise AssertionError("np.load called: the file was inflated before the check")

    huge = zip_bomb(tmp_path / "huge.npz", 60_000_000)
    assert huge.stat().st_size < 10_000
    monkeypatch.setattr(np, "load", no_inflating)
    with pytest.raises(ShprobeError, match="over the limit"):
        load_transfer(huge)
    # consistent and under the vertex limit, but more than memory allows (1e6 vertices at
    # lmax 6 with 3 layers: ~1.9 GB inflated)
    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "256M")
    bomb = zip_bomb(tmp_path / "bomb.npz", 1_000_000)
    with pytest.raises(ShprobeError, match="would need about"):
        load_transfer(bomb)
    # a member declaring more rows than the mesh has
    with zipfile.ZipFile(tmp_path / "odd.npz", "w") as z, zipfile.ZipFile(bomb) as b:
        for info in b.infolist():
            data = b.read(info)
            if info.filename == "albedo.npy":
                data = npy_header((1_000_001, 3))
            z.writestr(info.filename, data)
    with pytest.raises(ShprobeError, match="'albedo' has shape"):
        load_transfer(tmp_path / "odd.npz")
    monkeypatch.undo()
    fails_with_one_line(capsys, ["prt", "render", str(huge), "--cone", "0,1,0:30", "-o",
                            str(tmp_path / "x.png")], "huge.npz", "over the limit")


def test_relight_refuses_nan_lighting_and_transfers(sphere):
    _, t = sphere
    light = np.zeros((9, 3))
    light[0] = 1.0
    assert np.isfinite(relight(t, light)).all()
    bad = light.copy()
    bad[4, 1] = np.nan
    with pytest.raises(ShprobeError, match="NaN"):
        relight(t, bad)
    arr = t.transfer.astype(np.float64)
    arr[7, 0] = np.nan
    with pytest.raises(ShprobeError, match="NaN"):
        relight(arr, light)
    from dataclasses import replace

    shadowed = bake(trimesh.creation.icosphere(subdivisions=1), mode="shadowed", lmax=2,
                    samples=64)
    traced = shadowed.traced.copy()
    traced[0, 3, 2] = np.inf
    with pytest.raises(ShprobeError, match="NaN or infinity"):
        relight(replace(shadowed, traced=traced), light)
    with pytest.raises(ShprobeError, match="must be numbers"):
        relight(t, np.array([object()] * 9))


def test_absurd_turntable_is_refused_before_work(tmp_path, capsys, sphere):
    path, _ = sphere
    fails_with_one_line(capsys, ["prt", "render", str(path), "--cone", "0,1,0:30", "--turntable",
                            "100000", "-o", str(tmp_path / "f.png")], "--turntable", "3600")
    assert not list(tmp_path.glob("f_*"))


def test_turntable_streams_its_frames(tmp_path, sphere, monkeypatch):
    """Frames are rendered and written one at a time, and the automatic exposure reads a
    bounded number of them (72 angles spread over the turn), whatever the count."""
    import shprobe.prt.view as view

    path, _ = sphere
    alive, peak, exposure, rendering = [0], [0], [0], [False]
    inner_frame, inner_radiance = view.render_frame, view.frame_radiance

    class Held:
        def __init__(self, r):
            self.r = r
            alive[0] += 1
            peak[0] = max(peak[0], alive[0])

        def save(self, *a):
            self.r.save(*a)
            alive[0] -= 1

    def radiance(*a, **k):
        exposure[0] += not rendering[0]  # the exposure's, before any frame is rendered
        return inner_radiance(*a, **k)

    def frame(*a, **k):
        rendering[0] = True
        return Held(inner_frame(*a, **k))

    monkeypatch.setattr(view, "render_frame", frame)
    monkeypatch.setattr(view, "frame_radiance", radiance)
    out = tmp_path / "f.png"
    assert main(["prt", "render", str(path), "--cone", "0,1,0:30", "--turntable", "90",
                 "--size", "8x8", "-o", str(out)]) == 0
    assert len(list(tmp_path.glob("f_*.png"))) == 90
    assert peak[0] == 1 and alive[0] == 0
    assert exposure[0] == 72
