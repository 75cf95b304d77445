"""Memory limits that hold: every bake, export and splat write estimates its peak within 20 %
(bench/bench_estimates.py, each case in a fresh process), and refuses before work under a
limit below its estimate."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from shprobe.cli.main import main

BENCH = Path(__file__).resolve().parents[2] / "bench" / "bench_estimates.py"


@pytest.mark.slow
@pytest.mark.memory
def test_estimates_are_within_20_percent_of_measured_peaks():
    """Every case within 20 % of its measured peak. On a machine that reclaims idle memory
    while other jobs run (the suite's other worker), a resident peak can only come out low:
    a case out of tolerance is measured again, twice at most, and its highest peak kept."""

    def table(cases: str | None = None) -> dict[str, tuple[float, float]]:
        argv = [sys.executable, str(BENCH), "--scale", "small", "--tolerance", "0.2"]
        r = subprocess.run(argv + (["--cases", cases] if cases else []), capture_output=True,
                           text=True, timeout=1200)
        print(r.stdout, r.stderr)
        rows = {}
        for line in r.stdout.splitlines():
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if len(cells) == 5 and cells[4] in ("ok", "OUT"):
                rows[cells[0]] = (float(cells[1]), float(cells[2]))
        return rows

    rows = table()
    assert len(rows) == 15, rows

    def out() -> list[str]:
        return [k for k, (est, peak) in rows.items() if abs(est / peak - 1) > 0.2]

    for _ in range(2):
        if not out():
            break
        for k, (est, peak) in table(",".join(out())).items():
            rows[k] = (est, max(peak, rows[k][1]))
    assert not out(), {k: rows[k] for k in out()}


def _grid(tmp_path, res):
    from shprobe.grids import ProbeGrid, save_grid

    g = ProbeGrid(coeffs=np.ones((*res, 9, 3), np.float32),
                  bounds=np.array([[-1.0, -1, -1], [1, 1, 1]]))
    return save_grid(tmp_path / "g.npz", g)


@pytest.mark.parametrize("argv,phrase", [
    (["grid", "bake", "room", "--preset", "grace", "--resolution", "40,16,40", "--samples",
      "4096", "--bounces", "0"], "4096 rays per probe would need about"),
    (["grid", "export", "{grid}", "--format", "godot"], "the godot export would need about"),
])
def test_estimates_refuse_before_work(argv, phrase, tmp_path, capfd):
    grid = _grid(tmp_path, (64, 32, 64))
    argv = [a.replace("{grid}", str(grid)) for a in argv]
    out = tmp_path / "out.npz"
    rc = main(["--max-memory", "300M", *argv, "-o", str(out)])
    err = [ln for ln in capfd.readouterr().err.splitlines() if ln.strip()]
    print(rc, err)
    assert rc == 1 and len(err) == 1 and phrase in err[0] and "over the limit" in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("suffix", [".spz", ".glb"])
def test_splat_writes_refuse_before_work(suffix, tmp_path, monkeypatch):
    import shprobe.splats as sp
    from shprobe.errors import ShprobeError
    from tests.splats import splat_reference as ref

    r = ref.random_splats(200_000, 3, seed=1)
    s = sp.Splats(r["pos"], r["log_scales"], r["rot"], r["opacity"], r["sh"])
    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "100M")
    out = tmp_path / f"o{suffix}"
    with pytest.raises(ShprobeError, match="writing 200000 splats would need about") as e:
        sp.write(out, s)
    print(e.value)
    assert str(out) in str(e.value) and not out.exists()
