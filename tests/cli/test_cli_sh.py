"""`shprobe sh eval` / `shprobe sh zonal` through shprobe.cli.main.main."""

from __future__ import annotations

import json

import numpy as np
import pytest

from shprobe.cli.main import main


def run(args, capsys):
    rc = main(args)
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def test_eval_json_normalises_and_matches_table(capsys):
    rc, out, _ = run(["sh", "eval", "--dir", "0,0,2", "--dir", "3,0,4", "--lmax", "2",
                      "--format", "json"], capsys)
    assert rc == 0
    data = json.loads(out)
    v = np.array(data["values"])
    assert v.shape == (2, 9)
    # R&H table at +Z and at (0.6, 0, 0.8): y11 = 0.488603 x, y21 = 1.092548 xz, ...
    np.testing.assert_allclose(v[0, [0, 2, 6]], [0.282095, 0.488603, 0.315392 * 2], atol=1e-6)
    np.testing.assert_allclose(v[1, [3, 7, 8]], [0.488603 * 0.6, 1.092548 * 0.48,
                                                 0.546274 * 0.36], atol=1e-6)


def test_eval_extreme_magnitudes_normalise(capfd):
    """(1e200, 1e200, 0) and (1e-320, 0, 0) are valid directions: no overflow warning."""
    rc, out, err = run(["sh", "eval", "--dir", "1e200,1e200,0", "--dir", "1e-320,0,0",
                        "--lmax", "1", "--format", "json"], capfd)
    assert rc == 0 and err == ""
    v = np.array(json.loads(out)["values"])
    np.testing.assert_allclose(v[:, 1:], [[0.488603 / np.sqrt(2), 0, 0.488603 / np.sqrt(2)],
                                          [0, 0, 0.488603]], atol=1e-6)


def test_eval_table(capsys):
    rc, out, _ = run(["sh", "eval", "--dir", "1,0,0", "--lmax", "1"], capsys)
    assert rc == 0
    lines = out.strip().splitlines()
    assert len(lines) == 5 and lines[0].split()[:3] == ["k", "l", "m"]
    assert lines[4].split()[:3] == ["3", "1", "1"]
    assert abs(float(lines[4].split()[3]) - 0.488603) < 1e-6


def test_zonal_clamped_cosine(capsys):
    rc, out, _ = run(["sh", "zonal", "--lmax", "6", "--format", "json"], capsys)
    assert rc == 0
    np.testing.assert_allclose(json.loads(out)["A_hat_l"],
                               [3.141593, 2.094395, 0.785398, 0, -0.130900, 0, 0.049087],
                               atol=5e-7)


def test_zonal_runs_bare_as_the_readme_shows(capsys):
    rc, out, _ = run(["sh", "zonal"], capsys)
    rows = out.strip().splitlines()[1:]
    assert rc == 0 and len(rows) == 9  # l = 0..8
    assert abs(float(rows[2].split()[1]) - np.pi / 4) < 1e-8  # Â_2 = π/4 (R&H eq. 9)


def test_zonal_window(capsys):
    rc, out, _ = run(["sh", "zonal", "--lmax", "3", "--kind", "window", "--aperture", "180"],
                     capsys)
    assert rc == 0
    vals = [float(line.split()[1]) for line in out.strip().splitlines()[1:]]
    # the whole sphere at radiance 1: only the constant term 4π survives
    np.testing.assert_allclose(vals, [4 * np.pi, 0, 0, 0], atol=1e-12)


@pytest.mark.parametrize("args", [
    ["sh", "eval", "--dir", "0,0,0", "--lmax", "2"],
    ["sh", "eval", "--dir", "1,2", "--lmax", "2"],
    ["sh", "eval", "--dir", "a,b,c", "--lmax", "2"],
    ["sh", "eval", "--dir", "0,0,1", "--lmax", "-3"],
    ["sh", "eval", "--lmax", "2"],
    ["sh", "eval", "--dir", "0,0,1", "--lmax", "2", "--format", "xml"],
    ["sh", "zonal", "--lmax", "4", "--kind", "window"],
    ["sh", "zonal", "--lmax", "4", "--kind", "window", "--aperture", "0"],
    ["sh", "zonal", "--lmax", "4", "--aperture", "10"],
    ["sh", "zonal", "--lmax", "x"],
])
def test_bad_arguments_one_line(args, capsys):
    rc, _out, err = run(args, capsys)
    assert rc != 0
    err = err.strip()
    assert err.startswith("shprobe: error:") and "\n" not in err and "Traceback" not in err
