"""The viewer's committed three.js bundle: what tools/js/vendor.sha256 records, shipped with
its licence, and — where npm exists — rebuilt from the pinned lock byte for byte."""

from __future__ import annotations

import hashlib
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
VENDOR = REPO / "src" / "shprobe" / "viewer" / "static" / "vendor"
SUMS = REPO / "tools" / "js" / "vendor.sha256"


def recorded() -> dict[str, str]:
    out = {}
    for line in SUMS.read_text(encoding="utf-8").splitlines():
        digest, name = line.split(maxsplit=1)
        out[name] = digest
    return out


def test_the_committed_bundle_matches_its_recorded_sha256():
    files = {p.relative_to(VENDOR).as_posix() for p in VENDOR.rglob("*") if p.is_file()}
    sums = recorded()
    assert files == set(sums), "vendor/ and tools/js/vendor.sha256 list different files"
    for name, digest in sums.items():
        assert hashlib.sha256((VENDOR / name).read_bytes()).hexdigest() == digest, name


def test_the_bundle_carries_its_licence_and_versions():
    licence = (VENDOR / "three" / "LICENSE").read_text(encoding="utf-8")
    assert "MIT" in licence and "three.js authors" in licence
    versions = (VENDOR / "VERSIONS").read_text(encoding="utf-8")
    lock = (REPO / "tools" / "js" / "package-lock.json").read_text(encoding="utf-8")
    three = versions.split()[1]
    assert f'"node_modules/three": {{\n      "version": "{three}"' in lock
    # an ES module exporting what the page imports
    head = (VENDOR / "three" / "three.min.js").read_bytes()
    assert b"WebGLRenderer" in head and b"export{" in head


@pytest.mark.skipif(shutil.which("npm") is None or shutil.which("node") is None,
                    reason="npm/node not installed (apt install nodejs npm): the rebuild check "
                           "needs them")
@pytest.mark.node
def test_rebuilding_the_bundle_from_the_lock_reproduces_it_byte_for_byte():
    r = subprocess.run([str(REPO / "tools" / "vendor_js.sh"), "--check"], capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "byte for byte" in r.stdout
