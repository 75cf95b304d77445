"""The PRT bake's memory estimate (what it announces and what ``--max-memory`` trusts) against
the peak resident memory a bake reaches, each bake in a fresh subprocess
(its ``VmHWM``): the packaged bunny + ground, as ``shprobe prt bake bunny.obj --ground`` bakes
it (quick refinement of the traced modes), within 20 %, at lmax 2, 6, 10 and 16. The
interreflected bakes at lmax 10 and 16 take several minutes each: ``bench/bench_prt_memory.py``
runs them (docs/benchmarks.md has its table)."""

from __future__ import annotations

import pytest
from bench.bench_prt_memory import measure

TOLERANCE = 0.2


@pytest.mark.parametrize("lmax", [2, 6, 10, 16])
def test_unshadowed_estimate_holds(lmax):
    m = measure("unshadowed", lmax)
    assert m["estimate"] == pytest.approx(m["peak"], rel=TOLERANCE), m


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["shadowed", "interreflected"])
@pytest.mark.parametrize("lmax", [2, 6])
def test_traced_estimate_holds(mode, lmax):
    m = measure(mode, lmax)
    assert m["estimate"] == pytest.approx(m["peak"], rel=TOLERANCE), m
    # the vertex count the estimate assumes is the refinement's, within the same margin
    assert m["est_vertices"] == pytest.approx(m["vertices"], rel=TOLERANCE), m


@pytest.mark.slow
@pytest.mark.parametrize("lmax", [10, 16])
def test_shadowed_estimate_holds_at_high_degrees(lmax):
    m = measure("shadowed", lmax)
    assert m["estimate"] == pytest.approx(m["peak"], rel=TOLERANCE), m
    assert m["est_vertices"] == pytest.approx(m["vertices"], rel=TOLERANCE), m
