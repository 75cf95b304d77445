"""Shared by the tensor tests: importing torch/JAX (a skip on a developer's machine without
them, a failure in CI, where both are installed), seeded data, and the functions under test."""

from __future__ import annotations

import os

import numpy as np
import pytest

#: the extra that brings each optional module (the skip's reason names it)
EXTRAS = {"torch": "torch", "jax": "jax", "array_api_compat": "torch] or [jax",
          "e3nn": "dev", "e3nn.o3": "dev"}


def in_ci() -> bool:
    """CI is set (to anything but 0 / false / no): the tensor libraries must be there."""
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def need(module: str):
    """The module, or a skip whose reason names the extra that brings it (the lighter install
    without torch/JAX, docs/install.md); in CI (``CI`` set) a missing module fails the test
    instead, so the tensor tests can never skip silently there."""
    import importlib

    if in_ci():
        return importlib.import_module(module)
    try:
        return importlib.import_module(module)
    except ImportError:
        extra = EXTRAS.get(module, module.split(".")[0])
        pytest.skip(f"{module} is not installed (pip install -e '.[{extra}]'); outside CI the "
                    "tests that need it skip, in CI (CI set) they fail")


def unit(n: int, seed: int = 0) -> np.ndarray:
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def quats(n: int, seed: int = 1) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(n, 4))


def coeffs(lmax: int, c: int = 3, batch: tuple[int, ...] = (), seed: int = 2) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(*batch, (lmax + 1) ** 2, c))
