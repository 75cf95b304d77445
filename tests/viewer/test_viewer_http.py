"""The viewer's server refuses what it must, over real HTTP (uvicorn in a thread, as
`shprobe view` runs it): malformed edit states are one-line 400s checked once by the schema,
uploads are bounded by their declared length and streamed to a file, a broken-off upload and an
over-long URL are answered (or dropped) without a traceback, and a zip-bomb .npz is refused
before it is inflated."""

from __future__ import annotations

import io
import json
import socket
import time
import zipfile

import numpy as np
import pytest

from tests.viewer.test_viewer import VENDOR, Served

ENDPOINTS = ("/api/design", "/api/export/json", "/api/export/glsl", "/api/hbasis",
             "/api/irradiance")
BAD_STATES = [
    '{"sky": 5}', '{"sky": "blue"}', '{"rotation": [1,2,3]}', '{"scale": [1]}',
    '{"scale_band": [1]}', '{"scale_band": {"\\u00b2": 2}}', '{"%s": 1}' % ("9" * 5000),
    '{"scale": {"%s": 1}}' % ("9" * 5000), '{"scale_band": {"%s": 1}}' % ("9" * 5000),
    '{"weight": 1e308}', '{"weight": %s}' % ("9" * 5000), '{"lmax": true}',
    '{"directional": [{"dir": [0, 1, 0], "rgb": "red"}]}', '{"cone": {"dir": 1}}',
    '{"blends": [{"preset": "grace", "weight": "x"}]}', '{"window": 5}', '[1, 2]', '"x"',
    '{"scale": {"1,1": 1e300}, "weight": 1e9}', "{not json",
]


@pytest.fixture(scope="module")
def served():
    if not VENDOR.is_file():
        pytest.skip("three.js not vendored (run tools/vendor_js.sh)")
    from shprobe.viewer.session import Session

    s = Served(Session(preset="grace", mesh=None, transfer=None))
    yield s
    s.close()


@pytest.fixture
def client(served):
    with served.client() as c:
        yield c


def _raw(served, head: bytes, body: bytes = b"", wait: float = 5.0) -> bytes:
    """Send raw bytes on a fresh connection, close, and return what came back (b"" if
    nothing)."""
    with socket.create_connection(("127.0.0.1", served.port), timeout=wait) as s:
        s.sendall(head + body)
        s.shutdown(socket.SHUT_WR)
        out = b""
        try:
            while chunk := s.recv(65536):
                out += chunk
        except (TimeoutError, ConnectionResetError):
            pass
    return out


def _post_head(served, path: str, length: int, extra: str = "") -> bytes:
    return (f"POST {path}?token={served.token} HTTP/1.1\r\nHost: 127.0.0.1:{served.port}\r\n"
            f"Content-Length: {length}\r\n{extra}\r\n").encode()


@pytest.mark.parametrize("endpoint", ENDPOINTS)
def test_malformed_edit_states_are_one_line_400s(served, client, capfd, endpoint):
    for body in BAD_STATES:
        r = client.post(endpoint, content=body)
        assert r.status_code == 400, (endpoint, body[:60], r.status_code, r.text[:200])
        msg = r.json()["error"]
        assert msg and "\n" not in msg and len(msg) < 300, (body[:60], msg)
    err = capfd.readouterr().err
    assert "Traceback" not in err and "Exception" not in err, err[-2000:]
    assert client.post("/api/design", content="{}").status_code == 200  # still serving


def test_the_schema_is_the_one_check(client):
    """What the schema accepts the server computes (the design of a valid state is finite and
    equals the library's edit pipeline on the spec read the same way)."""
    from shprobe.lighting.design import edit_lighting
    from shprobe.lighting.edits import EditSpec
    from shprobe.probes.presets import get_preset

    state = {"scale": {"1,1": 2.0}, "scale_band": {"2": 0.5}, "weight": 3.0,
             "rotation": [{"axis": [0, 1, 0], "degrees": 30}, {"euler": [10, 20, 30]}]}
    r = client.post("/api/design", content=json.dumps(state))
    assert r.status_code == 200, r.text
    want = edit_lighting(get_preset("grace"), EditSpec.from_json(state)).coeffs
    np.testing.assert_allclose(r.json()["coeffs"], want, rtol=1e-12, atol=1e-12)


def test_broken_off_uploads_leave_no_traceback(served, client, capfd):
    """An upload declaring 10 GiB is refused on its header (413, before any body); one
    declaring 100 MiB that sends 1 KiB and closes is dropped: no traceback in the log, no
    file left in the upload folder, the server still serves."""
    folder = served.session.uploads._dir.name
    before = set(__import__("os").listdir(folder))
    out = _raw(served, _post_head(served, "/api/upload/probe", 10 << 30,
                                  "X-Filename: big.hdr\r\n"), b"x" * 1024)
    assert out.startswith(b"HTTP/1.1 413"), out[:200]
    assert b"limit" in out
    _raw(served, _post_head(served, "/api/upload/probe", 100 << 20,
                            "X-Filename: cut.hdr\r\n"), b"x" * 1024, wait=2)
    time.sleep(0.5)
    err = capfd.readouterr().err
    assert "Traceback" not in err and "ClientDisconnect" not in err, err[-2000:]
    assert set(__import__("os").listdir(folder)) == before
    assert client.get("/api/init").status_code == 200


def test_uploads_are_streamed_to_a_file(served):
    """The body goes to disk as it arrives (half of a 16 MiB upload sent: the file holds it),
    never held whole in memory."""
    import os

    folder = served.session.uploads._dir.name
    n = 16 << 20
    with socket.create_connection(("127.0.0.1", served.port), timeout=30) as s:
        s.sendall(_post_head(served, "/api/upload/probe", n, "X-Filename: s.hdr\r\n"))
        s.sendall(b"\0" * (n // 2))
        deadline, size = time.time() + 20, 0
        while size < n // 4 and time.time() < deadline:
            sizes = [os.path.getsize(os.path.join(folder, f)) for f in os.listdir(folder)]
            size = max(sizes, default=0)
            time.sleep(0.05)
        assert size >= n // 4
        s.sendall(b"\0" * (n - n // 2))
        resp = b""
        while b"}" not in resp and (chunk := s.recv(65536)):
            resp += chunk
    assert resp.startswith(b"HTTP/1.1 400")  # not an image: one line
    assert b"s.hdr" in resp and b"upload-" not in resp


def test_long_token_is_answered_not_reset(served):
    """GET /api/init?token=<1 MiB> is a 4xx answer, not a connection reset."""
    head = (f"GET /api/init?token={'x' * (1 << 20)} HTTP/1.1\r\n"
            f"Host: 127.0.0.1:{served.port}\r\n\r\n").encode()
    out = _raw(served, head, wait=30)
    assert out.startswith(b"HTTP/1.1 414"), out[:200]  # read whole, answered: not reset


def test_zip_bomb_transfer_is_refused_before_inflating(served, client, monkeypatch, tmp_path):
    """A small .npz whose arrays inflate past the upload's bound is refused from its headers
    (the bound lowered here so that the test's bomb is small to make)."""
    from shprobe.viewer import uploads

    monkeypatch.setattr(uploads, "MAX_INFLATED", 32 << 20)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name, a in (("vertices", np.zeros((3, 3))), ("faces", np.zeros((1, 3), int)),
                        ("transfer", np.zeros((64 << 20) // 8))):
            with z.open(name + ".npy", "w", force_zip64=True) as f:
                np.lib.format.write_array(f, a)
    data = buf.getvalue()
    assert len(data) < 1 << 20
    t = time.monotonic()
    r = client.post("/api/upload/transfer", content=data, headers={"X-Filename": "bomb.npz"})
    assert r.status_code == 400 and "bomb.npz" in r.json()["error"]
    assert "inflate" in r.json()["error"] and time.monotonic() - t < 10
    assert served.session.transfer is None
