"""Arguments that overflowed the arithmetic (numpy warnings on the terminal, then an unrelated
error, or an infinite result written) are refused in one line before the work; unbounded
brute-force work is estimated and refused with how to raise the limit. Every command runs
with RuntimeWarning as an error, so a warning on the way fails the test (exit 70)."""

from __future__ import annotations

import time
import warnings

import numpy as np
import pytest

from shprobe.cli.main import main
from shprobe.errors import ShprobeError
from shprobe.lighting.reference import reference_irradiance
from shprobe.limits import MAX_PAIRS, check_pairs
from shprobe.probes.env import Env, env_from_function
from shprobe.probes.images import read_image, write_image
from tests.conftest import one_line_error


def _run(args, capsys) -> tuple[int, str]:
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        rc = main([str(a) for a in args])
    return rc, capsys.readouterr().err


def test_fit_arguments_that_overflowed(tmp_path, grey, bunny_path, capsys):
    out = tmp_path / "c.json"
    rc, err = _run(["fit", "grey-ball", grey, "--camera", "perspective:1e-300"], capsys)
    assert rc == 1
    one_line_error(err, "field of view", "1e-300")
    rc, err = _run(["fit", "grey-ball", grey, "--albedo", "1e-320", "-o", out], capsys)
    assert rc == 1
    one_line_error(err, "albedo", "1e-320")  # was: infinite coefficients printed
    assert not out.exists()
    rc, err = _run(["fit", "mesh", grey, bunny_path, "--distance", "1e308"], capsys)
    assert rc == 1
    one_line_error(err, "distance", "1e+308")
    rc, err = _run(["fit", "grey-ball", grey, "--camera", "perspective:20", "-o", out],
                   capsys)
    assert rc == 0 and out.exists()  # an ordinary field of view is fine


def test_render_arguments_that_overflowed(tmp_path, capsys):
    out = tmp_path / "r.exr"
    rc, err = _run(["render", "--preset", "grace", "--size", "16x16", "--albedo",
                    "1e308,1e308,1e308", "-o", out], capsys)
    assert rc == 1
    one_line_error(err, "albedo must be in [0, 1e+30]")  # was: a float32 cast overflow
    rc, err = _run(["render", "--preset", "grace", "--size", "16x16", "--fov", "1e-300",
                    "-o", out], capsys)
    assert rc == 1
    one_line_error(err, "field of view", "1e-300")
    assert not out.exists()
    rc, err = _run(["render", "--preset", "grace", "--size", "16x16", "--albedo",
                    "1e-320,1e-320,1e-320", "-o", out], capsys)
    assert rc == 0 and read_image(out).max() == 0.0  # a subnormal albedo is black


def test_edits_that_overflowed(tmp_path, capsys):
    out = tmp_path / "e.json"
    # a number beyond the edit language's range is refused as it is read
    rc, err = _run(["edit", "--preset", "grace", "--scale", "0,0=1e308", "--scale",
                    "0,0=1e308", "-o", out], capsys)
    assert rc == 1
    one_line_error(err, "at most 1e+09", "1e308")
    rc, err = _run(["edit", "--preset", "grace", "--blend", "preset:grace:1e308", "-o", out],
                   capsys)
    assert rc == 1
    one_line_error(err, "at most 1e+09", "1e308")  # was written as 7.9e307
    # numbers in range whose product leaves the edited range: refused once applied
    rc, err = _run(["edit", "--preset", "grace", *["--scale", "0,0=1e9"] * 4, "-o", out],
                   capsys)
    assert rc == 1
    one_line_error(err, "magnitude", "too large")
    assert not out.exists()
    rc, err = _run(["edit", "--preset", "grace", "--blend", "preset:grace:1e8", "-o", out],
                   capsys)
    assert rc == 0 and out.exists()


def test_report_refuses_radiance_it_cannot_expose(tmp_path, capsys):
    tiny = tmp_path / "tiny.exr"
    write_image(tiny, np.full((32, 64, 3), 1e-38, np.float32))
    rc, err = _run(["report", tiny, "-o", tmp_path / "r.html"], capsys)
    assert rc == 1
    one_line_error(err, str(tiny), "1.26e-37")
    assert not (tmp_path / "r.html").exists()


def test_report_map_size_is_estimated_before_the_work(tmp_path, capsys):
    big = tmp_path / "big.exr"  # 4096 x 2048: > 300 s at --map-size 256
    write_image(big, np.ones((2048, 4096, 3), np.float32))
    t0 = time.monotonic()
    rc, err = _run(["report", big, "--map-size", "256", "-o", tmp_path / "r.html"], capsys)
    assert rc == 1
    one_line_error(err, str(big), "--map-size 256", "1.1e+12", "SHPROBE_MAX_PAIRS")
    assert time.monotonic() - t0 < 60


def test_reference_irradiance_bounds_and_types(monkeypatch):
    env = env_from_function(lambda d: 1.0 + 0.5 * d, "latlong", 16)  # 32 x 16
    n = np.array([[0.0, 0.0, 1.0]])
    with pytest.raises(ShprobeError, match=r"must be an Env .* got ndarray"):
        reference_irradiance(env.radiance, n)
    t0 = time.monotonic()
    with pytest.raises(ShprobeError, match=r"1000x1000 sub-pixels .* SHPROBE_MAX_PAIRS"):
        reference_irradiance(env, np.repeat(n, 4000, axis=0), subdivide=1000)
    assert time.monotonic() - t0 < 5
    # within the limit the result is the brute force: E(+z) of channels 1 + 0.5 (x, y, z)
    # is π, π, π + π/3 (∫ max(0, z) dω = π, ∫ z max(0, z) dω = 2π/3, ∫ x max(0, z) dω = 0)
    e = reference_irradiance(env, n, subdivide=8)
    np.testing.assert_allclose(e[0], [np.pi, np.pi, np.pi + np.pi / 3], atol=5e-3)
    monkeypatch.setenv("SHPROBE_MAX_PAIRS", "1000")  # a lower limit refuses that too ...
    with pytest.raises(ShprobeError, match="over the limit of 1e\\+03"):
        reference_irradiance(env, n, subdivide=8)
    monkeypatch.setenv("SHPROBE_MAX_PAIRS", "1e15")  # ... and a higher one lets more through
    check_pairs(10 * MAX_PAIRS, "ten times the default")
    monkeypatch.setenv("SHPROBE_MAX_PAIRS", "lots")
    with pytest.raises(ShprobeError, match="SHPROBE_MAX_PAIRS='lots' is not a number"):
        check_pairs(1.0, "anything")
    assert isinstance(env, Env)
