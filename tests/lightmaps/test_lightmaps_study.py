"""The §5 study on a real scene: the packaged game scene (tools/make_game_scene.py) baked once
into all six encodings and compared, at the normal-map normals of its texels, with the
independent path tracer of tests/lightmaps/test_lightmaps_bake.py (same sky, albedo and
bounces); the denoiser's error with and without it."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from shprobe.lightmaps import ENCODINGS, LightmapSettings, bake_lightmap, load_scene
from shprobe.lightmaps.scenes import game_scene_path

sys.path.insert(0, str(Path(__file__).parent))
import test_lightmaps_bake as ref

#: 256² texels: at 128² the bounce read from the coarser lightmap adds a few % in the arcade
SIZE = 256


def _normal_map_normal(prim, uv):
    """The material's normal-map normal (tangent space) at TEXCOORD_0, bilinear with REPEAT,
    glTF's scale on x and y."""
    tex = prim.normal_texture
    h, w = tex.shape[:2]
    x, y = uv[:, 0] * w - 0.5, uv[:, 1] * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    t = lambda yy, xx: tex[yy % h, xx % w]  # noqa: E731
    v = ((t(y0, x0) * (1 - fx) + t(y0, x0 + 1) * fx) * (1 - fy)
         + (t(y0 + 1, x0) * (1 - fx) + t(y0 + 1, x0 + 1) * fx) * fy) * 2 - 1
    v[:, :2] *= prim.normal_scale
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.fixture(scope="module")
def study():
    scene = load_scene(game_scene_path())
    settings = LightmapSettings(size=SIZE, samples=256, bounces=1, albedo=ref.ALBEDO, seed=1)
    lm = bake_lightmap(scene, ref.SKY, settings)
    tx = lm.texels
    ok = np.flatnonzero(tx.inside & lm.valid[tx.rc[:, 0], tx.rc[:, 1]])
    pick = np.sort(np.random.default_rng(4).choice(ok, 60, replace=False))
    n_ts = np.concatenate([_normal_map_normal(lm.atlas.primitives[p], tx.uv0[[i]])
                           for i, p in zip(pick, tx.prim[pick], strict=True)])
    n_world = np.einsum("pi,pij->pj", n_ts, tx.frames[pick])
    tracer = ref._Tracer(lm.atlas and type("S", (), {"primitives": lm.atlas.primitives}))
    geo = tracer.fn[tx.face[pick]]
    e_ref = tracer.irradiance(tx.points[pick], n_world, geo, 3000, 1)
    return lm, pick, n_ts, e_ref


def _errors(got, want, keep=None):
    rel = np.abs(got - want).mean(1) / want.mean(1)
    rel = rel if keep is None else rel[keep]
    return rel.mean(), np.percentile(rel, 95)


@pytest.mark.slow
def test_the_six_encodings_against_the_path_tracer(study):
    lm, pick, n_ts, e_ref = study
    rc = lm.texels.rc[pick]
    # converged: not the dim corners lit by bounces alone, where 256 rays leave tens of %
    m = e_ref.mean(1)
    keep = m >= 0.25 * np.median(m)
    rows = {enc: (_errors(lm.irradiance(rc, n_ts, enc), e_ref),
                  _errors(lm.irradiance(rc, n_ts, enc), e_ref, keep)) for enc in ENCODINGS}
    print(f"\ngame scene {SIZE}², 1 bounce, 256 rays/texel, normal-map normals: relative error "
          f"against the path tracer, all 60 texels | the {keep.sum()} converged")
    print("encoding  coeffs    mean    95th pct  |    mean    95th pct")
    for enc, ((m1, p1), (m2, p2)) in rows.items():
        print(f"{enc:8s}  {lm.coefficients(enc).shape[2]:6d}  {100 * m1:6.2f} %  {100 * p1:6.2f} %"
              f"  |  {100 * m2:6.2f} %  {100 * p2:6.2f} %")
    conv = {enc: r[1] for enc, r in rows.items()}
    assert conv["h6"][1] < 0.10
    for rival in ("plain", "hl2", "sh4"):
        assert conv["h6"][0] < conv[rival][0], rival
    assert conv["h6"][0] < conv["sh9"][0] + 0.03


@pytest.mark.slow
def test_denoising_reports_its_change_and_error(study):
    lm, pick, n_ts, e_ref = study
    settings = LightmapSettings(size=SIZE, samples=16, bounces=1, albedo=ref.ALBEDO, seed=1,
                                denoise=True)
    noisy = bake_lightmap(load_scene(game_scene_path()), ref.SKY, settings)
    assert noisy.noisy is not None and noisy.stats["denoise_change_rel_rms"] > 0
    rc = lm.texels.rc[pick]
    m = e_ref.mean(1)
    keep = m >= 0.25 * np.median(m)  # the converged texels, as above
    with_d = _errors(noisy.irradiance(rc, n_ts, "h6"), e_ref, keep)
    c = noisy.noisy["h6"][rc[:, 0], rc[:, 1]].astype(np.float64)
    from shprobe.lightmaps import evaluate

    without = _errors(evaluate("h6", c, n_ts), e_ref, keep)
    change = 100 * noisy.stats["denoise_change_rel_rms"]
    print(f"\nH6, 16 rays/texel, {keep.sum()} converged texels: mean error "
          f"{100 * without[0]:.2f} % without the denoiser, {100 * with_d[0]:.2f} % with it "
          f"(it changed the map by {change:.1f} % rms)")
    assert with_d[0] < without[0]
