"""The one ray caster (scene.raycast): first hits and occlusion against closed-form geometry,
precision far from the origin, concurrent queries, bad input."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.scene import RayCaster, sphere_mesh

#: two triangles in the plane z = 0, under the diagonals of the unit squares at x = 0 and 1
VERTS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0]], float)
FACES = np.array([[0, 1, 2], [1, 4, 5]])


def _down_rays(n, seed, shift=0.0, scale=1.0):
    """Rays straight down (−z) onto the plane from random (x, y) in [−0.2, 2.2] × [−0.2, 1.2]."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform([-0.2, -0.2], [2.2, 1.2], size=(n, 2))
    o = np.c_[xy, np.full(n, 3.0)] * scale + shift
    return xy, o, np.tile([0.0, 0.0, -1.0], (n, 1))


def _closed_form(xy):
    """Face and Embree (u, v) of the point (x, y) on VERTS/FACES: p = (1−u−v)p0 + u p1 + v p2."""
    x, y = xy[:, 0], xy[:, 1]
    face = np.full(len(xy), -1)
    u = np.zeros(len(xy))
    v = np.zeros(len(xy))
    t0 = (x >= 0) & (x <= 1) & (y >= 0) & (y <= x)  # (0,0) (1,0) (1,1): u = x − y, v = y
    face[t0], u[t0], v[t0] = 0, x[t0] - y[t0], y[t0]
    t1 = (x <= 2) & (y >= 0) & (y <= x - 1)  # (1,0) (2,0) (2,1): u = x − 1 − y, v = y
    face[t1], u[t1], v[t1] = 1, x[t1] - 1 - y[t1], y[t1]
    return face, u, v


def _away_from_edges(xy):
    x, y = xy[:, 0], xy[:, 1]
    d = np.minimum.reduce([np.abs(x), np.abs(x - 1), np.abs(x - 2), np.abs(y), np.abs(y - 1),
                           np.abs(y - x) / np.sqrt(2), np.abs(y - x + 1) / np.sqrt(2)])
    return d > 1e-4


@pytest.mark.parametrize("shift, scale", [(0.0, 1.0), (1e6, 1.0), (-3e4, 1e-3)])
def test_first_hit_is_the_closed_form(shift, scale):
    """Faces and barycentrics of rays onto two triangles, also for a mesh a million units from
    the origin (float32 there resolves 0.06 units: without the caster's local frame u and v
    would be off by that much) and a millimetre-sized one."""
    caster = RayCaster(VERTS * scale + shift, FACES)
    xy, o, d = _down_rays(4000, seed=1, shift=shift, scale=scale)
    keep = _away_from_edges(xy)
    face, u, v = caster.first_hit(o, d)
    want_f, want_u, want_v = _closed_form(xy)
    np.testing.assert_array_equal(face[keep], want_f[keep])
    hit = keep & (want_f >= 0)
    assert hit.sum() > 1000 and (keep & (want_f < 0)).sum() > 500
    np.testing.assert_allclose(u[hit], want_u[hit], atol=2e-6)
    np.testing.assert_allclose(v[hit], want_v[hit], atol=2e-6)
    # occlusion agrees with the first hits; rays pointing away hit nothing
    np.testing.assert_array_equal(caster.occluded(o, d)[keep], want_f[keep] >= 0)
    assert not caster.occluded(o, -d).any()
    assert (caster.first_hit(o, -d)[0] == -1).all()


def test_occlusion_of_a_sphere_matches_the_ray_sphere_test():
    """Rays from outside a tessellated unit sphere: blocked exactly when the line passes the
    centre closer than the radius (away from the grazing band the tessellation blurs)."""
    caster = RayCaster.from_mesh(sphere_mesh(5))
    rng = np.random.default_rng(3)
    o = rng.normal(size=(20000, 3))
    o *= (rng.uniform(1.2, 3.0, len(o)) / np.linalg.norm(o, axis=1))[:, None]
    d = rng.normal(size=o.shape) - o  # aimed roughly at the sphere: both outcomes are common
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t = -(o * d).sum(1)  # closest approach along the ray
    miss_dist = np.linalg.norm(o + np.maximum(t, 0)[:, None] * d, axis=1)
    want = miss_dist < 1.0
    clear = np.abs(miss_dist - 1.0) > 2e-3  # icosphere level 5: chord sag ≈ 3e-4
    got = caster.occluded(o, d)
    np.testing.assert_array_equal(got[clear], want[clear])
    assert 0.2 < want.mean() < 0.8


def test_concurrent_queries_equal_serial_ones():
    """Queries from 8 threads at once, starting right after construction (the BVH is committed
    there, not lazily by whichever thread comes first), give the serial answers bit for bit."""
    caster = RayCaster.from_mesh(sphere_mesh(4))
    rng = np.random.default_rng(7)
    batches = []
    for _ in range(32):
        o = rng.normal(size=(5000, 3)) * 2.0
        d = rng.normal(size=(5000, 3))
        batches.append((o, d))
    with ThreadPoolExecutor(8) as pool:
        par = list(pool.map(lambda b: caster.first_hit(*b), batches))
        occ = list(pool.map(lambda b: caster.occluded(*b), batches))
    for (o, d), (f, u, v), oc in zip(batches, par, occ, strict=True):
        f1, u1, v1 = caster.first_hit(o, d)
        np.testing.assert_array_equal(f, f1)
        np.testing.assert_array_equal(u, u1)
        np.testing.assert_array_equal(v, v1)
        np.testing.assert_array_equal(oc, caster.occluded(o, d))
        np.testing.assert_array_equal(oc, f1 >= 0)


def test_local_frame_and_empty_batches():
    moved = VERTS + np.array([10.0, -4.0, 2.0])
    caster = RayCaster(moved, FACES)
    p = caster.local(moved)
    assert p.dtype == np.float32 and p.flags.c_contiguous
    np.testing.assert_allclose(p.min(0), [-0.5, -0.25, 0.0])
    np.testing.assert_allclose(p.max(0), [0.5, 0.25, 0.0])
    f, u, v = caster.first_hit(np.zeros((0, 3)), np.zeros((0, 3)))
    assert f.shape == u.shape == v.shape == (0,)
    assert caster.occluded(np.zeros((0, 3)), np.zeros((0, 3))).shape == (0,)
    assert repr(caster) == "RayCaster(2 triangles)"


@pytest.mark.parametrize("verts, faces, msg", [
    (VERTS[:, :2], FACES, r"vertices \(V, 3\)"),
    (VERTS, FACES[:0], "no triangles"),
    (VERTS, FACES + 5, "outside 0..5"),
    (np.where(VERTS == 1, np.nan, VERTS), FACES, "non-finite"),
])
def test_bad_meshes_are_refused_in_one_line(verts, faces, msg):
    with pytest.raises(ShprobeError, match=msg) as e:
        RayCaster(verts, faces)
    assert "\n" not in str(e.value)


def test_offset_origin_is_put_back_where_the_step_crosses_another_part():
    """A box corner touching a ground plane, its normal pointing down: p + ε n would lie under
    the plane (open sky below); the origin is put back just above the plane. A point whose step
    crosses nothing keeps p + ε n, whatever its own part's surface does at p."""
    ground_v = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], float)
    ground_f = np.array([[0, 2, 1], [0, 3, 2]])  # normal +y
    tri_v = np.array([[0, 0, 0], [0.5, 0.5, 0], [0, 0.5, 0.5]], float)  # touches y = 0 at (0,0,0)
    v = np.concatenate([ground_v, tri_v])
    f = np.concatenate([ground_f, np.array([[4, 5, 6]])])
    rc = RayCaster(v, f)
    eps = 1e-3
    p = np.array([[0, 0, 0], tri_v.mean(0), [0.5, 0, 0.5]], float)
    n = np.array([[0, -1, 0], [0, -1, 0], [0, 1, 0]], float)
    o, crossed = rc.offset_points(p, n, eps, np.array([2, 2, 0]))
    # 1: on the triangle, touching the ground, normal down: back above the ground by eps/100
    np.testing.assert_allclose(o[0], [0, 0.01 * eps, 0], atol=1e-7)  # float32 distances
    # 2: the triangle's centroid, 1/3 above the ground: the step crosses nothing
    np.testing.assert_allclose(o[1], p[1] + eps * n[1], atol=1e-12)
    # 3: on the ground itself, normal up (its own part is not "another surface")
    np.testing.assert_allclose(o[2], p[2] + eps * n[2], atol=1e-12)
    assert crossed.tolist() == [True, False, False]
    with pytest.raises(ShprobeError, match="one face index per point"):
        rc.offset_points(p, n, eps, np.array([0, 1]))
