"""The Stanford bunny in the package data: the viewer's default object with no test data around,
``"bunny"`` wherever a mesh path is taken, its terms shipped beside it, the committed file what
tools/make_bunny.py makes; and a failed ``shprobe view`` start: one line, no URL."""

from __future__ import annotations

import importlib.util
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.scene.mesh import BUNNY, bunny_path, load_mesh, packaged_bunny
from tests.conftest import REPO, data_file
from tests.packaging.test_packaging import dists  # noqa: F401  (the built sdist and wheels, once per run)

SRC = str(REPO / "src")


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "SHPROBE_TEST_DATA"}
    return dict(env, PYTHONPATH=SRC, **extra)


# ----------------------------------------------------------------------------- the mesh


def test_packaged_bunny_is_a_clean_outward_mesh():
    m = packaged_bunny()
    assert (len(m.vertices), len(m.faces)) == (2503, 4968)
    assert m.is_winding_consistent
    assert m.volume > 0  # consistent and outward (a reversed winding gives a negative volume)
    # outward normals, checked independently of the winding: the vertex normal at the extreme
    # vertex along each axis points that way
    v, n = np.asarray(m.vertices), np.asarray(m.vertex_normals)
    for axis in range(3):
        for sign in (1, -1):
            i = int(np.argmax(sign * v[:, axis]))
            assert sign * n[i, axis] > 0.3, (axis, sign, n[i])
    assert np.isfinite(v).all() and np.ptp(v, axis=0).max() == pytest.approx(0.155, abs=0.01)


def test_packaged_bunny_is_the_source_geometry():
    """The test data's bunny as it is (the same faces, vertices to float32 precision): a
    further decimation showed as mottled shading (tools/make_bunny.py)."""
    import trimesh

    src = trimesh.load(data_file("meshes", "bunny.obj"), process=True)
    m = packaged_bunny()
    assert len(m.faces) == len(src.faces)
    np.testing.assert_allclose(m.vertices, src.vertices, rtol=1e-6, atol=1e-9)
    same = np.sort(np.sort(m.faces, axis=1), axis=0)
    assert (same == np.sort(np.sort(np.asarray(src.faces), axis=1), axis=0)).all()


def test_bunny_is_a_name_wherever_a_mesh_path_is_taken(tmp_path, monkeypatch):
    m = load_mesh(BUNNY)
    assert len(m.faces) == 4968 and Path(bunny_path()).is_file()
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bunny").write_text("not a mesh")  # a file of that name wins
    with pytest.raises(ShprobeError, match="bunny"):
        load_mesh(BUNNY)


def test_render_command_takes_mesh_bunny(tmp_path):
    from shprobe.cli.main import main

    out = tmp_path / "b.exr"
    assert main(["render", "--preset", "grace", "--mesh", "bunny", "--size", "64x64",
                 "-o", str(out)]) == 0
    from shprobe.probes.images import read_image

    img = read_image(out)
    assert img.shape[:2] == (64, 64) and 0.1 < (img.max(axis=-1) > 0).mean() < 0.9  # an object


def test_licence_ships_beside_it_with_the_terms():
    text = (Path(bunny_path()).parent / "bunny-LICENSE.txt").read_text()
    for words in ("Stanford Computer Graphics Laboratory", "3Dscanrep",
                  "not to be used for commercial purposes", "redistribute them for free",
                  "not covered by shprobe's MIT licence"):
        assert words in text, words
    head = Path(bunny_path()).read_text().splitlines()[:4]
    assert any("Stanford" in line for line in head)


def test_the_committed_bunny_is_what_the_tool_makes():
    src = data_file("meshes", "bunny.obj")
    spec = importlib.util.spec_from_file_location("make_bunny", REPO / "tools" / "make_bunny.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.make(src) == Path(bunny_path()).read_text()


@pytest.mark.slow
def test_the_wheel_holds_the_bunny_and_its_terms(dists):  # noqa: F811
    from tests.packaging.test_packaging import NAME, wheel_files

    files = wheel_files(dists["wheel"])
    assert files["shprobe/scene/data/bunny.obj"] == Path(bunny_path()).read_bytes()
    assert b"Stanford" in files["shprobe/scene/data/bunny-LICENSE.txt"]
    assert f"{NAME}.dist-info/licenses/src/shprobe/scene/data/bunny-LICENSE.txt" in files


# ----------------------------------------------------------------------------- shprobe view


def test_view_without_mesh_or_test_data_serves_the_bunny():
    """No --mesh, no $SHPROBE_TEST_DATA: the page gets the packaged bunny's arrays."""
    import httpx

    p = subprocess.Popen([sys.executable, "-m", "shprobe", "view", "--preset", "grace",
                          "--no-browser"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, env=_env())
    try:
        url = p.stdout.readline().split()[-1]
        base, tok = url.split("/?")[0], {"token": url.split("token=")[1]}
        init = httpx.get(base + "/api/init", params=tok, timeout=60).json()
        assert init["mesh"] == "bunny.obj"
        arrays = _unpack(httpx.get(base + "/api/mesh", params=tok, timeout=60).content)
        m = packaged_bunny()
        assert arrays["position"].shape == (2503, 3) and arrays["index"].shape == (4968, 3)
        np.testing.assert_allclose(arrays["position"], m.vertices, rtol=0, atol=1e-7)
    finally:
        p.terminate()
        p.wait(10)


def _unpack(buf: bytes) -> dict[str, np.ndarray]:
    """The arrays of one wire message (shprobe.viewer.wire.pack_binary's layout, read here as
    the page reads it)."""
    import json

    n = int.from_bytes(buf[:4], "little")
    meta = json.loads(buf[4:4 + n])["arrays"]
    return {k: np.frombuffer(buf, "<" + m["dtype"], int(np.prod(m["shape"])),
                             4 + n + m["offset"]).reshape(m["shape"]) for k, m in meta.items()}


def _failed_start(args: list[str]) -> str:
    r = subprocess.run([sys.executable, "-m", "shprobe", "view", *args, "--no-browser"],
                       capture_output=True, text=True, env=_env(), timeout=120)
    assert r.returncode == 1, r
    assert r.stdout == "", r.stdout  # no URL
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("shprobe: error: "), r.stderr
    return lines[0]


def test_failed_start_bad_mesh_is_one_line_and_no_url(tmp_path, grace_path):
    bad = tmp_path / "broken.obj"
    bad.write_text("v 0 0 0\nf 1 1 1\n")
    assert str(bad) in _failed_start([str(grace_path), "--mesh", str(bad)])
    assert "no such mesh file" in _failed_start(["--mesh", str(tmp_path / "none.obj")])


def test_failed_start_bad_transfer_is_one_line_and_no_url(tmp_path):
    bad = tmp_path / "t.npz"
    bad.write_bytes(b"PK\x03\x04 not a zip")
    assert str(bad) in _failed_start(["--preset", "grace", "--transfer", str(bad)])


def test_failed_start_bad_lighting_is_one_line_and_no_url(tmp_path, grace_path):
    assert "unknown preset" in _failed_start(["--preset", "nosuch"])
    cut = tmp_path / "cut.hdr"
    cut.write_bytes(grace_path.read_bytes()[:5000])
    assert _failed_start([str(cut)]) == (f"shprobe: error: {cut}: truncated or corrupt .hdr "
                                         "pixel data")


def test_failed_start_port_in_use_is_one_line_and_no_url():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        line = _failed_start(["--preset", "grace", "--port", str(port)])
    assert f"cannot listen on 127.0.0.1:{port}" in line
