"""Scene meshes: the one loader (formats, errors), albedo from materials, textures and colours
on disk, the bilinear texture lookup, the mesh hash."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.scene import Camera, load_mesh, render
from tests.scene.test_scene_render import _quad, lighting


def test_load_mesh_formats_and_errors(tmp_path):
    import trimesh

    a = trimesh.creation.box()
    b = trimesh.creation.icosphere(1)
    b.apply_translation([3, 0, 0])
    scene = trimesh.Scene([a, b])
    scene.export(tmp_path / "s.glb")
    m = load_mesh(tmp_path / "s.glb")
    assert len(m.faces) == len(a.faces) + len(b.faces)
    b.export(tmp_path / "s.ply")
    assert len(load_mesh(tmp_path / "s.ply").faces) == len(b.faces)
    (tmp_path / "bad.obj").write_text("this is not a mesh\n")
    (tmp_path / "bad.glb").write_bytes(b"glTF\x00garbage")
    for name in ("bad.obj", "bad.glb", "missing.ply"):
        with pytest.raises(ShprobeError) as e:
            load_mesh(tmp_path / name)
        assert name in str(e.value) and "\n" not in str(e.value)


def test_material_and_face_colours_from_disk(tmp_path):
    """Untextured albedo from the file: OBJ ``Kd``, glTF ``baseColorFactor`` (both linear),
    PLY face colours (8-bit sRGB); files written by hand except the GLB."""
    import trimesh
    from trimesh.visual import TextureVisuals
    from trimesh.visual.material import PBRMaterial

    L = lighting()
    cam = Camera(16, 16, projection="orthographic", ortho_height=1.0)
    white = render(_quad(), L, cam)
    quad = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
    (tmp_path / "k.mtl").write_text("newmtl m\nKd 0.8 0.4 0.2\n")
    (tmp_path / "k.obj").write_text(f"mtllib k.mtl\n{quad}usemtl m\nf 1 2 3\nf 1 3 4\n")
    res = render(load_mesh(tmp_path / "k.obj"), L, cam)
    np.testing.assert_allclose(res.image[white.mask], white.image[white.mask] * [0.8, 0.4, 0.2],
                               rtol=1e-2)
    g = trimesh.Trimesh(_quad().vertices, _quad().faces, process=False)
    g.visual = TextureVisuals(material=PBRMaterial(baseColorFactor=[0.2, 1.0, 0.6, 1.0]))
    g.export(tmp_path / "g.glb")
    res = render(load_mesh(tmp_path / "g.glb"), L, cam)
    np.testing.assert_allclose(res.image[white.mask], white.image[white.mask] * [0.2, 1.0, 0.6],
                               rtol=1e-2)
    (tmp_path / "f.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
        "-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n3 0 1 2 255 0 0\n3 0 2 3 0 0 255\n")
    res = render(load_mesh(tmp_path / "f.ply"), L, cam)
    # face 0 (lower right of the diagonal) red, face 1 (upper left) blue
    assert res.image[12, 14, 0] > 0.5 * white.image[12, 14, 0] and res.image[12, 14, 2] == 0
    assert res.image[2, 1, 2] > 0.5 * white.image[2, 1, 2] and res.image[2, 1, 0] == 0


def test_textured_obj_and_coloured_ply_from_disk(tmp_path):
    """Albedo taken from the file: an OBJ + MTL + PNG texture, a PLY with vertex colours."""
    import trimesh
    from PIL import Image

    img = np.zeros((4, 4, 3), np.uint8)
    img[:, :2] = [255, 0, 0]  # left half red
    img[:, 2:] = [0, 0, 255]  # right half blue
    Image.fromarray(img).save(tmp_path / "tex.png")
    (tmp_path / "q.mtl").write_text("newmtl m\nKd 1 1 1\nmap_Kd tex.png\n")
    (tmp_path / "q.obj").write_text(
        "mtllib q.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    L = lighting()
    cam = Camera(16, 16, projection="orthographic", ortho_height=1.0)
    res = render(load_mesh(tmp_path / "q.obj"), L, cam)
    white = render(_quad(), L, cam)
    np.testing.assert_allclose(res.image[:, :4, 0], white.image[:, :4, 0], rtol=1e-4)
    assert np.all(res.image[:, :4, 1:] < 1e-6) and np.all(res.image[:, -4:, :2] < 1e-6)
    # PLY with per-vertex colours: uniform mid grey (sRGB 128 → linear 0.2158)
    m = trimesh.creation.icosphere(2)
    m.visual.vertex_colors = np.tile([128, 128, 128, 255], (len(m.vertices), 1))
    m.export(tmp_path / "c.ply")
    res = render(load_mesh(tmp_path / "c.ply"), L, Camera(20, 20))
    plain = render(load_mesh(tmp_path / "c.ply"), L, Camera(20, 20), albedo=1.0)
    lin = ((128 / 255 + 0.055) / 1.055) ** 2.4
    np.testing.assert_allclose(res.image[res.mask], lin * plain.image[res.mask], rtol=1e-4)
