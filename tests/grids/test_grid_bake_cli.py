"""``shprobe grid bake`` end to end (the file it writes is the library's bake, read back by
``shprobe.load_grid``) and its bad input: one line each, before any work."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import shprobe
from shprobe.cli.main import main
from shprobe.grids import GridSettings, bake_grid
from shprobe.grids.scenes import room_on_ground
from shprobe.prt.geometry import load_scene
from tests.conftest import fails_with_one_line


@pytest.fixture(scope="module")
def room_obj(tmp_path_factory):
    path = tmp_path_factory.mktemp("grid_cli") / "room.obj"
    room_on_ground().mesh().export(path)
    return path


def test_bake_writes_the_librarys_grid(tmp_path, room_obj, capsys):
    out = tmp_path / "g.npz"
    args = ["grid", "bake", str(room_obj), "--preset", "grace", "--resolution", "5,3,5",
            "--bounds=-6,0,-6,6,4,6", "--albedo", "0.5", "--bounces", "1", "--lmax", "1",
            "--samples", "512", "-o", str(out)]
    assert main(args) == 0
    assert "wrote" in capsys.readouterr().err
    g = shprobe.load_grid(out)
    assert g.resolution == (5, 3, 5) and g.lmax == 1 and g.depth is not None
    assert g.meta["bounces"] == 1 and g.meta["lighting"] == "preset:grace"
    ref = bake_grid(load_scene(room_on_ground().mesh(), albedo=0.5), _preset("grace"),
                    GridSettings((5, 3, 5), bounds=[[-6, 0, -6], [6, 4, 6]], lmax=1,
                                 bounces=1, samples=512))
    assert np.allclose(g.coeffs, ref.coeffs, atol=1e-6)
    p, n = np.array([[3.5, 0.0, 0.0], [0.0, 1.0, 0.0]]), np.array([[0, 1.0, 0], [0, 1.0, 0]])
    assert np.allclose(g.irradiance(p, n), ref.irradiance(p, n))
    # the file exists now: refused without --force, replaced with it
    fails_with_one_line(capsys, args, "already exists")
    assert main([*args, "--force", "--samples", "256"]) == 0


def _preset(name):
    from shprobe.lighting.source import resolve_lighting

    return resolve_lighting(preset=name)


def _obj(path, text):
    path.write_text(text)
    return path


@pytest.mark.parametrize(("extra", "needles"), [
    (["--resolution", "0,4,4"], ["1 to 512"]),
    (["--resolution", "1000000,4,4"], ["1 to 512"]),
    (["--resolution", "4,4"], ["three integers"]),
    (["--resolution", "a,b,c"], ["three integers"]),
    (["--resolution", "4,4,4", "--bounds=100,100,100,101,101,101"], ["contain no geometry"]),
    (["--resolution", "4,4,4", "--bounds=0,0,0,1,nan,1"], ["finite"]),
    (["--resolution", "4,4,4", "--bounds=1,1,1,0,0,0"], ["max > min"]),
    (["--resolution", "4,4,4", "--bounces", "-1"], ["bounces"]),
    (["--resolution", "4,4,4", "--samples", "3"], ["samples"]),
    (["--resolution", "512,512,512"], ["would need about"]),
    (["--resolution", "4,4,4", "-o", "g.bin"], ["g.bin", "*.npz"]),
])
def test_bad_arguments_are_one_line_before_work(tmp_path, room_obj, capsys, extra, needles):
    out = tmp_path / "g.npz"
    took = fails_with_one_line(capsys, ["grid", "bake", str(room_obj), "--preset", "grace",
                                        "-o", str(out), *extra], *needles)
    assert not out.exists() and took < 5


def test_bad_scenes_are_one_line_naming_the_file(tmp_path, capsys):
    out = tmp_path / "g.npz"
    nan = _obj(tmp_path / "nan.obj", "v 0 0 0\nv 1 0 nan\nv 0 0 1\nf 1 3 2\n")
    empty = _obj(tmp_path / "empty.obj", "v 0 0 0\nv 1 0 0\nv 0 0 1\n")
    for path, what in ((nan, "non-finite vertex"), (empty, "triangles")):
        fails_with_one_line(capsys, ["grid", "bake", str(path), "--preset", "grace",
                                     "--resolution", "2,2,2", "-o", str(out)], path.name,
                            what)
    fails_with_one_line(capsys, ["grid", "bake", str(tmp_path / "missing.obj"), "--preset",
                                 "grace", "--resolution", "2,2,2", "-o", str(out)], "missing.obj")
    assert not out.exists()


def test_nan_vertices_in_a_mesh_object_are_refused():
    from shprobe.errors import ShprobeError

    mesh = trimesh.Trimesh([[0, 0, 0], [1, 0, np.nan], [0, 0, 1]], [[0, 2, 1]], process=False)
    with pytest.raises(ShprobeError, match="non-finite"):
        bake_grid(mesh, _preset("grace"), GridSettings((2, 2, 2)))


def test_lighting_is_required_once(tmp_path, capsys):
    tri = tmp_path / "t.obj"
    trimesh.creation.box().export(tri)
    out = str(tmp_path / "g.npz")
    fails_with_one_line(capsys, ["grid", "bake", str(tri), "--resolution", "2,2,2", "-o", out],
                        "--lighting PROBE", "got none")
    fails_with_one_line(capsys, ["grid", "bake", str(tri), "--preset", "grace", "--lighting",
                                 str(tri), "--resolution", "2,2,2", "-o", out], "exactly one")


def test_bake_under_a_probe_image(tmp_path, room_obj, grace_path, capsys):
    out = tmp_path / "g.npz"
    assert main(["-q", "grid", "bake", str(room_obj), "--lighting", str(grace_path),
                 "--resolution", "3,2,3", "--bounds=-6,0,-6,6,4,6", "--samples", "256",
                 "--bounces", "0", "-o", str(out)]) == 0
    g = shprobe.load_grid(out)
    assert g.meta["lighting"] == str(grace_path) and g.meta["bounces"] == 0
    assert np.all(np.isfinite(g.coeffs)) and g.coeffs[..., 0, :].max() > 0


def test_grid_group_holds_bake_and_export():
    """The top-level command's ``grid`` group offers both subcommands (export registered from
    its own module)."""
    import click

    from shprobe.cli import grid as grid_cli

    top = click.Group("top")
    grid_cli.register(top)
    assert set(top.commands["grid"].commands) == {"bake", "export"}
    assert "three" in top.commands["grid"].commands["export"].params[1].type.choices


def test_reference_scenes_by_name(tmp_path, capsys, monkeypatch):
    """``room`` and ``bunny-on-ground`` name the reference scenes (with their grid bounds as
    the default --bounds): the bake is the library's on room_on_ground(); a file of that name
    in the working folder is read instead (here a bad one: one line naming it)."""
    from shprobe.grids.scenes import bunny_on_ground, named_scene

    monkeypatch.chdir(tmp_path)
    out = tmp_path / "g.npz"
    assert main(["-q", "grid", "bake", "room", "--preset", "grace", "--resolution", "3,2,3",
                 "--albedo", "0.5", "--bounces", "1", "--lmax", "1", "--samples", "256",
                 "-o", str(out)]) == 0
    g = shprobe.load_grid(out)
    room = room_on_ground()
    np.testing.assert_array_equal(g.bounds, room.bounds)
    ref = bake_grid(load_scene(room.mesh(), albedo=0.5), _preset("grace"),
                    GridSettings((3, 2, 3), bounds=room.bounds, lmax=1, bounces=1,
                                 samples=256))
    assert np.allclose(g.coeffs, ref.coeffs, atol=1e-6)
    mesh, bounds = named_scene("bunny-on-ground")
    want_mesh, want_bounds = bunny_on_ground()
    np.testing.assert_array_equal(bounds, want_bounds)
    assert len(mesh.faces) == len(want_mesh.faces) > 4968
    assert named_scene("room.obj") is None and named_scene("bunny") is None
    (tmp_path / "room").write_text("not a mesh\n")
    assert named_scene("room") is None
    fails_with_one_line(capsys, ["grid", "bake", "room", "--preset", "grace", "--resolution",
                                 "2,2,2", "-o", str(tmp_path / "h.npz")], "room")
