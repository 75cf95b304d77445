"""shprobe batch in-process: inputs, row contents against independent computations, error
rows, Parquet schema, parts and resume. (The Dask cluster tests are in test_batch_dask.py.)"""

from __future__ import annotations

import io
import json
import math
import os
import subprocess
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import xxhash
from PIL import Image

from shprobe.batch import BatchOptions, Engine, expand_inputs, parts_dir, probe_row, run_batch
from shprobe.batch.rows import content_hash
from shprobe.cli.main import main
from shprobe.errors import ShprobeError
from shprobe.lighting import (
    auto_window,
    error_report,
    irradiance,
    irradiance_coeffs,
    irradiance_matrix,
    project,
    total_intensity,
)
from shprobe.probes.env import env_from_function, load_env, write_env
from shprobe.probes.environments import procedural_env
from shprobe.probes.images import write_image
from shprobe.progress import Recorder
from tests.conftest import write_raw_pfm

INLINE = Engine(scheduler="inline")  # the batch in this process

AXIS = np.array([0.48, 0.6, -0.64])  # unit


def lobe(n):
    """max(0, ω·a)^n + a small floor."""
    return lambda d: np.repeat((np.maximum(d @ AXIS, 0.0) ** n + 1e-4)[:, None], 3, axis=1)


@pytest.fixture
def library(tmp_path):
    """A few small probes in several formats and layouts, plus bad files."""
    root = tmp_path / "lib"
    (root / "sub" / ".hidden").mkdir(parents=True)
    write_env(root / "a.exr", procedural_env(64, 32))
    write_env(root / "sub" / "b.hdr", procedural_env(96, 48))
    write_env(root / "sub" / "c.pfm", env_from_function(lobe(4), "cube", 8), arrangement="vcross")
    write_env(root / "d.exr", env_from_function(lambda d: 1 + 0.5 * d, "angular", 16))
    write_env(root / "sub" / ".hidden" / "h.exr", procedural_env(64, 32))
    (root / "bad.exr").write_bytes(b"not an image")
    bad = np.ones((8, 16, 3), np.float32)
    bad[2, 3] = np.nan
    write_raw_pfm(root / "nan.pfm", bad)
    write_image(root / "wide.exr", np.ones((8, 24, 3), np.float32))  # 3:1, no layout
    (root / "notes.md").write_text("not a probe")
    return root


def test_expand_inputs(library, tmp_path, monkeypatch):
    got = expand_inputs([library])
    names = [p.split("/lib/")[1] for p, _ in got]
    assert names == ["a.exr", "bad.exr", "d.exr", "nan.pfm", "wide.exr", "sub/b.hdr",
                     "sub/c.pfm"]
    assert {lay for _, lay in got} == {"auto"}
    lst = tmp_path / "list.txt"
    lst.write_text("# probes\nlib/a.exr\n\n" + str(library / "sub" / "b.hdr") + "\nmissing.exr\n")
    csvf = tmp_path / "list.csv"
    csvf.write_text("path,layout\nlib/d.exr,angular\nlib/a.exr,\n")
    pqf = tmp_path / "list.parquet"
    pq.write_table(pa.table({"path": [str(library / "sub" / "c.pfm")], "layout": ["cube"]}), pqf)
    got = expand_inputs([csvf, lst, pqf, library / "a.exr", str(library / "**" / "*.hdr")],
                        layout="latlong")
    assert [(p.split("/")[-1], lay) for p, lay in got] == [
        ("d.exr", "angular"), ("a.exr", "latlong"), ("b.hdr", "latlong"),
        ("missing.exr", "latlong"), ("c.pfm", "cube")]
    assert got[3][0] == str(tmp_path / "missing.exr")  # relative to the list, kept
    with pytest.raises(ShprobeError, match="no image files match"):
        expand_inputs([str(library / "*.tif")])
    bad = tmp_path / "bad.csv"
    bad.write_text("file\nx.exr\n")
    with pytest.raises(ShprobeError, match="'path' column"):
        expand_inputs([bad])
    bad.write_text("path,layout\nx.exr,sideways\n")
    with pytest.raises(ShprobeError, match="unknown layout 'sideways'"):
        expand_inputs([bad])


def test_row_against_independent_results(tmp_path):
    """A narrow lobe cos^n about AXIS: band-1 / band-0 of cos^n is √3 (n+1)/(n+2), so the
    strength is (n+1)/(n+2) and the direction AXIS; everything else against the library
    functions on the whole image and a brute-force minimum."""
    n = 20
    p = tmp_path / "lobe.exr"
    write_env(p, env_from_function(lobe(n), "latlong", 128))
    row = probe_row(str(p), options=BatchOptions(lmax=2, reference=6, thumbnail=32))
    env = load_env(p)
    c = project(env, 2)
    assert row["failure"] is None and row["warning"] is None
    assert (row["layout"], row["width"], row["height"], row["lmax"]) == ("latlong", 256, 128, 2)
    assert row["size_bytes"] == p.stat().st_size and row["content_hash"] == content_hash(p)
    assert content_hash(p) == xxhash.xxh3_128_hexdigest(p.read_bytes())  # read in chunks
    np.testing.assert_allclose(row["coefficients"], c, atol=1e-12)
    np.testing.assert_allclose(row["irradiance_coefficients"], irradiance_coeffs(c), atol=1e-12)
    np.testing.assert_allclose(row["M"], irradiance_matrix(c), atol=1e-12)
    np.testing.assert_allclose(row["integral"], total_intensity(env), rtol=1e-6)  # float32 rows
    np.testing.assert_allclose(row["dominant_direction"], AXIS, atol=2e-3)
    assert abs(row["dominant_strength"] - (n + 1) / (n + 2)) < 5e-3
    # certified minimum: below every sampled E, and attained to rounding
    g = np.random.default_rng(0).normal(size=(200000, 3))
    e_min = irradiance(c, g / np.linalg.norm(g, axis=1, keepdims=True)).min(axis=0)
    assert row["min_irradiance_certified"]
    assert np.all(np.asarray(row["min_irradiance"]) <= e_min + 1e-12)
    np.testing.assert_allclose(row["min_irradiance"], e_min, atol=1e-3 * c[0, 0])
    win = auto_window(c)
    assert win.kind != "none"  # a sharp lobe rings negative at lmax 2
    assert (row["window"], row["window_strength"]) == (win.kind, pytest.approx(win.strength))
    rep = error_report(env, (2,), normal_grid=6).row(2)
    assert row["reference_grid"] == 6
    assert row["error_mean"] == pytest.approx(rep.mean_frac)
    assert row["error_max"] == pytest.approx(rep.max_frac)
    thumb = np.asarray(Image.open(io.BytesIO(row["thumbnail"])))
    assert thumb.shape == (16, 32, 3)
    # the brightest thumbnail pixel looks along AXIS: column ψ/2π·W, row θ/π·H
    y, x = np.unravel_index(thumb.sum(axis=2).argmax(), thumb.shape[:2])
    theta, psi = math.acos(AXIS[1]), math.atan2(-AXIS[0], AXIS[2]) % (2 * math.pi)
    assert abs(y + 0.5 - theta / math.pi * 16) <= 1.5
    assert abs(x + 0.5 - psi / (2 * math.pi) * 32) <= 1.5


def test_table_errors_and_schema(library, tmp_path):
    out = tmp_path / "t.parquet"
    t = run_batch([library], out, options=BatchOptions(lmax=3), engine=INLINE).table
    assert out.exists() and not parts_dir(out).exists()
    rows = {r["path"].split("/lib/")[1]: r for r in t.to_pylist()}
    assert len(rows) == 7
    errs = {k: r["failure"] for k, r in rows.items() if r["failure"] is not None}
    assert set(errs) == {"bad.exr", "nan.pfm", "wide.exr"}
    for k, msg in errs.items():
        assert msg.startswith(str(library / k) + ": ") and "\n" not in msg
    assert "NaN" in errs["nan.pfm"] and "cannot tell the layout" in errs["wide.exr"]
    assert rows["nan.pfm"]["content_hash"] is not None  # what was reached is kept
    assert [rows[k]["layout"] for k in ("a.exr", "sub/b.hdr", "sub/c.pfm", "d.exr")] == [
        "latlong", "latlong", "cube", "angular"]
    for k in ("a.exr", "sub/b.hdr", "sub/c.pfm", "d.exr"):
        ref = project(load_env(library / k), 3)  # .hdr: float32 row sums fused with decoding
        np.testing.assert_allclose(rows[k]["coefficients"], ref, rtol=0,
                                   atol=(1e-6 if k.endswith(".hdr") else 1e-12)
                                   * np.abs(ref).max())
        assert rows[k]["min_irradiance_certified"] is False  # lmax 3: numerical
    # typed, documented, readable as is
    back = pq.read_table(out)
    assert back.equals(t)
    f = back.schema.field("coefficients")
    assert f.type == pa.list_(pa.list_(pa.float64(), 3))
    assert f.metadata[b"unit"] == b"radiance x sr"
    assert back.schema.field("M").type == pa.list_(pa.list_(pa.list_(pa.float64(), 4), 4), 3)
    meta = json.loads(back.schema.metadata[b"shprobe"])
    assert "R&H 2001 signs" in meta["convention"] and meta["options"]["lmax"] == 3
    df = back.to_pandas()
    assert df["failure"].isna().sum() == 4 and df["width"].dtype.kind in "if"


def test_resume_interrupt_and_options(library, tmp_path):
    out = tmp_path / "t.parquet"
    full = run_batch([library], None, engine=INLINE).table
    seen = []

    class StopAfterThree(Recorder):  # a shprobe.progress reporter
        def update(self, done):
            seen.append(done)
            if done == 3:
                raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_batch([library], out, engine=INLINE, flush_rows=2, progress=StopAfterThree())
    assert not out.exists()
    kept = pq.read_table(parts_dir(out)).to_pylist()  # parts are whole Parquet files
    assert len(kept) == 3  # one part of 2 rows + the flush on interrupt
    # re-run: finishes the rest; done rows are not recomputed (their timing is kept)
    t = run_batch([library], out, engine=INLINE).table
    assert not parts_dir(out).exists()
    drop = ["seconds"]
    assert t.drop(drop).equals(full.drop(drop))
    secs = {r["path"]: r["seconds"] for r in t.to_pylist()}
    for r in kept:
        if r["failure"] is None:
            assert secs[r["path"]] == r["seconds"]
    # a copy of a done probe under a new name is filled from its hash; a new probe computed
    (library / "copy.exr").write_bytes((library / "a.exr").read_bytes())
    t2 = run_batch([library], out, engine=INLINE).table.to_pylist()
    by = {r["path"].split("/lib/")[1]: r for r in t2}
    assert len(by) == 8 and by["copy.exr"]["seconds"] == 0.0
    assert by["copy.exr"]["coefficients"] == by["a.exr"]["coefficients"]
    with pytest.raises(ShprobeError, match="other options"):
        run_batch([library], out, options=BatchOptions(lmax=1), engine=INLINE)
    t3 = run_batch([library / "a.exr"], out, options=BatchOptions(lmax=1), engine=INLINE,
                   force=True).table
    assert t3.num_rows == 1 and len(t3.column("coefficients")[0]) == 4
    # a table whose hashes were made by another algorithm (SHA-256 before) is refused by name
    meta = json.loads(t3.schema.metadata[b"shprobe"])
    assert meta["options"]["hash"] == "xxh3_128"
    assert t3.schema.field("content_hash").metadata[b"algorithm"] == b"xxh3_128"
    meta["options"]["hash"] = "sha256"
    pq.write_table(t3.replace_schema_metadata({"shprobe": json.dumps(meta)}), out)
    with pytest.raises(ShprobeError, match="content hashes are sha256"):
        run_batch([library], out, options=BatchOptions(lmax=1), engine=INLINE)
    with pytest.raises(ShprobeError, match=r"\.parquet file"):
        run_batch([library], tmp_path / "t.csv", engine=INLINE)


def test_cli(library, tmp_path, capsys):
    out = tmp_path / "t.parquet"
    rc = main(["batch", str(library / "a.exr"), str(library / "bad.exr"), "-o", str(out),
               "--scheduler", "inline", "--thumbnails", "16"])
    err = capsys.readouterr().err
    assert rc == 1 and "2 probes, 1 failed" in err  # a failed row fails the command
    assert err.splitlines()[-1].startswith(f"shprobe: error: {out}: 1 of 2 probes failed")
    t = pq.read_table(out)
    assert t.column("thumbnail").null_count == 1
    rc = main(["batch", str(library / "a.exr"), str(library / "bad.exr"), "-o", str(out),
               "--scheduler", "inline", "--thumbnails", "16", "--allow-failures"])
    assert rc == 0 and "2 probes, 1 failed" in capsys.readouterr().err
    rc = main(["batch", str(library / "a.exr"), "-o", str(out), "--scheduler", "inline",
               "-n", "4"])
    err = capsys.readouterr().err
    assert rc == 1 and err.startswith("shprobe: error:") and err.count("\n") == 1


_FAULTS = """
import resource, sys
if sys.argv[1] == "keep":
    from shprobe.batch.engine import _keep_heap
    assert _keep_heap()
a = bytearray(16 << 20)  # 16 MiB (malloc, not numpy: numpy asks for huge pages), freed,
del a
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
a = bytearray(16 << 20)  # then the same size again (the next probe)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc mallopt")
def test_worker_heap_reuses_buffers():
    """Under Dask's MALLOC_TRIM_THRESHOLD_=65536 a second 16 MiB buffer is mapped afresh
    (~4096 page faults); after _keep_heap (what the batch worker plugin does) it is the first
    one's memory again."""
    env = os.environ | {"MALLOC_TRIM_THRESHOLD_": "65536"}
    faults = {how: int(subprocess.run([sys.executable, "-c", _FAULTS, how], env=env, text=True,
                                      capture_output=True, check=True).stdout)
              for how in ("dask", "keep")}
    assert faults["dask"] > 3000 and faults["keep"] < 300, faults
