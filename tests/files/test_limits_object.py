"""Limits are an object passed in, not an environment variable: ``Limits`` and its scope,
the workflows' ``limits`` setting, and ``--max-memory`` building one without touching the
environment. The library names the setting (max_memory), the CLI the flag."""

from __future__ import annotations

import os
import threading

import pytest
import trimesh

from shprobe.errors import ShprobeError
from shprobe.limits import Limits, active_limits, check_memory, memory_limit


def test_limits_parse_and_lower_the_limit(monkeypatch):
    monkeypatch.delenv("SHPROBE_MAX_MEMORY", raising=False)
    assert Limits.parse("2M").max_memory == 2 << 20
    assert Limits.parse(None).max_memory is None
    assert memory_limit(Limits(1000)) == 1000
    assert memory_limit(Limits(1 << 60)) == memory_limit()  # never raised past the machine
    with pytest.raises(ShprobeError, match="max_memory"):
        Limits(-1)


def test_applied_limits_hold_in_their_block_and_thread_only():
    seen = []
    with Limits(4096).applied():
        assert active_limits().max_memory == 4096
        with pytest.raises(ShprobeError, match="the max_memory limit"):
            check_memory(1e6, "a thing")
        t = threading.Thread(target=lambda: seen.append(active_limits().max_memory))
        t.start()
        t.join()
    assert seen == [None] and active_limits().max_memory is None
    check_memory(1e6, "a thing")  # outside the block: the machine's limit


def test_a_bake_refuses_over_its_settings_limits():
    from shprobe.prt import PrtSettings, bake

    m = trimesh.creation.icosphere(subdivisions=1)
    with pytest.raises(ShprobeError, match="would need about"):
        bake(m, PrtSettings(mode="shadowed", lmax=2, samples=64, limits=Limits(1 << 10)))
    assert bake(m, PrtSettings(mode="shadowed", lmax=2, samples=64)).n_vertices == 42


def test_max_memory_flag_builds_limits_and_names_the_flag(tmp_path, capsys, monkeypatch):
    from shprobe.cli.main import main

    monkeypatch.delenv("SHPROBE_MAX_MEMORY", raising=False)
    mesh = tmp_path / "s.obj"
    trimesh.creation.icosphere(subdivisions=1).export(mesh)
    rc = main(["--max-memory", "1K", "prt", "bake", str(mesh), "--lmax", "2", "--samples",
               "64", "-o", str(tmp_path / "t.npz")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1 and "--max-memory" in err[0] and "max_memory" not in err[0]
    assert "SHPROBE_MAX_MEMORY" not in os.environ and not (tmp_path / "t.npz").exists()
