"""PRT run-time model switching, interreflection strength, albedo readings, seeds and threads
(Lisle & Huang 2007 §4): one bake gives every model up to the baked one, equal to separate bakes;
the open spherical bowl pins the direct term and the bounce ratio to closed forms.
"""

from __future__ import annotations

import importlib
import json
import threading

import numpy as np
import pytest
import trimesh

from shprobe.errors import ShprobeError
from shprobe.prt import bake, load_transfer, relight, sample_directions
from tests.prt.test_prt import box_scene, icosphere, uniform_light

FOUR_PI = 4.0 * np.pi
bake_module = importlib.import_module("shprobe.prt.trace")


# ----------------------------------------------------------------------------- model switching


@pytest.fixture(scope="module")
def box_bakes():
    """The concave box-over-plane scene (shadows and bounces), coloured box: separate bakes of
    every model with the same seed and samples."""
    meshes, _, nplane = box_scene(res=16)
    kw = dict(lmax=3, mesh_albedo=[0.7, (0.9, 0.5, 0.2)])
    ray = dict(samples=256, seed=4, **kw)
    return {
        "un": bake(meshes, mode="unshadowed", **kw),
        "sh": bake(meshes, mode="shadowed", **ray),
        "ir": [bake(meshes, mode="interreflected", bounces=k, **ray) for k in range(4)],
        "nplane": nplane,
    }


def test_one_bake_gives_every_model_exactly(box_bakes, tmp_path):
    un, sh, ir = box_bakes["un"], box_bakes["sh"], box_bakes["ir"]
    full = ir[3]
    assert full.modes == ("unshadowed", "shadowed", "interreflected")
    assert full.transfer.shape == (full.n_vertices, 16, 3)  # coloured box: three channels
    path = tmp_path / "ir.npz"
    full.save(path)
    for t in (full, load_transfer(path)):
        # shadowed = bounce 0 of the interreflected bake, bit for bit
        np.testing.assert_array_equal(t.select("shadowed"), sh.transfer)
        # bounces = k: equal to a bake with k bounces
        for k in range(4):
            np.testing.assert_array_equal(t.select(bounces=k), ir[k].transfer)
            np.testing.assert_array_equal(t.select("interreflected", k), ir[k].transfer)
        np.testing.assert_array_equal(t.select(), ir[3].transfer)
        # unshadowed from any bake = the analytic unshadowed bake
        np.testing.assert_array_equal(t.select("unshadowed"), un.transfer)
    np.testing.assert_array_equal(sh.select("unshadowed"), un.transfer)
    # through relight, with a rotation and a lower degree
    L = np.random.default_rng(2).normal(size=(16, 3))
    R = trimesh.transformations.rotation_matrix(0.4, [1, 1, 0])[:3, :3]
    np.testing.assert_array_equal(relight(full, L, R, lmax=2, mode="shadowed"),
                                  relight(sh, L, R, lmax=2))
    np.testing.assert_array_equal(relight(full, L, R, bounces=1), relight(ir[1], L, R))
    np.testing.assert_array_equal(relight(full, L, R, mode="unshadowed"), relight(un, L, R))
    # the models differ where they should: the plane under the box sees bounced light
    n = box_bakes["nplane"]
    b = [relight(full, uniform_light(), bounces=k)[:n, 0] for k in range(2)]
    assert (b[1] - b[0]).max() > 1e-3


def test_models_a_file_cannot_give_are_refused(box_bakes):
    un, sh, ir = box_bakes["un"], box_bakes["sh"], box_bakes["ir"]
    assert un.modes == ("unshadowed",) and sh.modes == ("unshadowed", "shadowed")
    with pytest.raises(ShprobeError, match="baked unshadowed"):
        un.select("shadowed")
    with pytest.raises(ShprobeError, match="baked unshadowed"):
        relight(un, uniform_light(), mode="interreflected")
    with pytest.raises(ShprobeError, match="baked shadowed"):
        sh.select("interreflected")
    np.testing.assert_array_equal(sh.select("interreflected", 0), sh.transfer)  # 0 bounces
    with pytest.raises(ShprobeError, match="2 bounces; it cannot give 3"):
        ir[2].select(bounces=3)
    with pytest.raises(ShprobeError, match="interreflected model"):
        ir[2].select("shadowed", bounces=1)
    with pytest.raises(ShprobeError, match="bounces must be"):
        ir[2].select(bounces=-1)
    with pytest.raises(ShprobeError, match="unknown PRT mode"):
        ir[2].select("glossy")
    with pytest.raises(ShprobeError, match="of a Transfer"):
        relight(sh.transfer, uniform_light(), mode="shadowed")


def test_format_1_files_still_load(box_bakes, tmp_path):
    """A file of the old format (one ``transfer`` array of the baked model) loads; it gives its
    own model and the analytic unshadowed one, and refuses the others with a clear error."""
    for t, name in ((box_bakes["sh"], "shadowed"), (box_bakes["ir"][2], "interreflected")):
        meta = {**t.metadata, "format": "shprobe-prt", "version": 1}
        p = tmp_path / f"{name}.npz"
        np.savez(p, transfer=t.transfer, vertices=t.vertices, normals=t.normals, faces=t.faces,
                 albedo=t.albedo, metadata=np.array(json.dumps(meta)))
        old = load_transfer(p)
        np.testing.assert_array_equal(old.transfer, t.transfer)
        np.testing.assert_array_equal(old.select("unshadowed"), box_bakes["un"].transfer)
    for t in (old, load_transfer(old.save(tmp_path / "resaved.npz"))):  # saved again: same
        np.testing.assert_array_equal(t.select(bounces=2), box_bakes["ir"][2].transfer)
        with pytest.raises(ShprobeError, match="format-1"):
            t.select("shadowed")
        with pytest.raises(ShprobeError, match="format-1"):
            t.select(bounces=1)
        with pytest.raises(ShprobeError, match="baked with 2 bounces"):
            t.select(bounces=3)
    meta["version"] = 7
    np.savez(p, transfer=t.transfer, vertices=t.vertices, normals=t.normals, faces=t.faces,
             albedo=t.albedo, metadata=np.array(json.dumps(meta)))
    with pytest.raises(ShprobeError, match="format 7 is not supported"):
        load_transfer(p)


# ----------------------------------------------------------------------------- bounce strength


def open_bowl(n_theta: int = 16, n_phi: int = 64) -> trimesh.Trimesh:
    """The lower half (y ≤ 0) of the unit sphere, rim exactly on y = 0, faces wound and vertex
    normals pointing inward (to the centre): an open hemispherical bowl."""
    th = np.linspace(0.0, np.pi / 2, n_theta + 1)[1:]  # polar angle from −Y
    ph = 2.0 * np.pi * np.arange(n_phi) / n_phi
    T, P = np.meshgrid(th, ph, indexing="ij")
    ring = np.stack([np.sin(T) * np.cos(P), -np.cos(T), np.sin(T) * np.sin(P)], -1)
    v = np.vstack([[0.0, -1.0, 0.0], ring.reshape(-1, 3)])

    def idx(i, j):
        return 1 + i * n_phi + j % n_phi

    f = [[0, idx(0, j), idx(0, j + 1)] for j in range(n_phi)]
    for i in range(n_theta - 1):
        for j in range(n_phi):
            f += [[idx(i, j), idx(i + 1, j), idx(i, j + 1)],
                  [idx(i, j + 1), idx(i + 1, j), idx(i + 1, j + 1)]]
    f = np.array(f)
    m = trimesh.Trimesh(v, f, process=False)
    if np.mean(np.einsum("ij,ij->i", m.face_normals, m.triangles_center)) > 0:
        m = trimesh.Trimesh(v, f[:, ::-1], process=False)
    m.vertex_normals = -v
    return m


def test_open_bowl_direct_and_bounces_match_closed_form():
    """Inside a sphere of radius R the form factor from a point p to an element dA' at q is
    cos θ cos θ' dA'/(π r²) with cos θ = cos θ' = r/(2R) (the chord meets both radii at the same
    angle), i.e. dA'/(4πR²) for every p. So from every point of the bowl the cosine-weighted
    fraction of the hemisphere leaving through the opening (where the removed cap, area 2πR²,
    would be) is f = 2πR²/4πR² = 1/2, and 1 − f lands on the bowl.

    Under uniform unit radiance with albedo ρ (transfer scale ρ/π ∫ L V cos, LH §4):
    direct B₀ = ρ/π · π f = ρ f everywhere; every bounce gathers the previous (uniform) one over
    1 − f: B_{k+1} = ρ (1 − f) B_k. With ρ = 0.6: B₀ = 0.3, ratio 0.3, cumulative
    0.3, 0.39, 0.417, 0.4251. A missing or doubled ρ/π, or a halved bounce, is off by ≥ 30 %.

    Monte Carlo tolerance: per vertex the direct term is a mean of X = 4ρ max(0, n·ω) 1_open(ω)
    over N = 2048 directions; from the bottom vertex (opening = the 45° cone about n)
    E X² = 16ρ²/(4π) · 2π(1 − cos³45°)/3, σ = 0.73, so plain MC has σ/√N = 5.4 % of B₀ per
    vertex and 3σ/√(N V) = 0.5 % for the mean of V = 1025 vertices. The randomised Fibonacci set
    does better (observed: worst vertex 1.8 %, mean 0.02 %). Asserted: mean within 1 %, every
    vertex within 5 %; the bounce ratio (mean of added over mean of previous) within 1 %.
    """
    rho, f = 0.6, 0.5
    m = open_bowl()
    n_samples = 2048
    t = bake(m, mode="interreflected", lmax=0, samples=n_samples, bounces=3, albedo=rho,
             seed=1)
    assert t.n_vertices == 1025
    ex2 = 16 * rho**2 / FOUR_PI * 2 * np.pi * (1 - np.cos(np.pi / 4) ** 3) / 3
    sigma = np.sqrt(ex2 - (rho * f) ** 2)
    assert 0.05 < sigma / np.sqrt(n_samples) / (rho * f) < 0.06  # the plain-MC figure above
    b = [relight(t, uniform_light(), bounces=k)[:, 0].astype(np.float64) for k in range(4)]
    direct = b[0]
    assert abs(direct.mean() / (rho * f) - 1) < 0.01
    assert np.abs(direct / (rho * f) - 1).max() < 0.05
    added = [direct] + [b[k + 1] - b[k] for k in range(3)]
    for k in range(3):
        ratio = added[k + 1].mean() / added[k].mean()
        assert abs(ratio / (rho * (1 - f)) - 1) < 0.01, (k, ratio)
    for k in range(4):
        closed = rho * f * sum((rho * (1 - f)) ** j for j in range(k + 1))
        assert abs(b[k].mean() / closed - 1) < 0.01, (k, b[k].mean(), closed)
    # ρ enters each bounce once: with ρ = 0.3 the ratio halves and the direct term halves
    t2 = bake(m, mode="interreflected", lmax=0, samples=n_samples, bounces=1, albedo=0.3,
              seed=1)
    c = [relight(t2, uniform_light(), bounces=k)[:, 0].astype(np.float64) for k in range(2)]
    np.testing.assert_allclose(c[0], direct / 2, rtol=1e-5)
    assert abs((c[1] - c[0]).mean() / c[0].mean() / (0.3 * (1 - f)) - 1) < 0.01


# ----------------------------------------------------------------------------- albedo readings


def three_spheres():
    """Three unit spheres 50 apart (each hides < 1e-3 of another's sky)."""
    out = []
    for k in range(3):
        s = icosphere()
        s.apply_translation([50.0 * k, 0.0, 0.0])
        out.append(s)
    return out


def test_per_mesh_albedo_is_not_read_as_rgb():
    """Three meshes: ``mesh_albedo=[a, b, c]`` is one grey value per mesh, ``albedo=(r, g, b)``
    one RGB for all. Checked on the stored albedo and on the light: a closed convex mesh under
    uniform unit radiance reflects exactly ρ (ρ/π · π, shadowed bake)."""
    meshes = three_spheres()
    nv = len(meshes[0].vertices)
    per = bake(meshes, mode="shadowed", lmax=0, samples=256, mesh_albedo=[0.1, 0.5, 0.9])
    assert per.transfer.ndim == 2  # every mesh grey: one channel
    want = np.repeat([0.1, 0.5, 0.9], nv)
    np.testing.assert_array_equal(per.albedo, np.repeat(want[:, None], 3, axis=1))
    out = relight(per, uniform_light())
    np.testing.assert_allclose(out[:, 0], want, rtol=0.02)
    for rgb in ((0.1, 0.5, 0.9), [0.1, 0.5, 0.9], np.array([0.1, 0.5, 0.9])):
        col = bake(meshes, mode="shadowed", lmax=0, samples=256, albedo=rgb)
        np.testing.assert_array_equal(col.albedo, np.tile([0.1, 0.5, 0.9], (3 * nv, 1)))
        np.testing.assert_allclose(relight(col, uniform_light()),
                                   np.tile([0.1, 0.5, 0.9], (3 * nv, 1)), rtol=0.02)
    # mixed per-mesh entries: grey, RGB, per-vertex, default
    pv = np.linspace(0.0, 1.0, nv)
    mix = bake(meshes, mode="unshadowed", lmax=0, mesh_albedo=[0.3, (0.2, 0.4, 0.6), pv])
    np.testing.assert_array_equal(mix.albedo[:nv], 0.3)
    np.testing.assert_array_equal(mix.albedo[nv:2 * nv], np.tile([0.2, 0.4, 0.6], (nv, 1)))
    np.testing.assert_array_equal(mix.albedo[2 * nv:, 1], pv)
    dflt = bake(meshes, mode="unshadowed", lmax=0, mesh_albedo=[None, 0.5, None])
    np.testing.assert_array_equal(dflt.albedo[:, 0], np.repeat([0.8, 0.5, 0.8], nv))


def test_three_vertex_mesh_rgb_and_per_vertex_readings():
    tri = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 0, -1]], [[0, 1, 2]], process=False)
    assert np.allclose(tri.vertex_normals, [0, 1, 0])
    rgb = bake(tri, mode="unshadowed", lmax=0, mesh_albedo=[[0.1, 0.2, 0.3]])
    np.testing.assert_array_equal(rgb.albedo, np.tile([0.1, 0.2, 0.3], (3, 1)))
    grey = bake(tri, mode="unshadowed", lmax=0, mesh_albedo=[[[0.1], [0.2], [0.3]]])
    np.testing.assert_array_equal(grey.albedo, np.repeat([[0.1], [0.2], [0.3]], 3, axis=1))


def test_albedo_arguments_are_checked():
    meshes = three_spheres()
    with pytest.raises(ShprobeError, match="one value for every mesh"):
        bake(meshes, mode="unshadowed", lmax=0, albedo=[0.1, 0.5])
    with pytest.raises(ShprobeError, match="one value for every mesh"):
        bake(meshes[0], mode="unshadowed", lmax=0, albedo=np.full(len(meshes[0].vertices), .5))
    with pytest.raises(ShprobeError, match="2 entries for 3 meshes"):
        bake(meshes, mode="unshadowed", lmax=0, mesh_albedo=[0.1, 0.5])
    with pytest.raises(ShprobeError, match="not both"):
        bake(meshes, mode="unshadowed", lmax=0, albedo=0.5, mesh_albedo=[0.1, 0.5, 0.9])
    with pytest.raises(ShprobeError, match=r"\[0, 1\]"):
        bake(meshes, mode="unshadowed", lmax=0, mesh_albedo=[0.1, 1.5, 0.9])


def test_vertex_colours_are_the_default_albedo(tmp_path):
    """A mesh's own vertex colours (8-bit sRGB) become its albedo, decoded to linear by the
    IEC 61966-2-1 formula (written out here); an explicit albedo wins."""
    m = icosphere()
    rng = np.random.default_rng(0)
    c8 = rng.integers(0, 256, size=(len(m.vertices), 3))
    m.visual.vertex_colors = np.hstack([c8, np.full((len(c8), 1), 255)]).astype(np.uint8)
    p = tmp_path / "coloured.ply"
    m.export(p)
    c = c8 / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    t = bake(p, mode="unshadowed", lmax=1)
    np.testing.assert_allclose(t.albedo, lin, atol=1e-6)
    assert t.transfer.shape[2:] == (3,)
    assert np.all(bake(p, mode="unshadowed", lmax=1, albedo=0.5).albedo == 0.5)
    plain = icosphere()
    assert np.all(bake(plain, mode="unshadowed", lmax=0).albedo == 0.8)


def test_face_and_material_colours_are_the_default_albedo(tmp_path):
    """As the renderer reads them: PLY face colours (sRGB) averaged over each vertex's faces,
    an OBJ's Kd (linear) on every vertex. Files written by hand."""
    quad = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
    (tmp_path / "k.mtl").write_text("newmtl m\nKd 0.8 0.4 0.2\n")
    (tmp_path / "k.obj").write_text(f"mtllib k.mtl\n{quad}usemtl m\nf 1 2 3\nf 1 3 4\n")
    np.testing.assert_allclose(bake(tmp_path / "k.obj", mode="unshadowed", lmax=1).albedo,
                               np.tile([0.8, 0.4, 0.2], (4, 1)), atol=3e-3)
    (tmp_path / "f.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
        "-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n3 0 1 2 255 0 0\n3 0 2 3 0 0 255\n")
    t = bake(tmp_path / "f.ply", mode="unshadowed", lmax=1)
    # vertices 0 and 2 touch both faces, 1 only the red one, 3 only the blue one
    red, blue, half = [1.0, 0, 0], [0, 0, 1.0], [0.5, 0, 0.5]
    order = np.argsort(t.vertices[:, 0] * 10 + t.vertices[:, 1])  # (-1,-1) (-1,1) (1,-1) (1,1)
    np.testing.assert_allclose(t.albedo[order], [half, blue, red, half], atol=1e-6)


# ----------------------------------------------------------------------------- seeds, threads


def test_negative_or_non_integer_seed_is_refused():
    m = icosphere()
    for seed in (-1, 1.5, "3", True):
        with pytest.raises(ShprobeError, match="seed"):
            bake(m, mode="shadowed", lmax=1, samples=64, seed=seed)
    with pytest.raises(ShprobeError, match="seed"):
        sample_directions(64, -5)
    with pytest.raises(ShprobeError, match="threads"):
        bake(m, mode="shadowed", lmax=1, samples=64, threads=0)
    big = bake(m, mode="shadowed", lmax=1, samples=64, seed=2**40)
    assert big.metadata["seed"] == 2**40


def test_threads_set_the_workers_and_not_the_result(monkeypatch):
    """threads=1 casts every ray in the calling thread; threads=3 in three workers running at
    once (each worker's first ray batch waits at a 3-party barrier: it breaks, failing the test,
    unless three workers exist) and never more; the transfer is the same bit for bit."""
    monkeypatch.setattr(bake_module, "RAYS_PER_CHUNK", 4096)  # many work items
    seen: list[int] = []
    state = {"active": 0, "peak": 0, "barrier": None}
    lock = threading.Lock()
    local = threading.local()
    inner = bake_module.RayCaster.first_hit_local

    def spy(self, o, d):
        with lock:
            seen.append(threading.get_ident())
            state["active"] += 1
            state["peak"] = max(state["peak"], state["active"])
        if state["barrier"] is not None and not getattr(local, "waited", False):
            local.waited = True
            state["barrier"].wait()
        try:
            return inner(self, o, d)
        finally:
            with lock:
                state["active"] -= 1

    monkeypatch.setattr(bake_module.RayCaster, "first_hit_local", spy)
    meshes, albedo, _ = box_scene(res=12)
    kw = dict(mode="interreflected", lmax=2, samples=128, bounces=2, mesh_albedo=albedo, seed=3)
    one = bake(meshes, threads=1, **kw)
    assert set(seen) == {threading.get_ident()} and len(seen) > 10 and state["peak"] == 1
    seen.clear()
    state.update(peak=0, barrier=threading.Barrier(3, timeout=20))
    three = bake(meshes, threads=3, **kw)
    assert len(set(seen)) == 3 and threading.get_ident() not in seen
    assert state["peak"] == 3
    np.testing.assert_array_equal(one.traced, three.traced)


def test_tampered_layers_are_refused(box_bakes, tmp_path):
    path = tmp_path / "t.npz"
    box_bakes["ir"][2].save(path)
    with np.load(path) as d:
        arrays = dict(d)
    for counts in ([0, 2, 1], [0, 1, 3], [-1, 0, 1]):
        np.savez(tmp_path / "bad.npz", **{**arrays, "bounce_counts": np.array(counts)})
        with pytest.raises(ShprobeError, match="corrupt file"):
            load_transfer(tmp_path / "bad.npz")
    np.savez(tmp_path / "bad.npz", **{**arrays, "traced": arrays["traced"][:2]})
    with pytest.raises(ShprobeError, match="layers"):
        load_transfer(tmp_path / "bad.npz")
