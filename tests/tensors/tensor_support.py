"""Shared by the tensor tests: importing torch/JAX (a skip on a developer's machine without
them, a failure in CI, where both are installed), seeded data, and the functions under test."""

from __future__ import annotations

import os

import numpy as np
import pytest


def need(module: str):
    """``pytest.importorskip`` locally; in CI (CI=true) a missing module fails the test, so
    the tensor tests can never skip silently there."""
    if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
        import importlib

        return importlib.import_module(module)
    return pytest.importorskip(module)


def unit(n: int, seed: int = 0) -> np.ndarray:
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def quats(n: int, seed: int = 1) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(n, 4))


def coeffs(lmax: int, c: int = 3, batch: tuple[int, ...] = (), seed: int = 2) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(*batch, (lmax + 1) ** 2, c))
