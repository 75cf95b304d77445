"""`shprobe prt bake` / `shprobe prt render`: files, refusals, one-line errors."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shprobe.cli.main import main
from shprobe.prt import bake, load_transfer


@pytest.fixture
def sphere_obj(tmp_path):
    p = tmp_path / "sphere.obj"
    trimesh.creation.icosphere(subdivisions=2).export(p)
    return p


def fails_with_one_line(capsys, args, *needles):
    capsys.readouterr()
    assert main(args) != 0
    err = capsys.readouterr().err.strip()
    assert err.startswith("shprobe: error:") and "\n" not in err, err
    for n in needles:
        assert n in err, err


def test_bake_cli_matches_library(tmp_path, sphere_obj, capsys):
    out = tmp_path / "t.npz"
    assert main(["prt", "bake", str(sphere_obj), "--mode", "shadowed", "--lmax", "4",
                 "--samples", "128", "--seed", "3", "--albedo", "0.5", "--threads", "1",
                 "-o", str(out)]) == 0
    t = load_transfer(out, scene=sphere_obj)
    ref = bake(sphere_obj, mode="shadowed", lmax=4, samples=128, seed=3, albedo=0.5)
    np.testing.assert_allclose(t.transfer, ref.transfer, rtol=1e-6, atol=1e-7)
    assert t.metadata["samples"] == 128 and t.metadata["seed"] == 3
    # an existing output is refused without --force, replaced with it
    fails_with_one_line(capsys, ["prt", "bake", str(sphere_obj), "-o", str(out), "--samples",
                                 "64"], str(out), "already exists")
    assert main(["prt", "bake", str(sphere_obj), "-o", str(out), "--mode", "unshadowed",
                 "--force"]) == 0
    assert load_transfer(out).mode == "unshadowed"


def test_bake_cli_ground_and_colour(tmp_path, sphere_obj):
    out = tmp_path / "g.npz"
    assert main(["prt", "bake", str(sphere_obj), "--ground", "--mode", "unshadowed",
                 "--albedo", "0.2,0.4,0.6", "--lmax", "2", "-o", str(out)]) == 0
    t = load_transfer(out)
    assert t.transfer.shape[1:] == (9, 3)
    assert t.n_vertices > len(trimesh.load(sphere_obj).vertices)  # the ground was added
    np.testing.assert_allclose(t.albedo[-1], [0.2, 0.4, 0.6])


def test_bake_cli_bad_mesh_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.obj"
    bad.write_text("this is not a mesh\n")
    fails_with_one_line(capsys, ["prt", "bake", str(bad), "-o", str(tmp_path / "x.npz")],
                        str(bad))
    fails_with_one_line(capsys, ["prt", "bake", str(tmp_path / "nope.obj"), "-o",
                                 str(tmp_path / "x.npz")], "nope.obj")


def test_render_refuses_transfer_of_another_mesh(tmp_path, sphere_obj, capsys):
    out = tmp_path / "t.npz"
    assert main(["prt", "bake", str(sphere_obj), "--mode", "unshadowed", "-o", str(out)]) == 0
    other = tmp_path / "other.obj"
    trimesh.creation.icosphere(subdivisions=1).export(other)
    fails_with_one_line(capsys, ["prt", "render", str(out), "--window", "0,1,0,30", "--scene",
                                 str(other), "-o", str(tmp_path / "x.png")],
                        str(out), "baked for mesh")
    assert not (tmp_path / "x.png").exists()


def test_render_window_and_turntable(tmp_path, sphere_obj):
    out = tmp_path / "t.npz"
    assert main(["prt", "bake", str(sphere_obj), "--mode", "shadowed", "--lmax", "6",
                 "--samples", "64", "-o", str(out)]) == 0
    png = tmp_path / "w.png"
    assert main(["prt", "render", str(out), "--window", "0,1,0,25", "--size", "64x48",
                 "--lmax", "4", "--rotate", "1,0,0,30", "-o", str(png)]) == 0
    from PIL import Image

    img = np.asarray(Image.open(png))
    assert img.shape == (48, 64, 3) and img.max() > 0
    assert main(["prt", "render", str(out), "--window", "1,0,0,25", "--size", "32x32",
                 "--turntable", "3", "-o", str(tmp_path / "f.png")]) == 0
    frames = [np.asarray(Image.open(tmp_path / f"f_{i:03d}.png")) for i in range(3)]
    assert not np.array_equal(frames[0], frames[1])  # the light moved


def test_render_probe_and_preset_need_no_rebake(tmp_path, sphere_obj, grace_path):
    out = tmp_path / "t.npz"
    assert main(["prt", "bake", str(sphere_obj), "--mode", "unshadowed", "--lmax", "6",
                 "-o", str(out)]) == 0
    before = out.stat().st_mtime_ns
    for args in ([str(grace_path), "--lmax", "4"], ["--preset", "grace"]):
        png = tmp_path / f"{len(args)}.png"
        assert main(["prt", "render", str(out), *args, "--size", "32x32", "-o", str(png)]) == 0
        assert png.stat().st_size > 0
    assert out.stat().st_mtime_ns == before
