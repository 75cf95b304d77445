"""A command's outputs are committed together or not at all (shprobe.files.transaction); the
temporary files of writers killed outright are removed by the next write to their folder;
what `render` writes, `fit` reads (no negative radiance)."""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from shprobe.cli.main import main
from shprobe.errors import ShprobeError
from shprobe.files import atomic_output, remove_stale_temporaries, transaction, write_text
from shprobe.lighting.export import export_coeffs
from shprobe.probes.images import read_image


def _leftovers(folder) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if ".shprobe-" in p.name)


def test_fit_outputs_all_or_none(tmp_path, grey, capsys, monkeypatch):
    """The last output fails (a full disk while the report is written): the residual and
    fitted images written before it do not stay."""
    import shprobe.fitting.report as fit_report

    def full_disk(path, *args, overwrite=False, **kw):
        with atomic_output(path, overwrite) as tmp:
            tmp.write_bytes(b"\x89PNG partial")
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(fit_report, "save_fit_figure", full_disk)
    out = tmp_path / "out"
    res, fit, rep = out / "R.exr", out / "F.exr", out / "small" / "rep.png"
    rc = main(["fit", "grey-ball", str(grey), "--residual", str(res), "--fitted", str(fit),
               "--report", str(rep), "-F", "json", "-o", str(out / "c.json")])
    err = capsys.readouterr().err
    assert rc == 1
    assert [x for x in err.splitlines() if x.strip()] == [
        f"shprobe: error: {rep}: cannot write: No space left on device"]
    assert not res.exists() and not fit.exists() and not (out / "c.json").exists()
    assert _leftovers(tmp_path) == []
    monkeypatch.undo()  # the same command with room on the disk writes all four
    rc = main(["fit", "grey-ball", str(grey), "--residual", str(res), "--fitted", str(fit),
               "--report", str(rep), "-F", "json", "-o", str(out / "c.json")])
    assert rc == 0, capsys.readouterr().err
    assert all(p.stat().st_size > 0 for p in (res, fit, rep, out / "c.json"))


def test_transaction_rolls_back_and_restores(tmp_path):
    old = tmp_path / "old.txt"
    old.write_text("before")
    with pytest.raises(ShprobeError, match="already exists"):
        with transaction():
            write_text(old, "after", overwrite=True)  # would replace ...
            write_text(tmp_path / "new.txt", "new")
            later = tmp_path / "later.txt"
            write_text(later, "x")
            later.with_name("later.txt").write_text("someone else")  # ... appears meanwhile
    # nothing of the transaction stays and the replaced file is as it was
    assert old.read_text() == "before" and not (tmp_path / "new.txt").exists()
    assert (tmp_path / "later.txt").read_text() == "someone else"
    assert _leftovers(tmp_path) == []
    with transaction():
        write_text(old, "after", overwrite=True)
        write_text(tmp_path / "new.txt", "new")
        assert old.read_text() == "before" and not (tmp_path / "new.txt").exists()
    assert old.read_text() == "after" and (tmp_path / "new.txt").read_text() == "new"
    with pytest.raises(KeyboardInterrupt), transaction():
        write_text(tmp_path / "a.txt", "a")
        raise KeyboardInterrupt
    assert not (tmp_path / "a.txt").exists() and _leftovers(tmp_path) == []


_KILLED = """
import sys, time
from shprobe.files import atomic_output
with atomic_output(sys.argv[1]) as tmp:
    with open(tmp, "wb") as f:
        f.write(b"x" * (1 << 20))
        f.flush()
        print(tmp.name, flush=True)
        time.sleep(600)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals, PIDs")
def test_stale_temporaries_of_killed_writers_are_removed(tmp_path):
    target = tmp_path / "big.exr"
    proc = subprocess.Popen([sys.executable, "-c", _KILLED, str(target)],
                            stdout=subprocess.PIPE, text=True)
    try:
        name = proc.stdout.readline().strip()
        assert name.startswith(f".shprobe-{proc.pid}-")
        assert remove_stale_temporaries(tmp_path, min_age=0) == []  # alive: kept
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    stale = tmp_path / name
    assert stale.exists() and not target.exists()  # SIGKILL runs no clean-up
    mine = tmp_path / ".shprobe-notes.tmp"  # not a name shprobe makes: never touched
    mine.write_text("keep")
    other = tmp_path / f".shprobe-{proc.pid}-0123abcd.tmp.exr"
    other.mkdir()  # a folder with the name: not removed either
    write_text(tmp_path / "fresh.txt", "x")  # a recent file may be another machine's writer
    assert stale.exists()
    past = time.time() - 3600
    os.utime(stale, (past, past))
    write_text(tmp_path / "next.txt", "x")  # the next write to the folder cleans up
    assert not stale.exists() and mine.exists() and other.is_dir()


def test_render_exr_is_readable_by_fit(tmp_path, capsys):
    """Per-vertex shading of lighting whose SH irradiance dips below zero wrote negative
    radiance to the EXR, which every shprobe reader (fit) refuses."""
    L = np.zeros((9, 3))
    L[0], L[2], L[6] = 1.0, 1.5, 0.8  # E < 0 on the -Z side
    coeffs = tmp_path / "neg.json"
    coeffs.write_text(export_coeffs(L, "json", source="test"))
    exr = tmp_path / "ball.exr"
    rc = main(["render", "--coeffs", str(coeffs), "--mode", "vertex", "--ortho", "--size",
               "96x96", "-o", str(tmp_path / "ball.png"), "--exr", str(exr)])
    assert rc == 0, capsys.readouterr().err
    img = read_image(exr)  # refuses negative pixels
    assert img.min() == 0.0 and img.max() > 0
    capsys.readouterr()
    rc = main(["fit", "grey-ball", str(exr), "-F", "json", "-o", str(tmp_path / "fit.json")])
    assert rc == 0, capsys.readouterr().err
