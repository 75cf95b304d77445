"""shprobe batch on hostile inputs and outputs, in real processes with a timeout: devices,
FIFOs and links to them are failure rows at once; '**' through symlink loops gives each file
once and ends; two batches on one output (one is refused, nothing committed is lost); missing
output folders are made; a table of the previous schema version is read and resumed."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pyarrow.parquet as pq
import pytest

from shprobe.batch import Engine, expand_inputs, read_table, run_batch
from shprobe.batch.lock import lock_path
from shprobe.probes.env import write_env
from shprobe.probes.environments import procedural_env

INLINE = Engine(scheduler="inline")  # the batch in this process

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="POSIX files")


def _shprobe(*args: str, timeout: float = 240) -> subprocess.CompletedProcess:
    """`shprobe ARGS` in a fresh process; a hang fails the test (the process is killed)."""
    return subprocess.run([sys.executable, "-m", "shprobe", *args], capture_output=True,
                          text=True, timeout=timeout)


def _lines(text: str) -> list[str]:
    return [x for x in text.splitlines() if x.strip()]


def test_devices_fifos_and_links_are_failure_rows_at_once(tmp_path):
    lib = tmp_path / "lib"
    lib.mkdir()
    write_env(lib / "good.hdr", procedural_env(32, 16))
    os.mkfifo(lib / "x.hdr")  # nobody ever writes to it: opening it for reading would block
    os.symlink("/dev/urandom", lib / "u.exr")  # endless
    os.mkfifo(tmp_path / "y.hdr")
    lst = tmp_path / "devzero.txt"
    lst.write_text(f"/dev/zero\n/dev/urandom\n{tmp_path / 'y.hdr'}\n{lib / 'good.hdr'}\n")
    out = tmp_path / "t.parquet"
    t0 = time.monotonic()
    r = _shprobe("batch", str(lst), str(lib), "-o", str(out), "--scheduler", "inline")
    assert time.monotonic() - t0 < 200
    assert r.returncode == 1, r.stderr
    assert _lines(r.stderr)[-1].startswith(f"shprobe: error: {out}: 5 of 6 probes failed")
    rows = {row["path"]: row for row in read_table(out).to_pylist()}
    assert set(rows) == {"/dev/zero", "/dev/urandom", str(tmp_path / "y.hdr"),
                         str(lib / "x.hdr"), str(lib / "u.exr"), str(lib / "good.hdr")}
    for p, row in rows.items():
        if p.endswith("good.hdr"):
            assert row["failure"] is None and row["width"] == 32
        else:
            assert "not a regular file" in row["failure"] and p in row["failure"], row
            assert row["content_hash"] is None and row["seconds"] < 5


def test_glob_through_symlink_loops(tmp_path):
    loop1 = tmp_path / "loop1"
    loop1.mkdir()
    write_env(loop1 / "x.hdr", procedural_env(16, 8))
    os.symlink(".", loop1 / "self")
    loop2 = tmp_path / "loop2"
    (loop2 / "d").mkdir(parents=True)
    write_env(loop2 / "d" / "y.hdr", procedural_env(16, 8))
    for name in "abc":  # 3 links to '.' in each of 2 folders: glob's walk explodes
        os.symlink(".", loop2 / name)
        os.symlink("..", loop2 / "d" / name)
    got = expand_inputs([str(loop1 / "**" / "*.hdr")])
    assert [p for p, _ in got] == [str(loop1 / "x.hdr")]
    code = ("import sys; from shprobe.batch import expand_inputs; "
            "print(len(expand_inputs([sys.argv[1]])))")
    r = subprocess.run([sys.executable, "-c", code, str(loop2 / "**" / "*.hdr")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.split() == ["1"], r.stderr
    # the walk still finds what glob finds where there is no loop, hidden entries skipped
    (tmp_path / "plain" / "a" / "b").mkdir(parents=True)
    (tmp_path / "plain" / ".h").mkdir()
    for q in ("plain/top.hdr", "plain/a/b/deep.hdr", "plain/.h/hidden.hdr", "plain/a/n.exr"):
        write_env(tmp_path / q, procedural_env(16, 8))
    import glob

    for pat in ("plain/**/*.hdr", "plain/**", "plain/a/**/*.hdr", "plain/*/**/*.exr"):
        want = sorted(q for q in glob.glob(str(tmp_path / pat), recursive=True)
                      if q.endswith((".hdr", ".exr")))
        assert [p for p, _ in expand_inputs([str(tmp_path / pat)])] == want, pat


def test_missing_output_folders_are_made(tmp_path):
    write_env(tmp_path / "a.hdr", procedural_env(32, 16))
    out = tmp_path / "out" / "new" / "deeper" / "t.parquet"
    t = run_batch([tmp_path / "a.hdr"], out, engine=INLINE, flush_rows=1).table
    assert t.num_rows == 1 and read_table(out).num_rows == 1
    assert not lock_path(out).exists()


def _library(root, n: int, size: int):
    root.mkdir()
    for i in range(n):
        write_env(root / f"p{i:02d}.hdr", procedural_env(size + 8 * i, size // 2 + 4 * i))
    return root


def test_two_batches_on_one_output(tmp_path):
    """A second batch on an output that one is writing is refused in one line; the first
    keeps all its rows; a resume afterwards adds the second's (2 real processes)."""
    a = _library(tmp_path / "probes", 24, 128)
    b = _library(tmp_path / "probes2", 3, 64)
    out = tmp_path / "T.parquet"
    first = subprocess.Popen([sys.executable, "-m", "shprobe", "batch", str(a), "-o", str(out),
                              "--scheduler", "inline", "--reference", "24"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not lock_path(out).exists() and first.poll() is None:
            assert time.monotonic() < deadline
            time.sleep(0.05)
        second = _shprobe("batch", str(b), "-o", str(out), "--scheduler", "inline",
                          "--reference", "24")
        running = first.poll() is None
        _, err1 = first.communicate(timeout=400)
    finally:
        if first.poll() is None:
            first.kill()
    assert running, "the first batch ended before the second started: make it longer"
    assert second.returncode == 1
    assert _lines(second.stderr) == [
        f"shprobe: error: {out}: is being written by another shprobe batch (process "
        f"{first.pid}, lock T.parquet.lock); wait for it or choose another output"]
    assert first.returncode == 0, err1
    rows = read_table(out).to_pylist()
    assert sorted(r["path"] for r in rows) == sorted(str(p) for p in a.iterdir())
    assert not lock_path(out).exists()
    again = _shprobe("batch", str(b), "-o", str(out), "--scheduler", "inline",
                     "--reference", "24")
    assert again.returncode == 0, again.stderr
    rows = read_table(out).to_pylist()
    assert len(rows) == 27 and all(r["failure"] is None for r in rows)


def test_stale_lock_file_of_a_killed_batch_is_no_lock(tmp_path):
    """flock dies with its process: a lock file left by a SIGKILLed batch does not block."""
    write_env(tmp_path / "a.hdr", procedural_env(32, 16))
    out = tmp_path / "t.parquet"
    lock_path(out).write_text("999999\n")
    assert run_batch([tmp_path / "a.hdr"], out, engine=INLINE).table.num_rows == 1
    assert not lock_path(out).exists()


def test_table_of_schema_version_1_is_read_and_resumed(tmp_path):
    """Before version 2 the failure column was named 'error' and the schema unversioned."""
    write_env(tmp_path / "a.hdr", procedural_env(32, 16))
    (tmp_path / "bad.hdr").write_bytes(b"not an image")
    out = tmp_path / "t.parquet"
    new = run_batch([tmp_path / "a.hdr", tmp_path / "bad.hdr"], out, engine=INLINE).table
    meta = json.loads(new.schema.metadata[b"shprobe"])
    assert meta["schema_version"] == 2 and "failure" in new.column_names
    assert "error" not in new.column_names
    del meta["schema_version"]
    old = new.rename_columns(["error" if n == "failure" else n for n in new.column_names])
    pq.write_table(old.replace_schema_metadata({"shprobe": json.dumps(meta)}), out)
    t = read_table(out)
    assert t.column_names == new.column_names
    assert t.column("failure").to_pylist() == new.column("failure").to_pylist()
    write_env(tmp_path / "c.hdr", procedural_env(48, 24))
    t = run_batch([tmp_path], out, engine=INLINE).table
    rows = {os.path.basename(r["path"]): r for r in t.to_pylist()}
    assert set(rows) == {"a.hdr", "bad.hdr", "c.hdr"}
    assert rows["a.hdr"]["seconds"] == new.column("seconds")[0].as_py()  # kept, not redone
    assert rows["c.hdr"]["failure"] is None and "bad.hdr" in rows["bad.hdr"]["failure"]
    meta["schema_version"] = 3
    pq.write_table(new.replace_schema_metadata({"shprobe": json.dumps(meta)}), out)
    with pytest.raises(ValueError, match="schema version 3"):
        read_table(out)
