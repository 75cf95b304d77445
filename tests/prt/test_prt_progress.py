"""What `shprobe prt bake` says: its estimate before a long bake (from the same cost model as
the memory check), one progress stage per step named "k/N: what" with a countable total, no
two stages with the same label, and a closing 'wrote …' line; the log of a bake written to a
file holds no blank lines or control codes."""

from __future__ import annotations

import subprocess
import sys

import pytest

from shprobe.cli.main import main
from shprobe.prt import QUICK, PrtSettings, estimate_bake, load_scene
from shprobe.prt.trace import bake_bytes


def test_estimate_grows_with_the_work_and_uses_the_memory_model(sphere_obj):
    sc = load_scene(str(sphere_obj), ground=True)

    def est(mode, lmax, samples, refine=False, threads=2):
        return estimate_bake(sc, PrtSettings(mode=mode, lmax=lmax, samples=samples,
                                             refine=refine, threads=threads))

    small = est("shadowed", 2, 256)
    assert small.vertices == sc.n_vertices
    more = [est("shadowed", 2, 1024), est("shadowed", 6, 1024),
            est("interreflected", 6, 1024), est("interreflected", 6, 1024, refine=QUICK)]
    times = [small.seconds] + [e.seconds for e in more]
    assert times == sorted(times) and len(set(times)) == len(times)
    assert est("shadowed", 2, 1024, threads=1).seconds == pytest.approx(2 * more[0].seconds)
    # a BakeScene is refined when asked: None is no refinement here
    assert est("interreflected", 6, 1024, refine=None) == more[2]
    e = more[2]  # unrefined: the bake's own memory model plus the process
    from shprobe.prt.baking import BASE_BYTES, TRACE_BYTES

    assert e.bytes == pytest.approx(BASE_BYTES + TRACE_BYTES
                                    + bake_bytes(sc.n_vertices, 6, 1024, 3, 1, 2))
    assert str(e).startswith("about ") and ("B" in str(e))


def test_bake_says_its_estimate_progress_and_what_it_wrote(tmp_path, sphere_obj, monkeypatch):
    """In a subprocess with stderr to a file: a plain line per long stage ("k/N: …"), no blank
    lines or control codes, the estimate first when over 30 s (the cost model scaled up so
    that a small bake reads as a long one), the 'wrote' line last."""
    out = tmp_path / "t.npz"
    code = ("import sys; import shprobe.prt.baking as b; "
            "b.COST = {k: (v[0] * 1e4, v[1]) for k, v in b.COST.items()}; "
            "from shprobe.cli.main import main; sys.exit(main(sys.argv[1:]))")
    log = tmp_path / "log.txt"
    with open(log, "w") as f:
        r = subprocess.run([sys.executable, "-c", code, "prt", "bake", str(sphere_obj),
                            "--ground", "--mode", "shadowed", "--lmax", "1",
                            "--samples", "64", "-o", str(out)],
                           stderr=f, stdout=subprocess.PIPE, text=True, timeout=600)
    text = log.read_text()
    assert r.returncode == 0, text
    lines = text.splitlines()
    assert all(line.strip() for line in lines) and "\x1b" not in text and "\r" not in text
    assert "on this machine" in lines[0] and "about" in lines[0]
    assert lines[-1].startswith(f"wrote {out}") and "shadowed transfer" in lines[-1]
    stages = lines[1:-1]  # a plain line only for a stage that lasts over a second
    assert all(ln.split(":")[0].count("/") == 1 for ln in stages), stages
    assert len(set(stages)) == len(stages)
    assert r.stdout == ""


def test_no_estimate_line_for_a_short_bake(tmp_path, sphere_obj, capsys):
    out = tmp_path / "t.npz"
    assert main(["prt", "bake", str(sphere_obj), "--mode", "shadowed", "--lmax", "1",
                 "--samples", "64", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "on this machine" not in err and err.strip().splitlines()[-1].startswith("wrote")
