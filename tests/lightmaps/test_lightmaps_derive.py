"""The encodings a stored lightmap implies (shprobe.lightmaps.derive): from a bake's L2 SH,
the other five equal the bake's own (H6, H4, HL2, L1 SH exactly; plain — the L2 series at the
surface normal against the bake's cosine-weighted estimate — within the l ≤ 2 truncation);
from H6, H4 is its first four coefficients; every stored encoding gives plain as itself at
n = (0, 0, 1)."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.lightmaps import format as fmt
from shprobe.lightmaps.derive import implied_encodings


@pytest.fixture(scope="module")
def bake():
    from shprobe.lightmaps import LightmapSettings, bake_lightmap, load_scene
    from shprobe.lightmaps.scenes import game_scene_path
    from shprobe.probes.presets import get_preset

    return bake_lightmap(load_scene(game_scene_path()), get_preset("grace"),
                         LightmapSettings(basis="sh9", size=128, samples=64, bounces=1))


def test_from_l2_sh_every_encoding_is_the_bakes(bake):
    v = bake.valid
    got = implied_encodings("sh9", bake.coefficients("sh9"))
    assert list(got) == list(fmt.ENCODINGS)
    for e in ("hl2", "sh4", "h4", "h6"):
        want = bake.coefficients(e)[v]
        assert np.abs(got[e][v] - want).max() <= 1e-5 * np.abs(want).max(), e
    plain, want = got["plain"][v][:, 0].mean(axis=1), bake.coefficients("plain")[v][:, 0].mean(1)
    lit = want > 0.05 * want.max()
    rel = np.abs(plain[lit] - want[lit]) / want[lit]
    assert np.median(rel) < 0.05 and np.percentile(rel, 90) < 0.15


def test_h6_gives_h4_and_plain():
    rng = np.random.default_rng(0)
    c = rng.normal(size=(4, 5, 6, 3))
    got = implied_encodings("h6", c)
    assert list(got) == ["plain", "h4", "h6"]
    np.testing.assert_array_equal(got["h4"], c[..., :4, :])
    n = np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(got["plain"][..., 0, :], fmt.evaluate("h6", c, n), atol=1e-12)
    # H6 at the normal: the first and third functions only (1/√(2π) and √(3/2π)(2z − 1))
    want = c[..., 0, :] / np.sqrt(2 * np.pi) + np.sqrt(3 / (2 * np.pi)) * c[..., 2, :]
    np.testing.assert_allclose(got["plain"][..., 0, :], want, atol=1e-12)
    for e in ("plain", "hl2", "sh4", "h4"):
        assert list(implied_encodings(e, rng.normal(size=(2, 2, fmt.N_COEFFS[e], 3)))) == (
            [e] if e == "plain" else ["plain", e])
