"""The two refinement settings reproduce the bakes they replace: QUICK the quick refinement
(``shprobe prt bake --quick-contact``) and ACCURATE the adaptive contact (the default of an
interreflected bake with a ground), both as the code stood before they became settings objects
(commit 7ef3af1). The golden figures were computed with that code on the scene below:
``bake_refined(icosphere + ground at resolution 8, mode="interreflected", lmax=2, samples=64,
bounces=2, threads=2, max_rounds=1, **QUICK_CONTACT / **ADAPTIVE_CONTACT)`` and the default
shadowed ``bake(icosphere, ground=True, lmax=2, samples=64)``; rounded to 5 decimals."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shprobe.errors import ShprobeError
from shprobe.prt import ACCURATE, QUICK, REFINEMENTS, PrtSettings, Refinement, bake, load_scene
from shprobe.prt.refine import bake_refined

GOLDEN = {'accurate': {'abs': [635.59651, 713.04061, 741.22795],
                       'f': 1971,
                       'n': 1006,
                       'picked': 369,
                       'post_dense': 519,
                       'post_split': 587,
                       'rounds': [123, 364, 1006],
                       'sums': [263.57164, 315.51906, 328.68555],
                       'v0': [0.22612, 0.22189, 0.0, -0.13713, -0.09772, 0.0, -0.06308, -0.0,
                              -0.04886],
                       'vlast': [0.21999, 0.251, 0.0041, 0.04128, 0.03911, 0.00389, -0.0447,
                                 -0.0042, -0.11854],
                       'vmid': [0.20663, 0.12092, 0.01553, 0.19557, 0.07987, 0.00775, -0.04747,
                                0.01239, 0.08918]},
          'quick': {'abs': [237.4423, 258.07565, 265.69196],
                    'f': 687,
                    'n': 364,
                    'picked': 0,
                    'post_dense': None,
                    'post_split': None,
                    'rounds': [123, 364],
                    'sums': [98.84124, 112.74494, 116.30643],
                    'v0': [0.22559, 0.22164, -1e-05, -0.13703, -0.09777, 0.0, -0.0632, -3e-05,
                           -0.04887],
                    'vlast': [0.22308, 0.25562, 0.00263, 0.02173, 0.01886, 0.00322, -0.05335,
                              0.00109, -0.11444],
                    'vmid': [0.21273, 0.11325, 0.0538, -0.20613, -0.07885, 0.02879, -0.03609,
                             -0.0391, 0.09251]},
          'shadowed': {'abs': [3094.33872],
                       'f': 8886,
                       'n': 4574,
                       'picked': 0,
                       'post_dense': None,
                       'post_split': None,
                       'rounds': [4267, 4394, 4571, 4574, 4574],
                       'sums': [1269.96915],
                       'v0': [0.22559, 0.22164, -1e-05, -0.13703, -0.09777, 0.0, -0.0632, -3e-05,
                              -0.04887],
                       'vlast': [0.07999, 0.029, -0.01946, 0.10341, 0.04647, -0.01185, -0.01563,
                                 -0.01379, 0.07906],
                       'vmid': [0.05506, 0.03692, 0.03261, 0.02259, 0.02551, 0.03385, 0.00655,
                                -0.00107, 0.02936]}}


def summary(t):
    tr = np.asarray(t.traced, dtype=np.float64)
    r = t.metadata.get("refine", {})
    return {"n": int(t.n_vertices), "f": len(t.faces),
            "sums": tr.reshape(tr.shape[0], -1).sum(1),
            "abs": np.abs(tr).reshape(tr.shape[0], -1).sum(1),
            "v0": tr[-1, 0], "vmid": tr[-1, t.n_vertices // 2], "vlast": tr[-1, -1],
            "picked": r.get("dense_picked"), "post_split": r.get("post_split"),
            "post_dense": r.get("post_dense"),
            "rounds": [x["vertices"] for x in r.get("rounds", [])]}


def check(got, want):
    for key, value in want.items():
        if isinstance(value, list) and value and isinstance(value[0], float):
            np.testing.assert_allclose(got[key], value, rtol=1e-6, atol=1.5e-5, err_msg=key)
        else:
            assert got[key] == value, key


def sphere():
    return trimesh.creation.icosphere(subdivisions=1, radius=0.5)


@pytest.mark.parametrize("name", ["quick", "accurate"])
def test_presets_reproduce_the_bakes_they_replace(name):
    sc = load_scene(sphere(), ground=True, ground_resolution=8)
    t = bake_refined(sc, REFINEMENTS[name].but(max_rounds=1),
                     PrtSettings(mode="interreflected", lmax=2, samples=64, bounces=2,
                                 threads=2))
    check(summary(t), GOLDEN[name])


def test_default_shadowed_bake_with_a_ground_is_unchanged():
    t = bake(sphere(), mode="shadowed", lmax=2, samples=64, ground=True, threads=2)
    assert t.metadata["refine"]["settings"] == "quick"
    check(summary(t), GOLDEN["shadowed"])


def test_quick_is_the_default_of_every_traced_bake_with_a_ground(monkeypatch):
    import shprobe.prt.baking as bake_module

    seen = []
    monkeypatch.setattr(bake_module, "bake_refined", lambda sc, s, *a: seen.append(s))
    for mode in ("shadowed", "interreflected"):
        bake(sphere(), mode=mode, lmax=1, samples=64, ground=True)
    bake(sphere(), mode="interreflected", lmax=1, samples=64, ground=True, refine="accurate")
    bake(sphere(), mode="interreflected", lmax=1, samples=64, ground=True, refine=ACCURATE)
    assert seen == [QUICK, QUICK, ACCURATE, ACCURATE]
    t = bake(sphere(), mode="shadowed", lmax=1, samples=64, ground=True, refine=False)
    assert "refine" not in t.metadata


@pytest.mark.parametrize("bad", [dict(tol=0), dict(gather_tol=float("nan")),
                                 dict(max_rounds=-1), dict(dense_quadrature="x"),
                                 dict(adaptive_levels=9), dict(dense_picks=(0.1, -1.0)),
                                 dict(post_jump=0.1, dense_picks=()), dict(direction_sets=0)])
def test_bad_settings_are_one_line(bad):
    with pytest.raises(ShprobeError):
        Refinement(**bad)
    with pytest.raises(ShprobeError, match="refine must be"):
        bake(sphere(), mode="shadowed", lmax=1, samples=64, refine="fine")


def test_settings_are_frozen_and_named():
    assert QUICK.name == "quick" and ACCURATE.name == "accurate"
    assert ACCURATE.but(max_rounds=1).name == "custom"
    with pytest.raises(AttributeError):
        QUICK.tol = 1.0  # type: ignore[misc]
