"""Shared fixtures and helpers: where the test data lives, seeded random directions, the
scenes several test packages use (a grey ball photo, a sphere mesh) and the one check of a
one-line refusal."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session", autouse=True)
def _own_cache_dir(tmp_path_factory: pytest.TempPathFactory):
    """shprobe's on-disk cache (shprobe.files.cache_dir) in a folder of this test run (the
    commands the tests start inherit it): tests never read or fill the user's cache."""
    old = os.environ.get("SHPROBE_CACHE_DIR")
    os.environ["SHPROBE_CACHE_DIR"] = str(tmp_path_factory.mktemp("shprobe-cache"))
    yield
    if old is None:
        os.environ.pop("SHPROBE_CACHE_DIR", None)
    else:
        os.environ["SHPROBE_CACHE_DIR"] = old


def shared_dir() -> Path:
    """$SHPROBE_TEST_DATA, default ../shared beside the checkout."""
    env = os.environ.get("SHPROBE_TEST_DATA")
    return Path(env) if env else REPO.parent / "shared"


def data_file(*parts: str) -> Path:
    """Path of a shared test file, or skip the test with a clear reason."""
    p = shared_dir().joinpath(*parts)
    if not p.is_file():
        pytest.skip(f"test data {p} not found (set SHPROBE_TEST_DATA to the shared/ folder)")
    return p


@pytest.fixture
def grace_path() -> Path:
    return data_file("probes", "grace.hdr")


@pytest.fixture
def ennis_path() -> Path:
    return data_file("probes", "ennis.hdr")


@pytest.fixture
def bunny_path() -> Path:
    return data_file("meshes", "bunny.obj")


def random_dirs(n: int, seed: int = 0, dtype=np.float64) -> np.ndarray:
    """n uniformly distributed unit vectors."""
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return (v / np.linalg.norm(v, axis=1, keepdims=True)).astype(dtype)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


def write_raw_pfm(path: Path, rgb: np.ndarray) -> Path:
    """Write a little-endian colour PFM by hand (bottom row first), NaN/Inf kept as they are.

    The project's writer refuses non-finite pixels, so bad-input tests make their files here.
    """
    a = np.asarray(rgb, np.float32)
    h, w = a.shape[:2]
    Path(path).write_bytes(f"PF\n{w} {h}\n-1.0\n".encode() + a[::-1].astype("<f4").tobytes())
    return Path(path)


# ----------------------------------------------------------------------------- scenes


@pytest.fixture
def grey(tmp_path) -> Path:
    """A grey ball (albedo 0.5) under the grace preset, rendered 120×100 orthographic (margin
    1.3) on a dark background: the photo the fit commands read (grace: ``get_preset``)."""
    from shprobe.probes.images import write_image
    from shprobe.probes.presets import get_preset
    from shprobe.scene import Camera, render

    r = render(None, get_preset("grace"), Camera(120, 100, "orthographic", margin=1.3),
               albedo=0.5, background=[0.03, 0.03, 0.03])
    path = tmp_path / "grey.exr"
    write_image(path, r.image)
    return path


@pytest.fixture
def sphere_obj(tmp_path) -> Path:
    """A unit icosphere (subdivision 2, 162 vertices) written as an OBJ."""
    import trimesh

    p = tmp_path / "sphere.obj"
    trimesh.creation.icosphere(subdivisions=2).export(p)
    return p


# ----------------------------------------------------------------------------- refusals


def one_line_error(err: str, *needles: str, rc: int | None = None,
                   warnings: bool = False) -> str:
    """Check a refusal as every command prints it: stderr is exactly one line starting
    ``shprobe: error:`` that names each of ``needles``, no traceback; the exit status ``rc``
    (when given) is not 0; with ``warnings``, lines ``shprobe: warning...`` may come before the
    error. Returns that line."""
    assert rc is None or rc != 0, (rc, err)
    lines = [ln for ln in err.splitlines()
             if not (warnings and ln.startswith("shprobe: warning"))]
    assert len(lines) == 1 and lines[0].startswith("shprobe: error:"), err
    assert "Traceback" not in err, err
    for n in needles:
        assert n in lines[0], err
    return lines[0]


def fails_with_one_line(cap: pytest.CaptureFixture, args, *needles: str) -> float:
    """Run ``shprobe args`` in this process with ``cap`` (capsys, or capfd where warnings
    printed by the warnings machinery must count too): a non-zero exit and
    :func:`one_line_error`. Returns the seconds the command took."""
    from shprobe.cli.main import main

    cap.readouterr()
    t = time.monotonic()
    assert main([str(a) for a in args]) != 0
    took = time.monotonic() - t
    one_line_error(cap.readouterr().err, *needles)
    return took


def one_line_message(excinfo) -> str:
    """The message of a raised error (a ``pytest.raises`` result or the exception), checked to
    be one line."""
    msg = str(getattr(excinfo, "value", excinfo))
    assert "\n" not in msg, msg
    return msg


def pytest_runtest_setup(item: pytest.Item) -> None:
    """Peak-memory measurements run alone (``pytest -m memory``, as .ci/run does): next to
    another worker the resident peaks come out lower than the process alone reaches."""
    if item.get_closest_marker("memory") and os.environ.get("PYTEST_XDIST_WORKER"):
        pytest.skip("measures peak memory: run alone with `pytest -m memory` (.ci/run does); "
                    "beside a parallel worker the resident peaks come out low")
