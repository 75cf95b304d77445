"""CLI: shprobe fit grey-ball / chrome-ball / normals / mesh — output as `shprobe prefilter`
writes it, the pictures, and one-line errors for bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from shprobe.cli.main import main
from shprobe.fitting import Circle, fit_grey_ball, parse_circle
from shprobe.lighting.document import read_coeffs_json
from shprobe.lighting.export import export_coeffs
from shprobe.probes.images import read_image, write_image
from shprobe.probes.presets import get_preset
from shprobe.scene import Camera, render
from tests.conftest import one_line_error


def run(args, capsys):
    rc = main([str(a) for a in args])
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_grey_ball_json_and_pictures(tmp_path, capsys, grey):
    path, L = grey, get_preset("grace")
    out = tmp_path / "fit.json"
    files = {k: tmp_path / f"{k}.{ext}" for k, ext in
             (("residual", "exr"), ("fitted", "exr"), ("mask", "png"), ("irradiance", "exr"),
              ("report", "png"))}
    rc, stdout, err = run(["fit", "grey-ball", path, "-F", "json", "-o", out, "--albedo",
                           "0.5"] + [a for k, p in files.items() for a in (f"--{k}", p)],
                          capsys)
    assert rc == 0, err
    last = err.splitlines()[-1]  # the closing line: the files, the fit's summary
    assert last.startswith("wrote 6 files in ") and "fit.json … report.png" in last
    assert "grey ball" in last and "poorly determined: L00, L10" in last
    c = read_coeffs_json(out)  # the prefilter document: `coefficients`
    lib = fit_grey_ball(read_image(path), None, albedo=0.5)
    np.testing.assert_allclose(c, lib.coeffs, rtol=1e-12, atol=1e-12)
    assert np.abs(c - L).max() < 0.01 * L[0].max()
    doc = json.loads(out.read_text())
    assert doc["fit"]["poorly_determined"] == ["L00", "L10"]
    assert doc["fit"]["kind"] == "grey" and len(doc["fit"]["circle"]) == 3
    assert set(doc) >= {"coefficients", "irradiance_coefficients", "M", "fit"}
    for p in files.values():
        assert p.stat().st_size > 0
    res = read_image(files["fitted"])
    assert res.shape == (100, 120, 3)
    # stdout formats: the table flags the coefficients, glsl is export_coeffs' text
    rc, stdout, _ = run(["fit", "grey-ball", path], capsys)
    assert rc == 0 and "poorly determined" in stdout and stdout.startswith(" ")
    rc, stdout, _ = run(["fit", "grey-ball", path, "-F", "glsl", "--circle",
                         lib.circle.text()], capsys)
    assert rc == 0
    given = fit_grey_ball(read_image(path), parse_circle(lib.circle.text()))
    assert stdout.strip() == export_coeffs(given.coeffs, "glsl", source=str(path)).strip()
    # no replacing without --force
    rc, _, err = run(["fit", "grey-ball", path, "-F", "json", "-o", out], capsys)
    one_line_error(err, "already exists", rc=rc, warnings=True)


def test_chrome_and_normals_commands(tmp_path, capsys, grey):
    L = get_preset("grace")
    r = render(None, L, Camera(64, 64, "orthographic"), albedo=1.0)
    write_image(tmp_path / "n.exr", r.normals)  # signed values kept in EXR
    write_image(tmp_path / "img.exr", r.image)
    rc, stdout, err = run(["fit", "normals", tmp_path / "img.exr", tmp_path / "n.exr", "-F",
                           "json"], capsys)
    assert rc == 0, err
    assert np.abs(np.array(json.loads(stdout)["coefficients"]) - L).max() < 1e-4
    const = np.zeros((64, 64, 3), np.float32)
    jj, ii = np.mgrid[0:64, 0:64]
    const[np.hypot(ii + 0.5 - 32, jj + 0.5 - 32) < 28] = 0.7
    write_image(tmp_path / "chrome.exr", const)
    rc, stdout, err = run(["fit", "chrome-ball", tmp_path / "chrome.exr", "-F", "json",
                           "--report", tmp_path / "c.png"], capsys)
    assert rc == 0, err
    doc = json.loads(stdout)
    assert doc["coefficients"][0][0] == pytest.approx(0.7 * 2 * np.sqrt(np.pi), rel=1e-4)
    assert doc["fit"]["blind_spot_degrees"] > 0 and "blind spot" in err


def test_bad_input_one_line(tmp_path, capsys, bunny_path):
    flat = tmp_path / "flat.exr"
    write_image(flat, np.full((40, 50, 3), 0.2, np.float32))
    rc, _, err = run(["fit", "grey-ball", flat], capsys)
    one_line_error(err, "no ball found", rc=rc, warnings=True)
    r = render(None, get_preset("grace"), Camera(80, 80, "orthographic", margin=1.2),
               albedo=0.5).image
    cut = tmp_path / "cut.exr"
    write_image(cut, r[:, 25:])
    rc, _, err = run(["fit", "grey-ball", cut], capsys)
    one_line_error(err, "border", rc=rc, warnings=True)
    rc, _, err = run(["fit", "grey-ball", cut, "--circle", "10,40,33"], capsys)
    one_line_error(err, "border", rc=rc, warnings=True)
    white = tmp_path / "white.png"  # every ball pixel clipped at 255
    write_image(white, r, exposure=12.0)
    rc, _, err = run(["fit", "grey-ball", white], capsys)
    one_line_error(err, "saturated", rc=rc, warnings=True)
    rc, _, err = run(["fit", "grey-ball", cut, "--camera", "fisheye"], capsys)
    one_line_error(err, "camera", rc=rc, warnings=True)
    rc, _, err = run(["fit", "grey-ball", cut, "--circle", "1,2"], capsys)
    one_line_error(err, "circle", rc=rc, warnings=True)
    small = tmp_path / "small.exr"
    write_image(small, np.full((16, 16, 3), 0.5, np.float32))
    rc, _, err = run(["fit", "mesh", small, bunny_path, "--margin", "1000"], capsys)
    one_line_error(err, "sees nothing", rc=rc, warnings=True)
    rc, _, err = run(["fit", "grey-ball", tmp_path / "missing.exr"], capsys)
    one_line_error(err, "no such file", rc=rc, warnings=True)
    assert Circle(1, 2, 3).text() == "1.000,2.000,3.000"


def test_bad_numbers_one_line(tmp_path, capsys, grey):
    path = grey
    for args, what in ((["--albedo", "0"], "albedo"), (["--albedo", "nan"], "albedo"),
                       (["--inset", "-1"], "inset"), (["--saturation", "nan"], "saturation")):
        rc, _, err = run(["fit", "grey-ball", path, *args], capsys)
        one_line_error(err, what, rc=rc, warnings=True)
