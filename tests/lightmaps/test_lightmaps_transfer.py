"""Relightable lightmaps (LH 2007 §4 per texel): the transfer bake relit under a probe
rotated by 90° equals a fresh bake under the rotated probe — exactly with the same rays, to
Monte-Carlo noise with others — and survives the .glb."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from shprobe.lighting.source import resolve_lighting
from shprobe.lightmaps import LightmapSettings, bake_lightmap, load_lightmap
from shprobe.sh.rotation import from_axis_angle, rotate

sys.path.insert(0, str(Path(__file__).parent))
from test_lightmaps_bake import _room  # the box room with its normal-mapped floor


@pytest.fixture(scope="module")
def baked():
    sky = resolve_lighting(preset="grace").coeffs[:9]
    settings = LightmapSettings(size=32, samples=256, bounces=2, transfer=True, seed=5)
    return sky, settings, bake_lightmap(_room(), sky, settings)


def test_the_transfer_reproduces_its_own_bake(baked):
    sky, _, lm = baked
    relit = lm.relight(sky)
    for enc, c in lm.encodings.items():
        np.testing.assert_allclose(relit.coefficients(enc), c, rtol=1e-4,
                                   atol=1e-5 * np.abs(c).max())


def test_relit_under_a_rotated_probe_equals_a_fresh_bake(baked):
    sky, settings, lm = baked
    turned = rotate(sky, from_axis_angle([0, 0, 1], 90))
    relit = lm.relight(turned)
    same_rays = bake_lightmap(_room(), turned, LightmapSettings(**{**settings.__dict__,
                                                                   "transfer": False}))
    other_rays = bake_lightmap(_room(), turned, LightmapSettings(**{**settings.__dict__,
                                                                    "transfer": False,
                                                                    "seed": 11}))
    ok = lm.valid
    for enc in ("plain", "h6", "sh9"):
        a, b = relit.coefficients(enc)[ok], same_rays.coefficients(enc)[ok]
        np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-5 * np.abs(b).max())
        c = other_rays.coefficients(enc)[ok]
        noise = np.sqrt(np.mean((b - c) ** 2))  # two independent bakes: √2 × one's noise
        assert np.sqrt(np.mean((a - c) ** 2)) < 1.2 * noise + 1e-6
        assert noise < 0.15 * np.abs(b[:, 0]).mean()  # the comparison is not vacuous


def test_the_transfer_survives_the_glb(baked, tmp_path):
    sky, _, lm = baked
    lm.save(tmp_path / "t.glb")
    back = load_lightmap(tmp_path / "t.glb")
    assert back.as_dict()["transfer"]
    np.testing.assert_array_equal(back.stats["sky"], sky)  # the bake's sky, for viewers
    turned = rotate(sky, from_axis_angle([0, 0, 1], 90))
    want = lm.relight(turned).coefficients("h6")
    np.testing.assert_allclose(back.relight(turned).coefficients("h6"), want,
                               atol=3e-3 * np.abs(want).max())


@pytest.mark.slow
def test_a_bake_on_a_dask_cluster_equals_the_local_bake():
    pytest.importorskip("distributed")
    from distributed import LocalCluster

    sky = resolve_lighting(preset="grace").coeffs[:9]
    settings = LightmapSettings(size=48, samples=1024, bounces=1, seed=2)  # several tiles
    local = bake_lightmap(_room(), sky, settings)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        remote = bake_lightmap(_room(), sky, settings, scheduler=cluster.scheduler_address)
    assert local.texels.count > 2 * 256  # more than two tiles of 256 texels
    for enc in local.encodings:
        np.testing.assert_array_equal(remote.coefficients(enc), local.coefficients(enc))
