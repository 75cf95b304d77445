"""`shprobe view --grid` over real HTTP (uvicorn in a thread, as the command runs it): the
grid page's data are the library's (probe positions, validity, E_lm = Â_l L_lm), the shading
endpoint's irradiance is ProbeGrid.irradiance at the placed object's vertices, leak control
on/off differ where the grid has depth data, malformed requests are one-line 400s, and a
missing or corrupt grid file is one line, no URL, a non-zero exit."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from shprobe.grids import ProbeGrid, save_grid
from shprobe.grids.scenes import room_on_ground
from shprobe.lighting.irradiance import irradiance
from shprobe.viewer.grid import MAX_SHADE, MAX_VIEW_PROBES, GridView
from tests.viewer.test_viewer import VENDOR, Served

SRC = Path(__file__).resolve().parents[2] / "src"


def make_grid(depth: bool = False, res: tuple[int, int, int] = (5, 3, 4)) -> ProbeGrid:
    """A grid over the room scene's bounds whose probes differ smoothly and strongly (a sky
    scaled and tinted by position, dark inside the room's cavity), some probes invalid and
    moved; ``depth``: octahedral depth moments of a nearby wall in every direction."""
    from shprobe.probes.presets import get_preset

    room = room_on_ground()
    g0 = ProbeGrid(np.zeros((*res, 9, 3), np.float32), room.bounds)
    c = g0.centres()
    sky = get_preset("grace")[:9]
    f = 0.3 + (c[..., 0:1] - room.bounds[0, 0]) / 12.0  # brighter towards +X
    coeffs = sky[None, None, None] * f[..., None] * np.array([1.0, 0.8, 0.6])
    coeffs[room.inside(c)] *= 0.02
    val = np.ones(res, np.float32)
    val[0, -1, 0] = 0.0
    pos = c.copy()
    pos[0, -1, 0, 1] -= 0.3
    d = None
    if depth:
        d = np.empty((*res, 8, 8, 2), np.float32)
        d[..., 0] = 0.4
        d[..., 1] = 0.4 ** 2 + 1e-4
    return ProbeGrid(coeffs.astype(np.float32), room.bounds, positions=pos, validity=val,
                     depth=d, meta={"lighting": "grace", "bounces": 1})


def unpack(body: bytes) -> tuple[dict, dict[str, np.ndarray]]:
    """viewer.wire.pack_binary read back (as the page's unpack reads it)."""
    n = int.from_bytes(body[:4], "little")
    head = json.loads(body[4:4 + n])
    out = {}
    for k, m in head["arrays"].items():
        dt = np.dtype("<" + m["dtype"])
        count = int(np.prod(m["shape"]))
        out[k] = np.frombuffer(body, dt, count, 4 + n + m["offset"]).reshape(m["shape"])
    return head, out


class GridServed(Served):
    """The grid app of ``view`` served by uvicorn on a free port in a thread."""

    def __init__(self, view: GridView):
        super().__init__(None, grid=view, page="/grid")


@pytest.fixture(scope="module")
def grid():
    return make_grid()


@pytest.fixture(scope="module")
def served(grid):
    if not VENDOR.is_file():
        pytest.skip("three.js not vendored (run tools/vendor_js.sh)")
    s = GridServed(GridView(grid, "test.npz"))  # the object: the unit sphere
    yield s
    s.close()


@pytest.fixture
def client(served):
    with served.client() as c:
        yield c


def test_page_and_data_are_the_librarys(client, grid):
    page = client.get("/grid")
    assert page.status_code == 200 and "grid.js" in page.text
    assert "Content-Security-Policy" in page.headers
    r = client.get("/api/grid")
    assert r.status_code == 200
    head, a = unpack(r.content)
    n = 5 * 3 * 4
    assert head["probes"] == n and head["resolution"] == [5, 3, 4] and head["lmax"] == 2
    assert np.allclose(head["bounds"], grid.bounds) and not head["has_depth"]
    # probes in the flat order of the interpolation, (ix·NY + iy)·NZ + iz
    assert np.allclose(a["probe_position"], grid.probe_positions().reshape(n, 3), atol=1e-6)
    assert np.allclose(a["probe_centre"], grid.centres().reshape(n, 3), atol=1e-6)
    assert a["validity"].tolist() == grid.validity.reshape(n).tolist()
    assert head["invalid"] == 1 and head["relocated"] == 1
    # E_lm summed over the basis at a normal = the library's irradiance of that probe there
    from shprobe.sh.basis import sh_basis

    nrm = np.array([[0, 1, 0], [0.6, -0.8, 0], [0, 0, -1.0], [0.48, 0.6, 0.64]])
    y = sh_basis(nrm, 2)
    for p in (0, 17, n - 1):
        ix, rest = divmod(p, 3 * 4)
        iy, iz = divmod(rest, 4)
        want = irradiance(grid.coeffs[ix, iy, iz].astype(np.float64), nrm)
        assert np.allclose(y @ a["probe_e"][p], want, rtol=1e-5, atol=1e-6)
    # the brightest probe irradiance (the page's white): the library's maximum over a dense
    # set of normals, within 3 %
    d = np.random.default_rng(1).normal(size=(20000, 3))
    e = irradiance(grid.coeffs.reshape(n, 9, 3).astype(np.float64).transpose(1, 0, 2)
                   .reshape(9, -1), d / np.linalg.norm(d, axis=1, keepdims=True))
    assert 0.97 * e.max() <= head["brightest"] <= 1.001 * e.max()
    # the object arrives in its unit bounding sphere
    assert abs(np.linalg.norm(a["object_position"], axis=1).max() - 1.0) < 1e-5


def _shade(client, **body):
    r = client.post("/api/grid/shade", content=json.dumps(body))
    assert r.status_code == 200, r.text
    return unpack(r.content)


def test_shading_is_grid_irradiance(client, grid):
    _, a = unpack(client.get("/api/grid").content)
    local, nrm = a["object_position"].astype(np.float64), a["object_normal"].astype(np.float64)
    for pos, size in (([0.0, 2.0, 0.0], 0.5), ([-4.1, 0.7, 3.3], 1.2), ([6.0, 4.0, -6.0], 0.3)):
        head, s = _shade(client, position=pos, size=size, leak_control=False)
        want = grid.irradiance(local * size + np.array(pos), nrm, leak_control=False)
        assert s["irradiance"].shape == want.shape
        assert np.allclose(s["irradiance"], want, rtol=1e-5, atol=1e-6)
        assert np.allclose(head["mean"], want.mean(axis=0), rtol=1e-5)
        assert head["leak_control"] is False
    # the interpolation moves with the object: E differs between the room's inside and out
    inside = _shade(client, position=[0, 1.3, 0], size=0.4, leak_control=False)[1]
    outside = _shade(client, position=[4.5, 1.3, 4.5], size=0.4, leak_control=False)[1]
    assert outside["irradiance"].mean() > 3 * inside["irradiance"].mean()


def test_uniform_grid_shades_as_one_probe(tmp_path):
    """An independent check: every probe the same → the object's irradiance is that probe's,
    wherever it stands (R&H eq. 7 at the vertex normals)."""
    from shprobe.probes.presets import get_preset

    L = get_preset("stpeters")[:4]
    g = ProbeGrid(np.broadcast_to(L, (3, 2, 3, 4, 3)).astype(np.float32),
                  np.array([[0, 0, 0], [3, 2, 3.0]]))
    view = GridView(g, "uniform.npz")
    e, leak = view.shade(_placement(g, [0.4, 1.7, 2.9], 0.8))
    assert not leak
    assert np.allclose(e, np.maximum(irradiance(L.astype(np.float32).astype(np.float64),
                                                view.normals), 0), rtol=1e-5, atol=1e-6)


def _placement(grid, pos, size, leak=False):
    from shprobe.viewer.grid import parse_placement

    return parse_placement({"position": pos, "size": size, "leak_control": leak}, grid)


def test_leak_control_on_and_off_differ():
    """With depth data the toggle changes the interpolation (visibility-aware weights) and the
    answer is ProbeGrid.irradiance(leak_control=True) either way."""
    g = make_grid(depth=True)
    view = GridView(g, "depth.npz")
    pl = _placement(g, [0.3, 1.4, -0.2], 1.5)
    on, leak_on = view.shade(_placement(g, [0.3, 1.4, -0.2], 1.5, leak=True))
    off, leak_off = view.shade(pl)
    assert leak_on and not leak_off
    pts = view.local * 1.5 + np.array([0.3, 1.4, -0.2])
    assert np.allclose(on, g.irradiance(pts, view.normals, leak_control=True), atol=1e-6)
    assert np.allclose(off, g.irradiance(pts, view.normals, leak_control=False), atol=1e-6)
    assert np.max(np.abs(on - off)) > 1e-3 * np.max(off)


BAD = [
    "{not json", "[1, 2]", '"x"', "{}", '{"position": [0, 2], "size": 1}',
    '{"position": [0, 2, "a"], "size": 1}', '{"position": [0, 2, true], "size": 1}',
    '{"position": [0, 99, 0], "size": 1}', '{"position": [0, 2, 0], "size": 0}',
    '{"position": [0, 2, 0], "size": -1}', '{"position": [0, 2, 0], "size": 1e300}',
    '{"position": [0, 2, 0], "size": NaN}', '{"position": [0, 2, 1e999], "size": 1}',
    '{"position": [0, 2, 0], "size": 1, "leak_control": "yes"}',
    '{"position": [0, 2, 0], "size": 1, "file": "/etc/passwd"}',
    '{"position": [0, 2, 0], "size": 1, "x": "%s"}' % ("9" * (MAX_SHADE + 10)),
]


@pytest.mark.parametrize("body", BAD)
def test_bad_shading_requests_are_one_line(client, body):
    r = client.post("/api/grid/shade", content=body)
    # an oversized body is 413 (Payload Too Large), as on the designer page's endpoints
    want = 413 if len(body.encode()) > MAX_SHADE else 400
    assert r.status_code == want, (body[:60], r.status_code)
    msg = r.json()["error"]
    assert msg and "\n" not in msg and "Traceback" not in msg and len(msg) < 300


def test_the_token_is_needed(served):
    import httpx

    r = httpx.get(served.base + "/api/grid", timeout=30)
    assert r.status_code == 403


def test_too_many_probes_is_one_line():
    from shprobe.errors import ShprobeError

    side = int(np.ceil(MAX_VIEW_PROBES ** (1 / 3))) + 1
    g = ProbeGrid(np.zeros((side, side, side, 4, 3), np.float32),
                  np.array([[0, 0, 0], [1, 1, 1.0]]))
    with pytest.raises(ShprobeError, match="at most"):
        GridView(g, "big.npz")


def _run(*args, timeout=60):
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    return subprocess.run([sys.executable, "-m", "shprobe", "view", *args, "--no-browser"],
                          capture_output=True, text=True, timeout=timeout, env=env)


def test_bad_grid_files_are_one_line_no_url(tmp_path):
    bad = {"missing.npz": None, "corrupt.npz": b"PK\x03\x04 not a zip at all" * 10,
           "text.npz": b"hello\n"}
    other = tmp_path / "notgrid.npz"
    np.savez(other, a=np.ones(3))
    paths = [other]
    for name, data in bad.items():
        p = tmp_path / name
        if data is not None:
            p.write_bytes(data)
        paths.append(p)
    nan = make_grid()
    c = np.array(nan.coeffs)
    save_grid(tmp_path / "ok.npz", nan)
    with np.load(tmp_path / "ok.npz") as z:
        arrays = dict(z)
    c[0, 0, 0, 0, 0] = np.nan
    arrays["coeffs"] = c
    np.savez(tmp_path / "nan.npz", **arrays)
    paths.append(tmp_path / "nan.npz")
    for p in paths:
        r = _run("--grid", str(p))
        assert r.returncode != 0, p
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and p.name in lines[0], (p.name, r.stderr)
        assert "Traceback" not in r.stderr and "http" not in r.stdout + r.stderr


def test_grid_with_a_probe_is_refused(tmp_path):
    save_grid(tmp_path / "g.npz", make_grid())
    r = _run("--grid", str(tmp_path / "g.npz"), "--preset", "grace")
    assert r.returncode != 0 and "--grid" in r.stderr and "http" not in r.stdout
    assert len(r.stderr.strip().splitlines()) == 1
    r = _run("--scene", str(tmp_path / "g.npz"))
    assert r.returncode != 0 and "--scene goes with --grid" in r.stderr and "http" not in r.stdout


def test_scene_by_name(tmp_path):
    """``--scene room`` draws the reference room (no file needed)."""
    from shprobe.viewer.grid import load_grid_view

    p = tmp_path / "g.npz"
    save_grid(p, make_grid())
    view = load_grid_view(str(p), None, "room")
    want = room_on_ground().mesh()
    assert view.scene_name == "room" and len(view.scene.faces) == len(want.faces)
    np.testing.assert_array_equal(view.scene.vertices, want.vertices)
