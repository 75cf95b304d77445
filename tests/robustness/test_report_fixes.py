"""Library messages a new user meets (issue 13): Env's short repr, write_env's swapped
arguments, quaternion order in rotate, relight's degree message."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from shprobe.errors import ShprobeError
from shprobe.probes.env import Env, env_from_function, load_env, write_env
from shprobe.sh.rotation import from_quaternion, rotate


def test_env_repr_is_short_and_states_the_total_intensity(grace_path):
    from shprobe.lighting import total_intensity

    env = load_env(grace_path)
    text = repr(env)
    assert text == str(env) and len(text) < 160 and "\n" not in text
    assert text.startswith("Env(latlong 256x128, float32, path=")
    tot = total_intensity(env)
    assert "∫L dω=(" + ", ".join(f"{v:.4g}" for v in tot) + ")" in text
    # a constant 1 over the sphere integrates to 4π, whatever the layout
    cube = env_from_function(lambda d: np.ones_like(d), "cube", 4)
    assert repr(cube) == "Env(cube 6x4x4, float32, ∫L dω=(12.57, 12.57, 12.57))"


def test_write_env_with_swapped_arguments_is_one_line(tmp_path):
    env = Env(np.ones((4, 8, 3), np.float32), "latlong")
    with pytest.raises(ShprobeError, match=r"first argument is the file.*got Env "
                                           r"\(arguments swapped\?\)"):
        write_env(env, tmp_path / "x.exr")
    with pytest.raises(ShprobeError, match="first argument is the file"):
        write_env(3, env)
    assert write_env(tmp_path / "x.exr", env).is_file()


def test_rotate_takes_scalar_first_quaternions_and_scipy_rotations():
    rng = np.random.default_rng(3)
    coeffs = rng.normal(size=(9, 3))
    rot = Rotation.from_rotvec([0.3, -1.1, 0.7])
    by_matrix = rotate(coeffs, rot.as_matrix())
    np.testing.assert_allclose(rotate(coeffs, rot), by_matrix, atol=1e-12)
    wxyz = np.roll(rot.as_quat(), 1)  # scipy is (x, y, z, w)
    np.testing.assert_allclose(rotate(coeffs, wxyz), by_matrix, atol=1e-12)
    np.testing.assert_allclose(from_quaternion(wxyz), rot.as_matrix(), atol=1e-12)
    # scipy's scalar-last array is a different rotation: the docstring's warning is real
    assert not np.allclose(rotate(coeffs, rot.as_quat()), by_matrix, atol=1e-3)
    doc = rotate.__doc__
    assert "scalar-first (w, x, y, z)" in doc and "as_quat()" in doc and "scalar-LAST" in doc


def test_relight_says_which_degree_limits_lmax():
    from shprobe.prt import relight

    with pytest.raises(ShprobeError, match=r"the lighting degree 2 \(9 coefficients\); the "
                                           r"highest usable is 2, set by the lighting"):
        relight(np.ones((5, 25)), np.ones((9, 3)), lmax=4)
    with pytest.raises(ShprobeError, match="set by the transfer"):
        relight(np.ones((5, 4)), np.ones((9, 3)), lmax=2)
