"""CLI: shprobe prefilter / irradiance / error / demo, coefficient sources and bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from shprobe.cli.main import main
from shprobe.lighting.irradiance import irradiance, irradiance_map
from shprobe.lighting.projection import project
from shprobe.probes.env import Env
from shprobe.probes.images import read_image, write_image
from shprobe.probes.presets import get_preset
from tests.conftest import one_line_error, write_raw_pfm


@pytest.fixture
def probe(tmp_path):
    """A small synthetic lat-long probe written as .hdr, and its Env as read back."""
    rng = np.random.default_rng(3)
    img = (rng.random((32, 64, 3)) * 2 + 0.1).astype(np.float32)
    path = tmp_path / "probe.hdr"
    write_image(path, img)
    return path, Env(read_image(path), "latlong")


def run(args, capsys):
    rc = main([str(a) for a in args])
    out = capsys.readouterr()
    return rc, out.out, out.err


def parse_table(out):
    rows = {}
    for line in out.splitlines():
        parts = line.replace("│", " ").split()
        if parts and parts[0].startswith("L") and len(parts) == 4:
            rows[parts[0]] = [float(v) for v in parts[1:]]
    return rows


def test_prefilter_table_matches_project(probe, capsys):
    path, env = probe
    rc, out, _ = run(["prefilter", path], capsys)
    assert rc == 0
    rows = parse_table(out)
    assert list(rows) == ["L00", "L1-1", "L10", "L11", "L2-2", "L2-1", "L20", "L21", "L22"]
    np.testing.assert_allclose(np.array(list(rows.values())), project(env, 2), atol=6e-5)


def test_prefilter_json_and_force(probe, tmp_path, capsys):
    path, env = probe
    out = tmp_path / "c.json"
    rc, _, _ = run(["prefilter", path, "--lmax", "3", "--format", "json", "-o", out], capsys)
    assert rc == 0
    doc = json.loads(out.read_text())
    assert doc["lmax"] == 3 and doc["layout"] == "latlong" and doc["source"] == str(path)
    np.testing.assert_allclose(doc["coefficients"], project(env, 3), rtol=1e-12)
    assert np.asarray(doc["M"]).shape == (3, 4, 4)
    before = out.read_bytes()
    rc, _, err = run(["prefilter", path, "--format", "json", "-o", out], capsys)
    one_line_error(err, rc=rc)
    assert "exists" in err and out.read_bytes() == before
    rc, _, _ = run(["prefilter", path, "--format", "json", "-o", out, "--force"], capsys)
    assert rc == 0 and json.loads(out.read_text())["lmax"] == 2
    # the JSON file is itself a coefficient source
    rc, stdout, _ = run(["prefilter", "--coeffs", out], capsys)
    assert rc == 0
    np.testing.assert_allclose(np.array(list(parse_table(stdout).values())), project(env, 2),
                               atol=6e-5)


def test_prefilter_preset_and_source_errors(capsys):
    rc, out, _ = run(["prefilter", "--preset", "grace"], capsys)
    assert rc == 0
    np.testing.assert_allclose(np.array(list(parse_table(out).values())), get_preset("grace"))
    rc, _, err = run(["prefilter"], capsys)
    one_line_error(err, rc=rc)
    rc, _, err = run(["prefilter", "--preset", "grace", "--lmax", "4"], capsys)
    one_line_error(err, rc=rc)


@pytest.mark.filterwarnings("ignore:.*8/16-bit")
def test_irradiance_sh_and_brute(probe, tmp_path, capsys):
    path, env = probe
    out = tmp_path / "e.exr"
    rc, _, _ = run(["irradiance", path, "-o", out, "--size", "32x16"], capsys)
    assert rc == 0
    e = read_image(out)
    want = irradiance_map(project(env, 2), "latlong", (32, 16)).radiance
    np.testing.assert_allclose(e, want, rtol=1e-5, atol=1e-5)
    brute = tmp_path / "b.pfm"
    rc, _, _ = run(["irradiance", path, "-o", brute, "--size", "16x8", "--method", "brute"],
                   capsys)
    assert rc == 0
    b = read_image(brute)
    sh4 = irradiance(project(env, 4), Env(b, "latlong").directions())
    np.testing.assert_allclose(b, sh4, rtol=0.02)  # a smooth probe: SH order 4 ≈ exact
    rc, _, _ = run(["irradiance", "--preset", "stpeters", "-o", tmp_path / "p.png",
                    "--out-layout", "latlong", "--size", "16x8"], capsys)
    assert rc == 0 and read_image(tmp_path / "p.png").shape == (8, 16, 3)


def test_error_command(probe, capsys):
    path, _ = probe
    rc, out, _ = run(["error", path, "--lmax-max", "3", "--normals", "8", "--format", "json"],
                     capsys)
    assert rc == 0
    doc = json.loads(out)
    assert [r["lmax"] for r in doc["rows"]] == [1, 2, 3] and doc["n_normals"] == 128
    assert all(0 <= r["mean_frac"] <= r["max_frac"] < 1 for r in doc["rows"])
    rc, _, err = run(["error", "--preset", "grace"], capsys)
    one_line_error(err, rc=rc)


def test_error_command_tolerance_and_worst_normal(probe, capsys):
    """--tol reaches the report; the JSON max is the exact error (brute force, computed here)
    at the reported normal and channel, no lower than the grid max; the table shows the worst
    normal and the tolerance; a bad --tol is one line."""
    from shprobe.lighting.projection import total_intensity
    from shprobe.lighting.reference import reference_irradiance

    path, env = probe
    rc, out, _ = run(["error", path, "--lmax-max", "2", "--normals", "8", "--tol", "1e-4",
                      "-F", "json"], capsys)
    assert rc == 0
    r = json.loads(out)["rows"][1]
    assert r["max_tol"] == 1e-4 and r["max_change"] < 1e-4 and r["max_converged"] is True
    n = np.asarray(r["max_normal"])[None]
    e = (np.abs(irradiance(project(env, 2), n) - reference_irradiance(env, n))
         / total_intensity(env))[0]
    assert e[r["max_channel"]] == pytest.approx(r["max_frac"], rel=1e-9) == e.max()
    assert r["max_frac"] >= r["grid_max_frac"]
    rc, out, _ = run(["error", path, "--lmax-max", "2", "--normals", "8", "--tol", "1e-4"],
                     capsys)
    assert rc == 0 and "± 0.01 pp" in out and "worst normal" in out
    assert " ".join(f"{x:+.2f}" for x in n[0]) in out
    for bad in ("0", "-1e-5", "nan", "inf"):
        rc, _, err = run(["error", path, "--tol", bad], capsys)
        one_line_error(err, rc=rc)


def test_error_table_flags_a_max_that_did_not_converge():
    import io
    from dataclasses import replace

    from rich.console import Console

    from shprobe.cli.prefilter import error_table
    from shprobe.lighting.reference import ErrorReport, ErrorRow

    ok = ErrorRow(2, 0.01, 0.05, 0.1, 0.1, np.array([0.0, 0.0, 1.0]), 1, 1e-5, 2e-6, 0.04, 1e-4)
    loose = replace(ok, lmax=4, max_change=3e-5)
    for rows, flagged in (((ok,), False), ((ok, loose), True)):
        con = Console(width=200, record=True, file=io.StringIO())
        con.print(error_table(ErrorReport(rows, np.ones(3), 2048, True)))
        out = con.export_text()
        assert "± 0.001 pp" in out and ("NOT converged to it for lmax 4" in out) == flagged
    assert "NOT converged" in repr(loose) and "NOT" not in repr(ok)


@pytest.mark.filterwarnings("ignore:.*8/16-bit")
def test_demo_writes_everything_once(tmp_path, capsys):
    out = tmp_path / "demo"
    rc, stdout, err = run(["demo", "--out", out, "--size", "64", "--table"], capsys)
    assert rc == 0
    assert "L2-2" in stdout and "sMAPE" in stdout  # the tables, asked for
    assert err.splitlines()[-1].startswith(f"wrote 5 files in {out}")
    names = {"probe.exr", "irradiance.exr", "irradiance.png", "side_by_side.png",
             "coefficients.json"}
    assert {p.name for p in out.iterdir()} == names
    from shprobe.probes.figures import read_panels  # a labelled figure: test_figures_cli

    assert [p["image_box"][2] - p["image_box"][0] for p in
            read_panels(out / "side_by_side.png")["panels"]] == [160, 160]
    stamp = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    rc, _, err = run(["demo", "--out", out, "--size", "64"], capsys)
    one_line_error(err, rc=rc)
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == stamp
    rc, _, _ = run(["demo", "--out", out, "--size", "32", "--force"], capsys)
    assert rc == 0


# ----------------------------------------------------------------------------- bad input


def _bad_files(tmp_path):
    empty = tmp_path / "empty.hdr"
    empty.write_bytes(b"")
    good = tmp_path / "good.hdr"
    write_image(good, np.ones((32, 64, 3), np.float32))
    trunc = tmp_path / "trunc.hdr"
    trunc.write_bytes(good.read_bytes()[: len(good.read_bytes()) // 2])
    corrupt = tmp_path / "corrupt.exr"
    corrupt.write_bytes(np.random.default_rng(0).integers(0, 256, 4000, np.uint8).tobytes())
    unknown = tmp_path / "probe.xyz"
    unknown.write_bytes(b"hello")
    square = tmp_path / "square.pfm"
    write_image(square, np.ones((16, 16, 3), np.float32))
    png = tmp_path / "good.png"
    Image.fromarray(np.random.default_rng(1).integers(0, 256, (64, 128, 3), np.uint8)).save(png)
    trunc_png = tmp_path / "trunc.png"
    trunc_png.write_bytes(png.read_bytes()[: len(png.read_bytes()) // 2])
    nan = tmp_path / "nan.pfm"
    img = np.ones((16, 32, 3), np.float32)
    img[3, 4, 1] = np.nan
    write_raw_pfm(nan, img)
    return {"empty": ([empty], "empty"), "truncated": ([trunc], "trunc.hdr"),
            "corrupt": ([corrupt], "corrupt.exr"), "unknown": ([unknown], "probe.xyz"),
            "aspect": ([square, "--layout", "latlong"], "square.pfm"),
            "nan": ([nan], "nan.pfm"), "truncated-png": ([trunc_png], "trunc.png")}


@pytest.mark.parametrize("case", ["empty", "truncated", "corrupt", "unknown", "aspect", "nan",
                                  "truncated-png"])
@pytest.mark.parametrize("command", ["prefilter", "irradiance", "error"])
def test_bad_input_is_one_line_and_writes_nothing(case, command, tmp_path, capfd):
    """capfd, not capsys: C libraries (libpng) write to file descriptor 2 directly."""
    args, name = _bad_files(tmp_path)[case]
    outdir = tmp_path / "out"
    outdir.mkdir()
    extra = {"prefilter": ["--format", "json", "-o", outdir / "c.json"],
             "irradiance": ["-o", outdir / "e.exr"], "error": []}[command]
    rc, _, err = run([command, *args, *extra], capfd)
    one_line_error(err, rc=rc)
    assert name in err
    assert list(outdir.iterdir()) == []


def test_existing_output_is_refused_before_any_work(probe, tmp_path, capsys):
    path, _ = probe
    out = tmp_path / "e.exr"
    out.write_bytes(b"keep me")
    rc, _, err = run(["irradiance", path, "-o", out], capsys)
    one_line_error(err, rc=rc)
    assert out.read_bytes() == b"keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.exr", "probe.hdr"]


@pytest.mark.parametrize("command", [["irradiance", "--method", "brute"],
                                     ["render", "--sphere", "--size", "8"]])
def test_unwritable_extension_is_refused_before_any_work(command, probe, tmp_path, capsys,
                                                         monkeypatch):
    import importlib

    import shprobe.lighting.reference

    render_module = importlib.import_module("shprobe.scene.render")  # shprobe.scene.render is
    # the function (shprobe.scene re-exports it), the module is patched

    def boom(*a, **k):
        raise AssertionError("work started before the output was checked")

    monkeypatch.setattr(shprobe.lighting.reference, "reference_irradiance", boom)
    monkeypatch.setattr(render_module, "render", boom)
    path, _ = probe
    rc, _, err = run([command[0], path, *command[1:], "-o", tmp_path / "e.gif"], capsys)
    one_line_error(err, rc=rc)
    assert "e.gif" in err and "extension" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["probe.hdr"]


def test_six_cube_face_files(tmp_path, capsys):
    """PROBE given as six face images (+X −X +Y −Y +Z −Z): f = 1 + a·ω has L00 = √(4π) and
    L_1m = a·√(4π/3) on (y, z, x) (R&H signs)."""
    from shprobe.probes.env import env_from_function

    a = np.array([0.5, 0.2, -0.3])
    env = env_from_function(lambda d: 1.0 + d @ a[:, None] * np.ones(3), "cube", 16)
    faces = [tmp_path / f"{n}.exr" for n in ("px", "nx", "py", "ny", "pz", "nz")]
    for k, f in enumerate(faces):
        write_image(f, env.radiance[k])
    out = tmp_path / "c.json"
    rc, _, _ = run(["prefilter", *faces, "--format", "json", "-o", out], capsys)
    assert rc == 0
    doc = json.loads(out.read_text())
    assert doc["layout"] == "cube"
    want = np.zeros(9)
    want[0] = np.sqrt(4 * np.pi)
    want[[1, 2, 3]] = a[[1, 2, 0]] * np.sqrt(4 * np.pi / 3)
    np.testing.assert_allclose(np.array(doc["coefficients"]), want[:, None] * np.ones(3),
                               atol=1e-5)
    rc, _, err = run(["prefilter", *faces[:3]], capsys)
    one_line_error(err, rc=rc)
    assert "six cube faces" in err
    rc, _, err = run(["prefilter", *faces, "--layout", "latlong"], capsys)
    one_line_error(err, rc=rc)
