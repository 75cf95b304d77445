"""shprobe's on-disk cache (shprobe.files) and the viewer's cached mesh payload: entries are
checked, damaged ones ignored, the least recently used pruned; a cached payload equals the
one made from the file by trimesh, follows the file's content, and a hit needs no trimesh."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.files import cache_dir, file_digest, read_cache, write_cache


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    d = tmp_path / "cache"
    monkeypatch.setenv("SHPROBE_CACHE_DIR", str(d))
    return d


def test_cache_round_trip_damage_off_and_unwritable(cache, tmp_path, monkeypatch):
    assert cache_dir() == cache
    assert read_cache("k", "abc") is None
    assert write_cache("k", "abc", b"payload")
    assert read_cache("k", "abc") == b"payload"
    entry = cache / "k" / "abc.bin"
    raw = entry.read_bytes()
    entry.write_bytes(raw[:3] + bytes([raw[3] ^ 1]) + raw[4:])  # one bit flipped
    assert read_cache("k", "abc") is None
    entry.write_bytes(raw[:-5])  # cut
    assert read_cache("k", "abc") is None
    entry.write_bytes(b"")
    assert read_cache("k", "abc") is None
    assert read_cache("k", "../x") is None and not write_cache("../k", "abc", b"x")
    monkeypatch.setenv("SHPROBE_CACHE_DIR", "off")
    assert cache_dir() is None and not write_cache("k", "abc", b"x")
    blocked = tmp_path / "blocked"
    blocked.write_text("a file where the folder would be")
    monkeypatch.setenv("SHPROBE_CACHE_DIR", str(blocked))
    assert not write_cache("k", "abc", b"x") and read_cache("k", "abc") is None


def test_cache_keeps_the_most_recently_used(cache):
    for i, key in enumerate(["a1", "b2", "c3"]):
        assert write_cache("k", key, key.encode(), keep=3)
        os.utime(cache / "k" / f"{key}.bin", ns=(10**18 + i * 10**9,) * 2)
    assert read_cache("k", "a1") == b"a1"  # used: now the newest
    assert write_cache("k", "d4", b"d4", keep=3)
    assert sorted(p.stem for p in (cache / "k").glob("*.bin")) == ["a1", "c3", "d4"]


def test_file_digest_follows_content_not_name(tmp_path):
    a, b, c = tmp_path / "a.obj", tmp_path / "b.obj", tmp_path / "c.obj"
    a.write_bytes(b"v 0 0 0\n")
    b.write_bytes(b"v 0 0 0\n")
    c.write_bytes(b"v 0 0 1\n")
    assert file_digest(a) == file_digest(b) != file_digest(c)
    assert file_digest(a, "x") != file_digest(a, "y")


def _direct(path: Path, name: str) -> bytes:
    from shprobe.scene import load_mesh
    from shprobe.viewer.payloads import mesh_payload

    return mesh_payload(load_mesh(path), name)


def test_cached_mesh_payload_equals_trimesh_and_needs_no_trimesh(bunny_path, cache, tmp_path):
    from shprobe.viewer.payloads import cached_mesh_payload

    want = _direct(bunny_path, "bunny.obj")
    assert cached_mesh_payload(str(bunny_path), "bunny.obj") == want  # made, and stored
    assert len(list((cache / "viewer_mesh").glob("*.bin"))) == 1
    # a new process (as `shprobe view`'s mesh loader): the bytes come from the cache alone
    code = ("import sys, hashlib; from shprobe.viewer.payloads import cached_mesh_payload; "
            f"d = cached_mesh_payload({str(bunny_path)!r}, 'bunny.obj'); "
            "print('trimesh' in sys.modules, hashlib.sha256(d).hexdigest())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=dict(os.environ), check=True).stdout.split()
    assert out == ["False", hashlib.sha256(want).hexdigest()]
    # the same file under another name is another payload (the name is in it)
    assert cached_mesh_payload(str(bunny_path), "other.obj") == _direct(bunny_path, "other.obj")


def test_cached_mesh_payload_follows_the_file_and_survives_damage(bunny_path, cache, tmp_path):
    from shprobe.viewer.payloads import cached_mesh_payload

    p = tmp_path / "m.obj"
    text = bunny_path.read_text()
    p.write_text(text)
    first = cached_mesh_payload(str(p), "m.obj")
    st = p.stat()
    # moved vertices, same size and time stamps: the content decides
    lines = text.splitlines()
    i = next(k for k, s in enumerate(lines) if s.startswith("v "))
    x = lines[i].split()
    lines[i] = " ".join([x[0], x[2], x[1], x[3]])  # swap two coordinates of one vertex
    p.write_text("\n".join(lines) + ("\n" if text.endswith("\n") else ""))
    os.utime(p, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert p.stat().st_size == st.st_size
    second = cached_mesh_payload(str(p), "m.obj")
    assert second != first and second == _direct(p, "m.obj")
    for e in (cache / "viewer_mesh").glob("*.bin"):  # damaged entries are made again
        e.write_bytes(e.read_bytes()[:100])
    assert cached_mesh_payload(str(p), "m.obj") == second
    bad = tmp_path / "bad.obj"
    bad.write_text("this is not a mesh\n")
    n = len(list((cache / "viewer_mesh").glob("*.bin")))
    for _ in range(2):  # refused each time, never cached
        with pytest.raises(ShprobeError, match=r"bad\.obj"):
            cached_mesh_payload(str(bad), "bad.obj")
    assert len(list((cache / "viewer_mesh").glob("*.bin"))) == n


def test_viewer_loader_sends_the_same_mesh_cached_or_not(bunny_path, grace_path, cache):
    """`shprobe view`'s forked loader: the first start reads the mesh with trimesh (and fills
    the cache), the next sends the cached arrays from the loader itself; the page gets the
    same bytes, and the probe's coefficients, either way."""
    from shprobe.viewer.session import Session

    want = _direct(bunny_path, "bunny.obj")
    got = []
    for _ in range(2):
        s = Session(str(grace_path), mesh=str(bunny_path), load=False)
        try:
            s.fork_loader()
            assert s._child is not None
            t = threading.Thread(target=s.load, daemon=True)  # a deadlock fails, not hangs
            t.start()
            t.join(60)
            assert not t.is_alive(), "the loader's pipes deadlocked"
            got.append((s.mesh_bytes(), np.array(s.source.coeffs2)))
        finally:
            s.close()
    assert len(list((cache / "viewer_mesh").glob("*.bin"))) == 1
    assert got[0][0] == want and got[1][0] == want
    np.testing.assert_array_equal(got[0][1], got[1][1])
