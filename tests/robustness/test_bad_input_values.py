"""Classes 2 and 3 of the bad-input issue: every invalid argument raises ShprobeError (a
ValueError) in one line, never TypeError / OverflowError / LinAlgError; readers validate shape,
channels and finiteness; nothing non-finite is written; one policy for non-unit and zero
normals in every irradiance function."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shprobe.errors import ShprobeError
from shprobe.lighting import (
    as_coeffs,
    coeffs_document,
    irradiance,
    irradiance_from_matrix,
    irradiance_matrix,
    irradiance_quadratic,
    reference_irradiance,
    shade_irradiance,
)
from shprobe.lighting.export import import_coeffs, parse_coeffs
from shprobe.lighting.windows import auto_window, min_irradiance
from shprobe.probes.env import env_from_function
from shprobe.probes.presets import get_preset
from shprobe.sh import check_lmax, sh_basis
from shprobe.sh.rotation import rotate, unit_vectors, wigner_d

L9 = get_preset("grace")


@pytest.mark.parametrize("lmax", [None, float("nan"), float("inf"), -1, 2.5, "2", [2], True,
                                  10**30])
def test_bad_degrees_are_shprobe_errors(lmax):
    with pytest.raises(ShprobeError):
        check_lmax(lmax)
    with pytest.raises(ShprobeError):
        sh_basis([[0.0, 0.0, 1.0]], lmax)


@pytest.mark.parametrize("bad", [None, "abc", {"a": 1}, [[1, 2], [3]], np.array([object()]),
                                 np.ones(5), np.ones((9, 0)), np.full((9, 3), np.nan),
                                 np.ones((9, 3)) * 1j])
def test_bad_coefficient_arrays_are_one_line(bad):
    with pytest.raises(ShprobeError):
        as_coeffs(bad)


def test_nan_lighting_is_refused_by_windows_and_documents():
    bad = L9.copy()
    bad[4, 1] = np.nan
    for fn in (min_irradiance, auto_window, coeffs_document):
        with pytest.raises(ShprobeError, match="NaN"):
            fn(bad)


def test_zero_rotations_are_refused_not_divided_by():
    for lmax in (1, 2, 3, 6):
        with pytest.raises(ShprobeError):
            rotate(np.ones(((lmax + 1) ** 2, 3)), np.zeros((3, 3)))
        with pytest.raises(ShprobeError):
            wigner_d(np.zeros((3, 3)), lmax)


# ----------------------------------------------------------------------------- normals


@pytest.mark.parametrize("fn", [irradiance, irradiance_quadratic, shade_irradiance,
                                lambda L, n: irradiance_from_matrix(irradiance_matrix(L), n)])
def test_one_normals_policy(fn):
    n = np.array([[0.3, -0.4, 0.5], [0.0, 2.0, 0.0]])
    np.testing.assert_allclose(fn(L9, n), fn(L9, n / np.linalg.norm(n, axis=1, keepdims=True)),
                               rtol=1e-6)
    for bad in ([[0.0, 0.0, 0.0]], [[np.nan, 0, 1]], [[np.inf, 0, 0]]):
        with pytest.raises(ShprobeError, match="normals"):
            fn(L9, bad)
    with pytest.raises(ShprobeError, match=r"complex|real"):
        fn(L9, np.array([[0, 0, 1j]]))


def test_reference_irradiance_follows_the_same_policy():
    env = env_from_function(lambda d: 1.0 + d[..., :1] * np.ones(3), "latlong", 16)
    n = np.array([[0.0, 3.0, 0.0]])
    np.testing.assert_allclose(reference_irradiance(env, n), reference_irradiance(env, n / 3))
    with pytest.raises(ShprobeError, match="normals"):
        reference_irradiance(env, [[0.0, 0.0, 0.0]])


def test_unit_vectors_do_not_overflow():
    np.testing.assert_allclose(unit_vectors([1e308, 1e308, 0]), [2**-0.5, 2**-0.5, 0])
    np.testing.assert_allclose(unit_vectors([[0, 0, 0], [0, 0, 2]], zero="keep"),
                               [[0, 0, 0], [0, 0, 1]])


# ----------------------------------------------------------------------------- coefficient files


@pytest.mark.parametrize("text", [
    '{"coefficients": [[NaN, 0, 0]]}',
    '{"coefficients": [[Infinity, 0, 0]]}',
    '{"coefficients": [[1' + "0" * 5000 + ', 0, 0]]}',  # an integer too long to convert
    "[" * 100_000 + "]" * 100_000,  # nesting deep enough to overflow the parser
    '{"coefficients": "not numbers"}',
    '{"coefficients": [["a", "b", "c"]]}',
    '{"coefficients": []}',
    '{"coefficients": [[1, 2, 3], [4, 5, 6]]}',  # 2 is not (lmax+1)²
    '{"object": {"sh": "x"}}',
    '{"object": {"sh": [1, 2]}}',
    '{"extensions": {"EXT_lights_image_based": {"lights": [{"irradianceCoefficients": 5}]}}}',
    '{"extensions": {"EXT_lights_image_based": "nope"}}',
    '{"format": "three.SphericalHarmonics3", "coefficients": [1, 2]}',
    "12",
])
def test_malformed_coefficient_files_are_one_line(tmp_path, text):
    p = tmp_path / "c.json"
    p.write_text(text)
    with pytest.raises(ShprobeError) as e:
        import_coeffs(p)
    assert "c.json" in str(e.value) and "\n" not in str(e.value)


@settings(max_examples=150, deadline=None)
@given(st.recursive(st.none() | st.booleans() | st.floats(allow_nan=False) | st.integers()
                    | st.text(max_size=5),
                    lambda c: st.lists(c, max_size=4) | st.dictionaries(
                        st.sampled_from(["coefficients", "format", "object", "sh", "extensions",
                                         "EXT_lights_image_based", "lights",
                                         "irradianceCoefficients", "intensity"]), c,
                        max_size=4), max_leaves=20))
def test_any_json_document_is_coefficients_or_one_line(doc):
    """Whatever JSON arrives, the reader returns finite (K, C) coefficients or raises
    ShprobeError — no other exception type."""
    try:
        c, _ = parse_coeffs(json.dumps(doc), "x.json")
    except ShprobeError as e:
        assert "\n" not in str(e)
    else:
        assert c.ndim == 2 and np.all(np.isfinite(c))


def test_no_writer_emits_non_finite_json():
    doc = coeffs_document(L9)
    text = json.dumps(doc, allow_nan=False)  # raises if anything were non-finite
    assert "NaN" not in text


@pytest.mark.parametrize("option", [["--elevation", "nan"], ["--azimuth", "inf"],
                                    ["--fov", "nan"]])
def test_non_finite_camera_is_refused_not_rendered_black(tmp_path, capsys, option):
    from shprobe.cli.main import main

    rc = main(["render", "--preset", "grace", "--sphere", "--size", "16", *option, "-o",
               str(tmp_path / "e.png")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1
    assert "finite" in err[0] or "field of view" in err[0]
    assert not (tmp_path / "e.png").exists()
