"""What the viewer's servers refuse in one line (a 4xx with ``{"error": ...}``, or the command's
one-line error before any URL): an edit state's numbers given as JSON text on every endpoint
that reads one, a non-ASCII digit as the PRT bounce count, and grid files the grid page cannot
draw (a depth array of the wrong shape, a non-numeric ``normal_bias``, bounds or coefficients
beyond what the page's 32-bit floats hold) — never an HTTP 500 or a NaN sent to the page."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.grids import ProbeGrid, save_grid
from shprobe.viewer.grid import GridView
from shprobe.viewer.wire import pack_binary
from tests.viewer.test_viewer import VENDOR, Served
from tests.viewer.test_viewer_grid import SRC, make_grid
from tests.viewer.test_viewer_http import ENDPOINTS


@pytest.fixture(scope="module")
def served():
    if not VENDOR.is_file():
        pytest.skip("three.js not vendored (run tools/vendor_js.sh)")
    from shprobe.viewer.session import Session

    s = Served(Session(preset="grace", mesh=None, transfer=None))
    yield s
    s.close()


@pytest.mark.parametrize("state", ['{"lmax": "2"}', '{"weight": "1"}',
                                   '{"scale_band": {"1": "0.5"}}',
                                   '{"rotation": {"axis": [0, "1", 0], "degrees": 30}}'])
def test_text_for_a_number_is_refused_on_every_endpoint(served, state):
    with served.client() as c:
        for ep in (*ENDPOINTS, "/api/snippet"):
            r = c.post(ep, content=state)
            assert r.status_code == 400, (ep, state, r.status_code)
            msg = r.json()["error"]
            print(ep, "->", msg)
            assert "\n" not in msg and "must be a JSON number" in msg


def test_the_same_state_with_numbers_is_served(served):
    with served.client() as c:
        assert c.post("/api/design", content='{"lmax": 2, "scale_band": {"1": 0.5}}'
                      ).status_code == 200


@pytest.mark.parametrize("q", [{"bounces": "①"}, {"bounces": "٣"}, {"bounces": "-1"},
                               {"bounces": "1e3"}, {"mode": "x" * 300}])
def test_transfer_query_refused_in_one_line(served, q):
    with served.client() as c:
        r = c.get("/api/transfer", params={**q, "token": served.token})
    assert r.status_code == 400, (q, r.status_code, r.text[:200])
    msg = r.json()["error"]
    print(q, "->", msg)
    assert "transfer" not in msg  # refused for the query, before any transfer is looked at


def _bad_grids() -> dict[str, ProbeGrid]:
    g = make_grid(depth=True)
    big = np.array([[-1e308, -1e308, -1e308], [1e308, 1e308, 1e308]])
    return {
        "depth of the wrong shape": replace(g, depth=np.ones((*g.resolution, 4, 5),
                                                            np.float32)),
        "depth without its moments": replace(g, depth=np.ones((*g.resolution, 8, 8, 1),
                                                             np.float32)),
        "normal_bias as text": replace(g, meta={**g.meta, "normal_bias": "abc"}),
        "normal_bias out of range": replace(g, meta={**g.meta, "normal_bias": 7}),
        "bounds of ±1e308": replace(g, bounds=big, positions=None),
        "coefficients of 3e38": replace(g, coeffs=np.full(g.coeffs.shape, 3e38, np.float32)),
    }


@pytest.mark.parametrize("name", list(_bad_grids()))
def test_grid_the_page_cannot_draw_is_one_line(name):
    with pytest.raises(ShprobeError) as e:
        GridView(_bad_grids()[name], "g.npz")
    msg = str(e.value)
    print(name, "->", msg)
    assert "\n" not in msg and "g.npz" in msg


def test_view_grid_of_a_bad_file_exits_in_one_line(tmp_path):
    g = make_grid(depth=True)
    path = save_grid(tmp_path / "g.npz", replace(g, meta={**g.meta, "normal_bias": "abc"}))
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    r = subprocess.run([sys.executable, "-m", "shprobe", "view", "--grid", str(path),
                        "--no-browser"], capture_output=True, text=True,
                       timeout=120, env=env)
    print(r.stderr)
    assert r.returncode != 0 and "http" not in r.stdout
    assert len(r.stderr.strip().splitlines()) == 1 and "normal_bias" in r.stderr


def test_pack_binary_never_sends_a_non_finite_number():
    with pytest.raises(ShprobeError):
        pack_binary({"x": float("inf")}, {})
    with pytest.raises(ShprobeError):
        pack_binary({}, {"e": np.array([1e39])})  # ∞ once a 32-bit float
    with pytest.raises(ShprobeError):
        pack_binary({}, {"e": np.array([np.nan], np.float32)})
    assert pack_binary({"x": 1.0}, {"e": np.array([3e38])})


@pytest.mark.parametrize("version", ['"abc"', "1e400", "NaN", "null", "[1]", "{}"])
def test_grid_meta_of_the_wrong_type_is_one_line(tmp_path, version):
    """``view --grid`` of a grid whose meta.version is text, ∞, NaN, null, a list or an
    object (and a meta nested 5,000 deep): one line naming the file, whatever the reader
    makes of it."""
    import json

    from shprobe.viewer.grid import load_grid_view

    g = make_grid(depth=True)
    path = save_grid(tmp_path / "g.npz", g)
    d = dict(np.load(path))
    meta = json.loads(d["meta"].astype(np.uint8).tobytes())
    text = json.dumps(meta).replace(f'"version": {json.dumps(meta["version"])}',
                                    f'"version": {version}')
    d["meta"] = np.frombuffer(text.encode(), np.uint8)
    np.savez(tmp_path / "bad.npz", **d)
    with pytest.raises(ShprobeError) as e:
        load_grid_view(str(tmp_path / "bad.npz"))
    print(version, "->", e.value)
    assert "\n" not in str(e.value) and "bad.npz" in str(e.value)


def test_grid_meta_nested_deep_is_one_line(tmp_path):
    from shprobe.viewer.grid import load_grid_view

    g = make_grid()
    path = save_grid(tmp_path / "g.npz", g)
    d = dict(np.load(path))
    text = d["meta"].astype(np.uint8).tobytes().decode()
    text = text[:-1] + ', "deep": ' + "[" * 5000 + "]" * 5000 + "}"
    d["meta"] = np.frombuffer(text.encode(), np.uint8)
    np.savez(tmp_path / "deep.npz", **d)
    with pytest.raises(ShprobeError) as e:
        load_grid_view(str(tmp_path / "deep.npz"))
    print("deep ->", e.value)
    assert "\n" not in str(e.value) and "deep.npz" in str(e.value)
