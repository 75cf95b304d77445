"""The viewer's Session without a browser: the forked loader's failure paths, the upload
unpacker's malformed bodies."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import sys
import time

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.viewer.session import Session
from shprobe.viewer.wire import unpack_files
from tests.conftest import data_file

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork loader: Linux")


def _fds() -> set[str]:
    return set(os.listdir("/proc/self/fd"))


@linux
def test_forked_loader_bad_probe_with_mesh_is_cleaned_up(tmp_path):
    """A bad probe plus a mesh: load() raises one line, the loader is joined (no zombie),
    every pipe end is closed, and close() leaves no fd of the session open."""
    bad = tmp_path / "cut.hdr"
    bad.write_bytes(data_file("probes", "grace.hdr").read_bytes()[:5000])
    before = _fds()
    s = Session(str(bad), mesh=str(data_file("meshes", "bunny.obj")), load=False)
    s.fork_loader()
    child = list(s._child)
    assert len(child) == 2
    with pytest.raises(ShprobeError) as e:
        s.load()
    assert "\n" not in str(e.value) and "cut.hdr" in str(e.value)
    assert s._child is None
    for proc, recv in child:
        assert recv.closed
        with pytest.raises(ValueError):  # joined and closed: reaped, not a zombie
            proc.is_alive()
    s.close()
    assert _fds() <= before


def _fake_loader(conn, tail: str) -> None:
    """A loader whose first frame arrives and whose Env does not: garbage on the pipe (an
    unpickling error in the server) or an ("error", line) after "ready"."""
    conn.send(("source", np.ones((9, 3)), "latlong", {}))
    conn.send(("ready", {}))
    if tail == "garbage":
        conn.send_bytes(b"not a pickle")
    elif tail == "env":
        from shprobe.probes.environments import procedural_env

        time.sleep(0.2)  # the server asks for the background before the Env arrives
        conn.send(("env", procedural_env(32, 16), np.full((25, 3), 2.0), b"BG", {}))
    else:
        conn.send(("error", "x.hdr: boom"))
    conn.close()


@contextlib.contextmanager
def _fake_session(tail: str):
    """A Session whose forked loader is :func:`_fake_loader` (sending ``tail`` after the
    first frame's data), loaded; closed on exit."""
    ctx = multiprocessing.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_fake_loader, args=(send, tail), daemon=True)
    proc.start()
    send.close()
    s = Session("x.hdr", load=False)
    s._child = [(proc, recv)]
    try:
        s.load()
        yield s
    finally:
        s.close()


@linux
@pytest.mark.parametrize("tail", ["garbage", "error"])
def test_env_failure_after_first_frame_is_one_line_not_a_hang(tail):
    with _fake_session(tail) as s:
        src = s.source
        assert src._arrived.wait(30)  # the Env's wait ends
        assert np.array_equal(s.base(2), np.ones((9, 3)))  # the first frame's data stands
        for f in (lambda: src.env, lambda: src.coeffs, lambda: src.coeffs_at(3),
                  lambda: s.base(3), s.background_bytes):
            with pytest.raises(ShprobeError) as e:
                f()
            msg = str(e.value)
            assert "\n" not in msg and msg.startswith("x.hdr: ")
            assert ("boom" in msg) if tail == "error" else ("Unpickling" in msg)


def _body(header: bytes, payload: bytes = b"") -> bytes:
    return len(header).to_bytes(4, "little") + header + payload


def _unpack(body: bytes) -> list[tuple[str, bytes]]:
    import io

    return [(n, body[o: o + k]) for n, o, k in unpack_files(io.BytesIO(body), len(body))]


def test_unpack_files_malformed_is_one_line():
    assert _unpack(_body(b'{"files": [{"name": "a.hdr", "size": 2}]}', b"xy")) == \
        [("a.hdr", b"xy")]
    for head in (b'{"files": [{"name": "a", "size": 1e999}]}',  # int(inf): OverflowError
                 b'{"files": [{"name": "a", "size": NaN}]}', b'{"files": [{"name": "a"}]}',
                 b'{"files": [{"name": "a", "size": [1]}]}', b'{"files": 3}', b"\xff\xfe",
                 b'{"files": [{"name": "a", "size": 5}]}'):
        with pytest.raises(ShprobeError, match=r"^malformed multi-file upload$"):
            _unpack(_body(head, b"xy"))


def test_probe_coeffs_every_degree_equals_projection():
    """A registered probe blended at any degree is the probe projected to exactly that degree
    (R&H eq. 10), as `shprobe edit --blend FILE:W` projects it."""
    from shprobe.lighting.projection import project
    from shprobe.probes.environments import procedural_env
    from shprobe.viewer.source import env_source

    s = Session(preset="grace", load=False)
    try:
        env = procedural_env(32, 16)
        pid = s.register_probe(env_source(env, "sky"), "dir/sky.hdr")
        assert s.probe_list() == [{"id": pid, "name": "sky.hdr"}]
        assert s.probe_names() == {pid: "dir/sky.hdr"}
        for lmax in range(6):
            c = s.probe_coeffs(pid, lmax)
            assert c.shape == ((lmax + 1) ** 2, 3)
            np.testing.assert_allclose(c, project(env, lmax), rtol=1e-12, atol=1e-12)
        with pytest.raises(ShprobeError):
            s.probe_coeffs(pid[:-1] + "9", 2)
    finally:
        s.close()


@linux
def test_background_comes_from_the_loader_not_recomputed():
    """background_bytes waits for the pending Env and serves the loader's texture."""
    with _fake_session("env") as s:
        assert s.background_bytes() == b"BG"
        assert np.array_equal(s.source.coeffs, np.full((25, 3), 2.0))


@linux
def test_env_is_sent_when_a_view_asks_for_it(monkeypatch):
    """A real forked loader: after the first frame's data (lmax-2 coefficients, mesh) the
    decoded probe waits in the loader until a view needs it, then arrives equal to the
    library's own decode and projection."""
    from shprobe.lighting.projection import project
    from shprobe.probes.env import load_env
    from shprobe.viewer import loader

    monkeypatch.setattr(loader, "ENV_WAIT", 120.0)  # read by the forked process
    probe = data_file("probes", "grace.hdr")
    s = Session(str(probe), mesh=str(data_file("meshes", "bunny.obj")), load=False)
    try:
        s.fork_loader()
        s.load()
        src = s.source
        assert s.mesh_bytes()  # the first frame's data is here ...
        time.sleep(0.5)
        assert not src._arrived.is_set()  # ... and the Env is not, unasked
        t = time.monotonic()
        env = src.env  # asks for it: here at once, not after ENV_WAIT
        assert time.monotonic() - t < 30
        want = load_env(probe)
        assert np.array_equal(env.radiance, want.radiance)
        np.testing.assert_allclose(src.coeffs, project(want, 4), rtol=0, atol=1e-12)
        assert s.background_bytes()
    finally:
        s.close()


def test_blend_only_probes_keep_coefficients_not_images():
    """Probes that are only blend sources (uploaded, then replaced as the source) drop their
    decoded image but keep their coefficients at every design degree, equal to the
    projections of the image they had; the current source and the latest upload keep theirs."""
    from shprobe.lighting.projection import project
    from shprobe.probes.environments import procedural_env
    from shprobe.viewer.design import DESIGN_LMAX
    from shprobe.viewer.source import Source

    s = Session(None, load=False)
    try:
        envs = [procedural_env(32 + 8 * i, 16 + 4 * i) for i in range(3)]
        srcs = [Source(f"p{i}", project(e, 2), e) for i, e in enumerate(envs)]
        for i, src in enumerate(srcs):
            s.register_probe(src, f"p{i}")
            s.source = src
        deadline = time.time() + 30
        while srcs[0]._env is not None or srcs[1]._env is not None:
            assert time.time() < deadline
            time.sleep(0.01)
        assert srcs[2].env is envs[2]
        blend = Source("blend", project(envs[0], 2), envs[0])  # the latest upload, blend only
        s.register_probe(blend, "blend")
        time.sleep(0.2)
        assert blend._env is envs[0] and srcs[2]._env is envs[2]  # kept: latest and source
        for src, env in zip(srcs[:2], envs[:2], strict=True):
            assert src.background is None
            for lmax in range(DESIGN_LMAX + 1):
                np.testing.assert_allclose(src.coeffs_at(lmax), project(env, lmax), rtol=0,
                                           atol=1e-12)
    finally:
        s.close()


@linux
def test_stopping_the_loader_ends_the_mesh_process_at_once(monkeypatch, tmp_path):
    """Closing a session while the loader's mesh process is still reading (here: a reader
    that takes a minute) ends that process too, at once: terminate() reaches it through the
    loader, and the join does not wait for it."""
    import psutil

    import shprobe.scene

    monkeypatch.setenv("SHPROBE_CACHE_DIR", str(tmp_path / "empty"))  # the mesh is read

    def slow(path):  # what the forked mesh process runs
        time.sleep(60)

    monkeypatch.setattr(shprobe.scene, "load_mesh", slow)
    s = Session(str(data_file("probes", "grace.hdr")),
                mesh=str(data_file("meshes", "bunny.obj")), load=False)
    s.fork_loader()
    loader = s._child[0][0]
    kids = []
    deadline = time.time() + 10
    while not kids and time.time() < deadline:
        kids = psutil.Process(loader.pid).children()
        time.sleep(0.01)
    assert kids, "no mesh process"
    time.sleep(0.5)  # inside the slow read
    t = time.monotonic()
    s.close()
    assert time.monotonic() - t < 2
    _, alive = psutil.wait_procs(kids, timeout=2)
    assert not alive


@linux
def test_killing_the_loader_around_the_env_signal_leaves_no_hang(monkeypatch):
    """The loader can be killed at any moment — inside its wait for the Env signal, or just
    after the server gave it (a multiprocessing.Event then stays locked by the dead process
    and every later set() hangs: the viewer's request threads would block forever). Killed
    with SIGKILL right after the signal, and closed while waiting, later signals return."""
    import signal
    import threading

    from shprobe.viewer import loader

    monkeypatch.setattr(loader, "ENV_WAIT", 120.0)
    probe = str(data_file("probes", "grace.hdr"))
    for delay, signal_first in ((0.5, False), (0.0, True), (0.2, True), (0.5, None)):
        s = Session(probe, load=False)
        s.fork_loader()
        go, proc = s._go, s._child[0][0]
        s.load()  # the lmax-2 coefficients are in: the loader is at (or inside) its wait
        time.sleep(delay)
        if signal_first is not None:  # killed inside the wait, or right after the signal
            if signal_first:
                go.set()
            os.kill(proc.pid, signal.SIGKILL)
            proc.join(5)
        th = [threading.Thread(target=go.set, daemon=True) for _ in range(3)]
        for t in th:
            t.start()
        th.append(threading.Thread(target=s.close, daemon=True))  # signals the loader too
        th[-1].start()
        for t in th:
            t.join(5)
        assert not any(t.is_alive() for t in th), (delay, signal_first)
        t = threading.Thread(target=go.set, daemon=True)  # and after close
        t.start()
        t.join(5)
        assert not t.is_alive()
