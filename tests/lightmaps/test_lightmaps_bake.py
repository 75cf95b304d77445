"""The lightmap bake against closed forms (a plane under a constant sky: E = π L at the normal
and π L (1 + z)/2 at tilted normal-map normals; a plane under a sun: the cosine law) and an
independent path tracer written here (Embree through embreex directly, cosine sampling, the
same albedo and one bounce) in a box room with a normal-mapped floor."""

from __future__ import annotations

import math

import numpy as np
import pytest

from shprobe.hbasis import hemisphere_quadrature
from shprobe.lightmaps import ENCODINGS, LightmapSettings, bake_lightmap, basis_values
from shprobe.lightmaps.scene import LightmapScene, Primitive
from shprobe.sh import sh_basis

Y00 = 0.5 / math.sqrt(math.pi)


def _plane(size=2.0, uv1=True):
    h = size / 2
    pos = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], float)
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float)
    return Primitive(pos, np.array([[0, 1, 2], [0, 2, 3]]), np.tile([0, 0, 1.0], (4, 1)), uv,
                     uv * 0.9 + 0.05 if uv1 else None)


def _tilted(n=50, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.3
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _hemi_projection(enc, f):
    """Least-squares coefficients of f on the upper hemisphere (quadrature, exact for these
    polynomial bases): the HL2 reference."""
    nodes, w = hemisphere_quadrature(24, 48)
    b = basis_values(enc, nodes)
    g = (b * w[:, None]).T @ b
    return np.linalg.solve(g, (b * w[:, None]).T @ f(nodes))


def test_constant_sky_over_a_plane_is_pi_L_in_every_encoding():
    L = 1.7
    sky = np.zeros((9, 3))
    sky[0] = L / Y00
    lm = bake_lightmap(LightmapScene([_plane()]), sky, LightmapSettings(size=8, samples=16,
                                                                        bounces=0))
    rc = np.argwhere(lm.valid)
    up = np.tile([0.0, 0.0, 1.0], (len(rc), 1))
    for enc in ("plain", "sh4", "sh9", "h4", "h6"):
        np.testing.assert_allclose(lm.irradiance(rc, up, enc), math.pi * L, rtol=1e-5)
    # tilted normal-map normals: only the sky above the plane lights them, E = π L (1 + z)/2,
    # linear in z: SH (l ≤ 1 already) and H4/H6 hold it exactly
    n = _tilted(len(rc))
    want = math.pi * L * (1 + n[:, 2]) / 2
    for enc in ("sh4", "sh9", "h4", "h6"):
        np.testing.assert_allclose(lm.irradiance(rc, n, enc)[:, 1], want, rtol=1e-5)
    np.testing.assert_allclose(lm.irradiance(rc, n, "plain")[:, 1], math.pi * L, rtol=1e-6)
    # HL2 spans x, y, z only: its least-squares fit of π L (1 + z)/2 on the hemisphere
    c = _hemi_projection("hl2", lambda d: math.pi * L * (1 + d[:, 2]) / 2)
    np.testing.assert_allclose(lm.irradiance(rc, n, "hl2")[:, 0], basis_values("hl2", n) @ c,
                               rtol=1e-5)


def test_sun_over_a_plane_follows_the_cosine_law():
    s = np.array([0.5, -0.3, 0.8])
    s /= np.linalg.norm(s)
    rgb = np.array([3.0, 2.0, 1.0])
    lm = bake_lightmap(LightmapScene([_plane()]), np.zeros((9, 3)),
                       LightmapSettings(size=8, samples=4, bounces=0,
                                        sun=(tuple(s), tuple(rgb))))
    rc = np.argwhere(lm.valid)
    up = np.tile([0.0, 0.0, 1.0], (len(rc), 1))
    np.testing.assert_allclose(lm.irradiance(rc, up, "plain"), np.broadcast_to(s[2] * rgb, (
        len(rc), 3)), rtol=1e-6)
    # SH 9: the clamped cosine's own l ≤ 2 series, E_s Σ_l Â_l (2l + 1)/4π P_l(n·s)
    n = _tilted(len(rc), 2)
    t = n @ s
    zh = (math.pi * 1 / (4 * math.pi) + 2 * math.pi / 3 * 3 / (4 * math.pi) * t
          + math.pi / 4 * 5 / (4 * math.pi) * 0.5 * (3 * t * t - 1))
    np.testing.assert_allclose(lm.irradiance(rc, n, "sh9"), zh[:, None] * rgb, atol=1e-5 * 3)
    # and where the normals face the sun it is the cosine law to the band limit's few %
    facing = t > 0.9
    assert facing.any()
    np.testing.assert_allclose(lm.irradiance(rc[facing], n[facing], "h6"),
                               t[facing, None] * rgb, rtol=0.08)


# ----------------------------------------------------------------------------- the box room

ALBEDO = 0.6
SKY = np.array([[1.2, 1.1, 1.3], [0.1, 0.1, 0.2], [0.6, 0.55, 0.5], [0.3, 0.2, 0.1],
                [0.05, 0, 0], [0, 0.05, 0], [-0.1, -0.1, -0.1], [0.05, 0.02, 0], [0.02, 0, 0]])


def _normal_field(uv):
    """The floor's normal map as a function: a tangent-space normal per TEXCOORD_0."""
    u, v = uv[:, 0], uv[:, 1]
    n = np.stack([0.45 * np.sin(2 * np.pi * 2 * u), 0.45 * np.cos(2 * np.pi * 3 * v),
                  np.ones_like(u)], 1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _room():
    """A 2 × 2 room, walls 1 high facing inwards, no ceiling; the floor has a normal map and
    TEXCOORD_0 with u along +x and v along −y (so its tangent frame is the world frame)."""
    floor = _plane(uv1=False)
    n = 64
    g = (np.arange(n) + 0.5) / n
    uu, vv = np.meshgrid(g, g)
    floor.normal_texture = ((_normal_field(np.stack([uu.ravel(), vv.ravel()], 1)) + 1) / 2
                            ).reshape(n, n, 3).astype(np.float32)
    floor.base_color = np.array([ALBEDO, ALBEDO, ALBEDO, 1.0])
    walls = []
    for k in range(4):
        a = k * np.pi / 2
        r = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        q = np.array([[-1, -1, 0], [1, -1, 0], [1, -1, 1], [-1, -1, 1]], float) @ r.T
        walls.append(q)
    pos = np.concatenate(walls)
    faces = np.concatenate([[[4 * k, 4 * k + 2, 4 * k + 1], [4 * k, 4 * k + 3, 4 * k + 2]]
                            for k in range(4)])
    wall = Primitive(pos, faces, base_color=np.array([ALBEDO, ALBEDO, ALBEDO, 1.0]))
    return LightmapScene([floor, wall])


class _Tracer:
    """An independent path tracer: embreex directly, cosine-weighted sampling."""

    def __init__(self, scene):
        from embreex import mesh_construction, rtcore_scene

        self.v = np.concatenate([p.positions for p in scene.primitives]).astype(np.float32)
        off = np.cumsum([0] + [len(p.positions) for p in scene.primitives])
        self.f = np.concatenate([p.faces + o for p, o in zip(scene.primitives, off,
                                                             strict=False)]).astype(np.int32)
        self.scene = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(self.scene, self.v, self.f)
        t = self.v[self.f].astype(np.float64)
        fn = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        self.fn = fn / np.linalg.norm(fn, axis=1, keepdims=True)
        self.rng = np.random.default_rng(7)

    def cosine(self, n, k):
        """k cosine-distributed directions around each unit n (N, 3) → (N, k, 3)."""
        u1, u2 = self.rng.random((len(n), k)), self.rng.random((len(n), k))
        r, phi = np.sqrt(u1), 2 * np.pi * u2
        local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u1)], -1)
        a = np.where(np.abs(n[:, :1]) > 0.9, [[0.0, 1, 0]], [[1.0, 0, 0]])
        t = np.cross(a, n)
        t /= np.linalg.norm(t, axis=1, keepdims=True)
        b = np.cross(n, t)
        return (local[..., :1] * t[:, None] + local[..., 1:2] * b[:, None]
                + local[..., 2:] * n[:, None])

    def irradiance(self, p, n, geo, k, bounces, sun=None):
        """E at points p for shading normals n on surfaces of geometric normal geo; ``sun``:
        (direction towards it, RGB irradiance), with a shadow ray."""
        d = self.cosine(n, k)
        o = np.repeat(p + 1e-4 * geo, k, 0)
        dd = d.reshape(-1, 3)
        r = self.scene.run(o.astype(np.float32), dd.astype(np.float32), output=1)
        face, dist = r["primID"], r["tfar"]
        radiance = sh_basis(dd, 2) @ SKY
        radiance[face >= 0] = 0.0
        above = (dd * np.repeat(geo, k, 0)).sum(1) > 0
        radiance[~above] = 0.0
        hit = np.flatnonzero((face >= 0) & above)
        if bounces > 0 and len(hit):
            fn = self.fn[face[hit]]
            front = (fn * dd[hit]).sum(1) < 0
            hit = hit[front]
            q = o[hit] + dist[hit, None] * dd[hit]
            e = self.irradiance(q, self.fn[face[hit]], self.fn[face[hit]], 16, bounces - 1,
                                sun)
            radiance[hit] = ALBEDO / np.pi * e
        e = np.pi * radiance.reshape(len(p), k, 3).mean(1)
        if sun is not None:
            s, rgb = np.asarray(sun[0], float), np.asarray(sun[1], float)
            s = s / np.linalg.norm(s)
            o = (p + 1e-4 * geo).astype(np.float32)
            free = self.scene.run(o, np.tile(s, (len(p), 1)).astype(np.float32),
                                  query="OCCLUDED") == -1
            lit = free & (geo @ s > 0)
            e = e + np.where(lit, np.maximum(n @ s, 0.0), 0.0)[:, None] * rgb
        return e


@pytest.fixture(scope="module")
def room_bake():
    scene = _room()
    lm = bake_lightmap(scene, SKY, LightmapSettings(size=40, samples=400, bounces=1, seed=3))
    return scene, lm


def test_the_floor_frame_is_the_normal_maps_tangent_frame(room_bake):
    _, lm = room_bake
    floor = lm.texels.prim == 0
    np.testing.assert_allclose(lm.texels.frames[floor], np.broadcast_to(np.eye(3), (
        floor.sum(), 3, 3)), atol=1e-9)


def test_encodings_against_an_independent_path_tracer(room_bake):
    scene, lm = room_bake
    tx = lm.texels
    inner = np.abs(tx.points[:, :2]).max(1) < 0.85
    pick = np.flatnonzero((tx.prim == 0) & tx.inside & inner)
    pick = pick[np.random.default_rng(1).choice(len(pick), 40, replace=False)]
    n_ts = _normal_field(tx.uv0[pick])
    n_world = n_ts  # the floor's frame is the world frame (previous test)
    ref = _Tracer(scene).irradiance(tx.points[pick], n_world,
                                    np.tile([0.0, 0, 1], (len(pick), 1)), 3000, 1)
    rows = []
    for enc in ENCODINGS:
        got = lm.irradiance(tx.rc[pick], n_ts, enc)
        rel = np.abs(got - ref).mean(1) / ref.mean(1)
        rows.append((enc, rel.mean(), np.percentile(rel, 95)))
    print("\nencoding   mean rel. error   95th pct (40 floor texels, 1 bounce, 400 rays)")
    for enc, m, p in rows:
        print(f"{enc:8s}   {100 * m:6.2f} %          {100 * p:6.2f} %")
    err = {enc: (m, p) for enc, m, p in rows}
    assert err["h6"][1] < 0.10  # H6 within 10 % where texels are converged
    # §5's ranking where this scene follows it: H6 beats the 3- and 4-coefficient SH-family
    # rivals and plain light mapping, and stays within a few % of L2 SH (it is derived from it)
    for rival in ("plain", "hl2", "sh4"):
        assert err["h6"][0] < err[rival][0], rival
    assert err["h6"][0] < err["sh9"][0] + 0.03


def test_the_hit_kernel_equals_its_numpy_reference():
    from shprobe.lightmaps.encode import hit_sums, hit_sums_numpy
    from shprobe.lightmaps.gather import Gathered

    rng = np.random.default_rng(0)
    m, p = 500, 40
    g = Gathered(np.zeros((p, 9, 6)), np.zeros((p, 6)), rng.integers(0, p, m),
                 rng.random((m, 2)).astype(np.float32), rng.random((m, 3)).astype(np.float32),
                 np.zeros((m, 3), np.float32), np.ones(p, bool), np.zeros((2, p, 6)))
    image = rng.normal(size=(7, 5, 6))
    factor = rng.normal(size=(m, 9))
    np.testing.assert_allclose(hit_sums(g, image, factor), hit_sums_numpy(g, image, factor),
                               rtol=1e-10, atol=1e-12)


def test_a_sun_with_shadows_against_the_path_tracer():
    """A low sun: the walls shadow part of the floor; the plain lightmap (no band limit) and
    H6 (the sun's clamped cosine to l ≤ 2) against the tracer with its own shadow rays."""
    scene = _room()
    sun = ((0.6, 0.3, 0.75), (2.0, 1.8, 1.5))
    lm = bake_lightmap(scene, SKY, LightmapSettings(size=40, samples=256, bounces=1, seed=3,
                                                    sun=sun))
    tx = lm.texels
    inner = np.abs(tx.points[:, :2]).max(1) < 0.85
    pick = np.flatnonzero((tx.prim == 0) & tx.inside & inner)
    pick = pick[np.random.default_rng(2).choice(len(pick), 40, replace=False)]
    up = np.tile([0.0, 0, 1], (len(pick), 1))
    tracer = _Tracer(scene)
    n_ts = _normal_field(tx.uv0[pick])
    ref_up = tracer.irradiance(tx.points[pick], up, up, 3000, 1, sun)
    ref_n = tracer.irradiance(tx.points[pick], n_ts, up, 3000, 1, sun)
    s = np.asarray(sun[0]) / np.linalg.norm(sun[0])
    shade = tracer.scene.run((tx.points[pick] + 1e-4 * up).astype(np.float32),
                             np.tile(s, (len(pick), 1)).astype(np.float32),
                             query="OCCLUDED") != -1
    assert 0 < shade.sum() < len(pick)  # some picked texels lie in the walls' shadow
    rel = {}
    for enc, n, ref in (("plain", up, ref_up), ("h6", n_ts, ref_n), ("sh9", n_ts, ref_n),
                        ("h4", n_ts, ref_n)):
        got = lm.irradiance(tx.rc[pick], n, enc)
        r = np.abs(got - ref).mean(1) / ref.mean(1)
        rel[enc] = (r.mean(), np.percentile(r, 95))
    print("\nbox room under sky and a low sun (40 floor texels, some in shadow):")
    for enc, (m, p) in rel.items():
        print(f"{enc:6s} mean {100 * m:5.2f} %   95th pct {100 * p:5.2f} %")
    assert rel["plain"][0] < 0.05
    assert rel["h6"][0] < 0.10



def test_texels_per_unit_sets_the_density():
    """The room's 12 m² at 10 texels per metre: about 1,200 covered texels (xatlas's charts
    and their borders add some)."""
    lm = bake_lightmap(_room(), SKY, LightmapSettings(texels_per_unit=10.0, samples=4,
                                                      bounces=0))
    assert 0.9 * 1200 < lm.texels.count < 1.6 * 1200, lm.texels.count


def test_the_blocked_ray_kernel_equals_its_numpy_reference():
    from shprobe.lightmaps._kernels import blocked_sums
    from shprobe.lightmaps.gather import blocked_sums_numpy

    rng = np.random.default_rng(1)
    n, s, faces, c_count = 6, 16, 10, 6
    dt = rng.normal(size=(n, s, 3))
    dt /= np.linalg.norm(dt, axis=2, keepdims=True)
    dw = rng.normal(size=(n, s, 3))
    dw /= np.linalg.norm(dw, axis=2, keepdims=True)
    below = rng.random((n, s)) < 0.2
    f = np.where(rng.random((n, s)) < 0.5, rng.integers(0, faces, (n, s)), -1)
    fn = rng.normal(size=(faces, 3))
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    sky = rng.normal(size=(9, c_count))
    sh, e, half = np.zeros((n, 9, c_count)), np.zeros((n, c_count)), np.zeros((2, n, c_count))
    front, back = np.empty((n, s), bool), np.empty(n)
    wt = rng.random((n, s))
    blocked_sums(dt, dw, below, f, fn, sky, wt, sh, e, half, front, back)
    want = blocked_sums_numpy(dt, dw, below, f, fn, sky, wt)
    for got, ref in zip((-sh, -e, -half, front, back), want, strict=True):
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)
