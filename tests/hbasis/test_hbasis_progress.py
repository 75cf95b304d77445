"""`hbasis render` reports its three stages in order, and the brute-force reference counts its
normal–pixel pairs (so the terminal can show an ETA)."""

from __future__ import annotations

import numpy as np
import trimesh

from shprobe.hbasis.rendering import render_normal_mapped
from shprobe.probes.env import env_from_function
from shprobe.progress import Recorder, numbered


def test_render_reports_numbered_stages_and_counts_reference_pairs():
    env = env_from_function(lambda d: np.stack([1 + d[..., 1], 1 + 0 * d[..., 0],
                                                2 - d[..., 2]], -1), "latlong", 16)
    rec = Recorder()
    res = render_normal_mapped(trimesh.creation.icosphere(2), env, size=24, progress=rec)
    begins = [e for e in rec.events if e[0] == "begin"]
    assert [b[1].split(":")[0] for b in begins] == ["1/3", "2/3", "3/3"]
    assert "brute force" in begins[2][1]
    hits = int(res.mask.sum())
    total = hits * int(np.prod(env.grid))
    assert begins[2][2] == total
    updates = [e[1] for e in rec.events if e[0] == "update"]
    assert updates[-1] == total and updates == sorted(updates)
    assert sum(e[0] == "end" for e in rec.events) == 3


def test_numbered_passes_none_and_prefixes_labels():
    assert numbered(None, 1, 2) is None
    rec = Recorder()
    p = numbered(rec, 2, 5)
    p.begin("x", 10)
    p.update(3)
    p.end()
    assert rec.events == [("begin", "2/5: x", 10), ("update", 3, None), ("end", None, None)]
