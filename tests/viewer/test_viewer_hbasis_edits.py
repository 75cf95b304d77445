"""The H-basis view follows the page's edits: band scales, coefficient scales and a window
change its panels and errors, which are then exactly the library's H-basis render of the
edited coefficients (``render_normal_mapped`` of ``edit_lighting``'s result); with no edit
but a rotation it is the probe's own (brute-force reference)."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.lighting.edits import EditSpec
from shprobe.viewer.design import read_state
from shprobe.viewer.session import Session
from shprobe.viewer.views import is_rotation_only
from tests.conftest import data_file
from tests.viewer.test_viewer_grid import unpack

EDITS = {"band 2 at 0": {"scale_band": {"2": 0}},
         "band 0 at 3x": {"scale_band": {"0": 3}},
         "coefficient 1,0 at 2x": {"scale": {"1,0": 2}},
         "hann window": {"window": "hann:0.5"}}


@pytest.fixture(scope="module")
def session():
    return Session(str(data_file("probes", "grace.hdr")))


@pytest.fixture(scope="module")
def plain(session):
    head, arrays = unpack(session.hbasis(read_state({"lmax": 4}))[0])
    return head, arrays


def test_rotation_only_is_the_probe():
    assert is_rotation_only(read_state({"lmax": 2}))
    assert is_rotation_only(read_state({"rotation": {"axis": [0, 1, 0], "degrees": 40},
                                        "scale_band": {"1": 1}}))
    for doc in EDITS.values():
        assert not is_rotation_only(read_state(doc))


@pytest.mark.parametrize("name", list(EDITS))
def test_edits_change_the_panels_as_the_library_bakes_them(session, plain, name):
    from shprobe.hbasis.rendering import render_normal_mapped
    from shprobe.lighting.design import edit_lighting
    from shprobe.lighting.projection import project

    spec = read_state({"lmax": 2, **EDITS[name]})
    head, arrays = unpack(session.hbasis(spec)[0])
    ph, pa = plain
    # the edit shows: other panels and other errors than the unedited probe's
    assert head["reference"] == "the lighting's SH expansion"
    for k in ("H6", "H4", "SH9"):
        assert np.abs(arrays[k] - pa[k]).max() > 1e-3, (name, k)
        assert head["rel_rms"][k] != pytest.approx(ph["rel_rms"][k], rel=1e-3), (name, k)
    # ... and they are the library's H-basis render of the edited coefficients (lmax 4)
    env = session.source.env
    L = edit_lighting(np.asarray(project(env, 4), np.float64), spec.with_lmax(4),
                      lambda b, l: None).coeffs
    res = render_normal_mapped(session.mesh, L, size=160)
    for k in ("H6", "H4", "SH9"):
        np.testing.assert_allclose(arrays[k], res.layers[k] / np.pi, rtol=1e-5, atol=1e-6)
        assert head["rel_rms"][k] == pytest.approx(res.info["rel_rms"][k], rel=1e-9)
    np.testing.assert_allclose(arrays["reference"], res.irradiance / np.pi, rtol=1e-5,
                               atol=1e-6)
    tot = np.sqrt(4 * np.pi) * np.abs(L[0])
    err = (np.abs(res.layers["H4"] - res.irradiance) / tot).max(axis=-1)
    assert head["max_frac"]["H4"] == pytest.approx(float(err.max()), rel=1e-5)


def test_unedited_view_is_the_probe_brute_force(plain):
    head, _ = plain
    assert head["reference"] == "brute force over the probe"
    assert EditSpec(lmax=4) == read_state({"lmax": 4})
