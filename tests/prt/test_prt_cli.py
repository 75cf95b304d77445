"""`shprobe prt bake` / `shprobe prt render`: files, refusals, one-line errors."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shprobe.cli.main import main
from shprobe.prt import bake, load_transfer
from tests.conftest import fails_with_one_line


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
    fails_with_one_line(capsys, ["prt", "render", str(out), "--cone", "0,1,0:30", "--scene",
                                 str(other), "-o", str(tmp_path / "x.png")],
                        str(out), "baked for mesh")
    assert not (tmp_path / "x.png").exists()


def test_render_window_and_turntable(tmp_path, sphere_obj):
    out = tmp_path / "t.npz"
    assert main(["prt", "bake", str(sphere_obj), "--mode", "shadowed", "--lmax", "6",
                 "--samples", "64", "-o", str(out)]) == 0
    png = tmp_path / "w.png"
    assert main(["prt", "render", str(out), "--cone", "0,1,0:25", "--size", "64x48",
                 "--lmax", "4", "--rotate", "1,0,0:30", "-o", str(png)]) == 0
    from PIL import Image

    img = np.asarray(Image.open(png))
    assert img.shape == (48, 64, 3) and img.max() > 0
    assert main(["prt", "render", str(out), "--cone", "1,0,0:25", "--size", "32x32",
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


def test_render_picks_the_model_at_run_time(tmp_path, sphere_obj, capsys):
    """One interreflected bake renders as shadowed, as 1 bounce and as unshadowed, pixel for
    pixel the same as renders of separate bakes (same seed and samples)."""
    from shprobe.probes.images import read_image

    box = tmp_path / "box.obj"
    trimesh.creation.box(extents=[1.0, 0.2, 1.0]).apply_translation([0.0, 1.3, 0.0]).export(box)
    bake_args = [str(sphere_obj), str(box), "--lmax", "3", "--samples", "128", "--seed", "2"]
    files = {}
    for mode, extra in (("interreflected", ["--bounces", "2"]), ("interreflected1",
                        ["--bounces", "1"]), ("shadowed", []), ("unshadowed", [])):
        files[mode] = tmp_path / f"{mode}.npz"
        assert main(["prt", "bake", *bake_args, "--mode", mode.rstrip("1"), *extra, "-o",
                     str(files[mode])]) == 0

    def render(path, *args):
        out = tmp_path / f"r{len(list(tmp_path.glob('r*.pfm')))}.pfm"
        assert main(["prt", "render", str(path), "--cone", "0,1,0:60", "--size", "40x40",
                     "--elevation", "10", *args, "-o", str(out)]) == 0
        return read_image(out)

    ir = files["interreflected"]
    for args, ref in ((["--mode", "shadowed"], "shadowed"), (["--bounces", "1"],
                      "interreflected1"), (["--mode", "unshadowed"], "unshadowed"),
                      ([], "interreflected")):
        np.testing.assert_array_equal(render(ir, *args), render(files[ref]))
    assert not np.array_equal(render(ir, "--mode", "shadowed"), render(ir))
    # what a file cannot give: one line naming the file, no picture
    for f, args, msg in ((files["unshadowed"], ["--mode", "shadowed"], "baked unshadowed"),
                         (files["shadowed"], ["--mode", "interreflected"], "baked shadowed"),
                         (ir, ["--bounces", "3"], "2 bounces"),
                         (ir, ["--mode", "shadowed", "--bounces", "1"], "interreflected")):
        fails_with_one_line(capsys, ["prt", "render", str(f), "--cone", "0,1,0:60", *args,
                                     "-o", str(tmp_path / "no.png")], str(f), msg)
    assert not (tmp_path / "no.png").exists()


def test_bake_cli_refuses_bad_seed_and_threads(tmp_path, sphere_obj, capfd):
    out = tmp_path / "y.npz"
    fails_with_one_line(capfd, ["prt", "bake", str(sphere_obj), "--seed", "-5", "-o",
                                   str(out)], "--seed", "-5")
    fails_with_one_line(capfd, ["prt", "bake", str(sphere_obj), "--threads", "0", "-o",
                                   str(out)], "--threads")
    fails_with_one_line(capfd, ["prt", "bake", str(sphere_obj), "--mode", "interreflected",
                                   "--bounces", "-1", "-o", str(out)], "--bounces")
    assert not out.exists()


def test_bake_cli_albedo_per_mesh(tmp_path, capsys):
    """--albedo once per mesh (in order) is per-mesh grey; once with r,g,b is RGB for every
    mesh; another count is refused; --ground-albedo sets the ground."""
    paths = []
    for k in range(3):
        p = tmp_path / f"m{k}.obj"
        trimesh.creation.icosphere(1).apply_translation([3.0 * k, 0.0, 0.0]).export(p)
        paths.append(str(p))
    nv = len(trimesh.load(paths[0]).vertices)
    out = tmp_path / "a.npz"
    assert main(["prt", "bake", *paths, "--mode", "unshadowed", "--lmax", "1", "--albedo",
                 "0.1", "--albedo", "0.5", "--albedo", "0.9", "--ground", "--ground-albedo",
                 "0.3", "-o", str(out)]) == 0
    t = load_transfer(out)
    np.testing.assert_array_equal(t.albedo[: 3 * nv, 0], np.repeat([0.1, 0.5, 0.9], nv))
    np.testing.assert_array_equal(t.albedo[3 * nv:], 0.3)  # the ground
    assert t.transfer.ndim == 2
    assert main(["prt", "bake", *paths, "--mode", "unshadowed", "--lmax", "1", "--albedo",
                 "0.1,0.5,0.9", "-o", str(out), "--force"]) == 0
    np.testing.assert_array_equal(load_transfer(out).albedo, np.tile([0.1, 0.5, 0.9],
                                                                     (3 * nv, 1)))
    assert main(["prt", "bake", *paths, "--mode", "unshadowed", "--lmax", "1", "--albedo",
                 "0.2", "--albedo", "1,0,0", "--albedo", "0.4", "-o", str(out), "--force"]) == 0
    np.testing.assert_array_equal(load_transfer(out).albedo[nv:2 * nv], [[1, 0, 0]] * nv)
    fails_with_one_line(capsys, ["prt", "bake", *paths, "--albedo", "0.1", "--albedo", "0.5",
                                 "-o", str(tmp_path / "b.npz")], "2 times for 3 meshes")
    fails_with_one_line(capsys, ["prt", "bake", *paths, "--albedo", "0.1,0.5", "-o",
                                 str(tmp_path / "b.npz")], "r,g,b")


@pytest.mark.parametrize("args", [["--preset", "grace", "--rotate", "0,1,0:inf"],
                                  ["--preset", "grace", "--rotate", "nan,1,0:30"],
                                  ["--cone", "inf,1,0:30"],
                                  ["--cone", "0,1,0:nan"],
                                  ["--preset", "grace", "--azimuth", "nan"],
                                  ["--preset", "grace", "--elevation", "inf"]])
def test_render_refuses_non_finite_numbers_in_one_line(tmp_path, sphere_obj, capfd, args):
    t = tmp_path / "t.npz"
    assert main(["prt", "bake", str(sphere_obj), "--mode", "unshadowed", "--lmax", "2", "-o",
                 str(t)]) == 0
    fails_with_one_line(capfd, ["prt", "render", str(t), *args, "-o",
                                   str(tmp_path / "x.png")], "finite")
    assert not (tmp_path / "x.png").exists()


def test_render_huge_axis_is_normalised_without_overflow(tmp_path, sphere_obj, capfd):
    """An axis of 1e308 components is a direction like any other (no overflow warning)."""
    from shprobe.probes.images import read_image

    t = tmp_path / "t.npz"
    assert main(["prt", "bake", str(sphere_obj), "--mode", "unshadowed", "--lmax", "2", "-o",
                 str(t)]) == 0
    capfd.readouterr()
    for name, axis in (("a", "1e308,1e308,0"), ("b", "1,1,0")):
        assert main(["prt", "render", str(t), "--cone", f"{axis}:40", "--rotate",
                     f"{axis}:30", "--size", "24x24", "-o", str(tmp_path / f"{name}.pfm")]) == 0
    assert "Warning" not in capfd.readouterr().err
    np.testing.assert_array_equal(read_image(tmp_path / "a.pfm", clamp=True),
                                  read_image(tmp_path / "b.pfm", clamp=True))
