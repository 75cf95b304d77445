"""Shared fixtures: where the test data lives, and seeded random directions."""

from __future__ import annotations

import os
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
