"""Bad input to the probes, H-basis and fitting library: one ShprobeError, never a TypeError
or ValueError from numpy (load_env, h_basis, sh_to_h, normal maps)."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.hbasis import evaluate_h, h_basis, sh_to_h
from shprobe.probes.env import load_env


@pytest.mark.parametrize("arg", [None, 5, 2.5, object()])
def test_load_env_of_a_non_path(arg):
    with pytest.raises(ShprobeError, match="file path"):
        load_env(arg)


def test_load_env_of_six_non_paths():
    with pytest.raises(ShprobeError, match="file path"):
        load_env([1, 2, 3, 4, 5, 6])


BAD_ARRAYS = {
    "object": np.array([[0.0, 0.0, 1.0]], dtype=object),
    "strings": np.array([["a", "b", "c"]]),
    "ragged": [[0.0, 0.0, 1.0], [1.0]],
    "nan": np.array([[np.nan, 0.0, 1.0]]),
    "inf": np.array([[0.0, np.inf, 1.0]], np.float32),
}


@pytest.mark.parametrize("name", sorted(BAD_ARRAYS))
def test_h_basis_refuses_non_numeric_and_non_finite(name):
    with pytest.raises(ShprobeError, match="normals"):
        h_basis(BAD_ARRAYS[name])


@pytest.mark.parametrize("name", ["object", "nan", "inf"])
def test_sh_to_h_refuses_non_numeric_and_non_finite(name):
    c = np.ones((9, 3), dtype=object if name == "object" else np.float64)
    if name != "object":
        c[4, 1] = np.nan if name == "nan" else -np.inf
    with pytest.raises(ShprobeError, match="SH coefficients"):
        sh_to_h(c)
    big = np.ones((5000, 9, 1))  # the numba path (≥ 4096 sets) checks the same way
    big[1234, 3, 0] = np.nan
    with pytest.raises(ShprobeError, match="NaN"):
        sh_to_h(big)


def test_evaluate_h_refuses_nan():
    with pytest.raises(ShprobeError):
        evaluate_h(np.full(6, np.nan), [0.0, 0.0, 1.0])
    with pytest.raises(ShprobeError):
        evaluate_h(np.ones(6), [np.nan, 0.0, 1.0])


def test_nan_normal_map_refused_naming_the_file(tmp_path, capsys):
    from shprobe.cli.main import main
    from shprobe.fitting import fit_normals, read_normal_map
    from shprobe.probes.images import write_image

    jj, ii = np.mgrid[0:16, 0:16]
    x, y = (ii + 0.5) / 8 - 1, 1 - (jj + 0.5) / 8
    n = np.stack([x, y, np.sqrt(np.maximum(1 - x * x - y * y, 0))], -1).astype(np.float32)
    n[x * x + y * y > 1] = 0  # a ball's normals, zero (background) outside
    img = np.full((16, 16, 3), 0.5, np.float32)
    write_image(tmp_path / "img.exr", img)
    bad = n.copy()
    bad[3, 4] = np.nan
    import OpenImageIO as oiio  # write_image refuses NaN itself: write the file raw

    out = oiio.ImageOutput.create(str(tmp_path / "n.exr"))
    out.open(str(tmp_path / "n.exr"), oiio.ImageSpec(16, 16, 3, oiio.FLOAT))
    out.write_image(bad)
    out.close()
    with pytest.raises(ShprobeError, match="NaN") as e:
        read_normal_map(tmp_path / "n.exr")
    assert "n.exr" in str(e.value)
    rc = main(["fit", "normals", str(tmp_path / "img.exr"), str(tmp_path / "n.exr")])
    err = capsys.readouterr().err
    assert rc != 0 and "n.exr" in err and "NaN" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    with pytest.raises(ShprobeError, match="NaN"):
        fit_normals(img, bad)
    fit_normals(img, n)  # the same map without the NaN fits
