"""Class 4 of the bad-input issue: output files. Temporary files go on SIGTERM / SIGHUP too; a
dangling link at the target is not replaced without --force; the final move cannot clobber a
file another process wrote meanwhile; errors name the target, come before the work, and
fit a 255-byte name; bakes are .npz only; missing output folders are made, the same way by
every command."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from shprobe.cli.main import main
from shprobe.errors import ShprobeError
from shprobe.files import atomic_output, check_output_path, save_npz, write_text

ROOT = Path(__file__).resolve().parents[2]


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if ".tmp" in p.name)


def test_dangling_link_is_not_replaced_without_force(tmp_path):
    target = tmp_path / "out.txt"
    target.symlink_to(tmp_path / "nowhere")
    with pytest.raises(ShprobeError, match="already exists"):
        write_text(target, "x")
    write_text(target, "x", overwrite=True)
    assert target.read_text() == "x" and not target.is_symlink()


def test_a_file_written_meanwhile_is_not_clobbered(tmp_path):
    target = tmp_path / "out.txt"
    with pytest.raises(ShprobeError, match="already exists"):
        with atomic_output(target) as tmp:
            tmp.write_text("mine")
            target.write_text("theirs")  # another process wins the race
    assert target.read_text() == "theirs"
    assert _leftovers(tmp_path) == []


def test_a_255_byte_name_works(tmp_path):
    name = "a" * 251 + ".txt"
    write_text(tmp_path / name, "x")
    assert (tmp_path / name).read_text() == "x"
    with pytest.raises(ShprobeError, match="longer than 255"):
        check_output_path(tmp_path / ("b" * 256))


def test_missing_folders_are_made_and_bad_parents_refused_first(tmp_path):
    write_text(tmp_path / "a" / "b" / "c.txt", "x")
    assert (tmp_path / "a" / "b" / "c.txt").read_text() == "x"
    (tmp_path / "file").write_text("")
    with pytest.raises(ShprobeError, match="is not a folder"):
        check_output_path(tmp_path / "file" / "x.txt")


def test_unwritable_folder_is_refused_before_work(tmp_path, monkeypatch):
    ro = tmp_path / "ro"
    ro.mkdir(mode=0o500)
    if os.geteuid() == 0:  # root may write anywhere: the folder reads as read-only to others
        real = os.access
        monkeypatch.setattr(os, "access", lambda p, mode, **kw: (
            False if Path(p) == ro and mode & os.W_OK else real(p, mode, **kw)))
    with pytest.raises(ShprobeError, match="not writable"):
        check_output_path(ro / "x.txt")


def test_errors_while_writing_name_the_target(tmp_path):
    with pytest.raises(ShprobeError) as e:
        with atomic_output(tmp_path / "t.bin") as tmp:
            tmp.write_bytes(b"x")
            raise OSError(28, "No space left on device")
    assert "t.bin" in str(e.value) and "No space left" in str(e.value)
    assert ".tmp" not in str(e.value) and _leftovers(tmp_path) == []


def test_npz_only_under_npz_names(tmp_path):
    mesh = tmp_path / "m.obj"
    mesh.write_text("v 0 0 0\n")
    with pytest.raises(ShprobeError, match=r"\.npz"):
        save_npz(mesh, overwrite=True, a=np.zeros(3))
    assert mesh.read_text() == "v 0 0 0\n"
    with pytest.raises(ShprobeError, match="non-finite"):
        save_npz(tmp_path / "x.npz", a=np.array([np.nan]))


def test_prt_bake_refuses_to_replace_its_mesh(tmp_path, capsys):
    from tests.conftest import data_file

    mesh = tmp_path / "bunny.obj"
    mesh.write_bytes(data_file("meshes", "bunny.obj").read_bytes())
    before = mesh.read_bytes()
    rc = main(["prt", "bake", str(mesh), "-o", str(mesh), "--force", "--mode", "unshadowed"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc != 0 and len(err) == 1 and ".npz" in err[0]
    assert mesh.read_bytes() == before


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_signals_leave_no_temporary_file(tmp_path, sig):
    """A command killed by SIGTERM / SIGHUP while writing removes its temporary file and leaves
    no target."""
    code = (
        "import sys, time\n"
        "import shprobe.files as f\n"
        "from shprobe.cli import main as m\n"
        "def slow(path, text, overwrite=False):\n"
        "    with f.atomic_output(path, overwrite) as tmp:\n"
        "        tmp.write_text(text)\n"
        "        print('writing', flush=True)\n"
        "        time.sleep(60)\n"
        "f.write_text = slow\n"
        "import shprobe.cli.prefilter\n"
        "sys.exit(m.main(['prefilter', '--preset', 'grace', '--format', 'json', '-o', "
        f"{str(tmp_path / 'c.json')!r}]))\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    assert proc.stdout.readline().strip() == "writing"
    assert _leftovers(tmp_path)  # the temporary file exists while it works
    proc.send_signal(sig)
    try:
        proc.wait(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 128 + sig
    assert _leftovers(tmp_path) == [] and not (tmp_path / "c.json").exists()
    assert "Traceback" not in proc.stderr.read()



def test_devices_are_never_replaced(tmp_path, capsys):
    """`-o /dev/null --force` must not turn the device into a file (renaming over it would)."""
    import stat as st

    assert st.S_ISCHR(os.stat("/dev/null").st_mode)
    with pytest.raises(ShprobeError, match="not a regular file"):
        check_output_path("/dev/null", overwrite=True)
    rc = main(["prefilter", "--preset", "grace", "--format", "json", "-o", "/dev/null",
               "--force"])
    assert rc == 1 and "not a regular file" in capsys.readouterr().err
    assert st.S_ISCHR(os.stat("/dev/null").st_mode)
