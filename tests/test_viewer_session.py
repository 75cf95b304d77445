"""The viewer's Session without a browser: the forked loader's failure paths, the upload
unpacker's malformed bodies."""

from __future__ import annotations

import os
import sys

import pytest

from shprobe.errors import ShprobeError
from shprobe.viewer.session import Session

from .conftest import data_file

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
