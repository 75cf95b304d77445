"""The tensor tests' rule for a missing torch/JAX: a skip naming the extra on a developer's
machine (the lighter install of docs/install.md), a failure in CI, where both are installed."""

from __future__ import annotations

import pytest

from tests.tensors import tensor_support
from tests.tensors.tensor_support import need

MISSING = "shprobe_no_such_tensor_library"


def test_missing_library_skips_with_its_extra_outside_ci(monkeypatch):
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setitem(tensor_support.EXTRAS, MISSING, "torch")
    with pytest.raises(pytest.skip.Exception,
                       match=r"is not installed \(pip install -e '\.\[torch\]'\)"):
        need(MISSING)


@pytest.mark.parametrize("value", ["true", "1", "yes", "github-actions"])
def test_missing_library_fails_in_ci(monkeypatch, value):
    monkeypatch.setenv("CI", value)
    with pytest.raises(ImportError):
        need(MISSING)


@pytest.mark.parametrize("value", ["", "0", "false"])
def test_ci_off_values_skip(monkeypatch, value):
    monkeypatch.setenv("CI", value)
    with pytest.raises(pytest.skip.Exception, match=MISSING):
        need(MISSING)
