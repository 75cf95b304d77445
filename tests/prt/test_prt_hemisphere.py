"""The adaptive hemisphere quadrature (shprobe.prt.hemisphere) against closed forms: the map's
Jacobian, Lambert's polygon formula for ∫ V cos dω under an occluding quad, a brute-force
Fibonacci quadrature for the higher bands, and the bake that uses it."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.prt import PrtSettings, load_transfer
from shprobe.prt.directions import OFFSET_FRACTION, sample_directions
from shprobe.prt.geometry import BakeScene, mesh_hash
from shprobe.prt.hemisphere import (
    TraceContext,
    adaptive_grid,
    equal_area_hemisphere,
    trace_adaptive,
)
from shprobe.prt.trace import DenseVertices, trace_bake
from shprobe.scene.raycast import RayCaster
from shprobe.sh import sh_basis

Y00 = 0.5 / np.sqrt(np.pi)


def test_equal_area_hemisphere_jacobian():
    """|∂d/∂u × ∂d/∂v| = 2π everywhere (off the map's seams), unit vectors, z ≥ 0; the square's
    centre is the pole and its border the horizon."""
    rng = np.random.default_rng(1)
    u, v = rng.random(2000), rng.random(2000)
    h = 1e-6
    keep = np.abs(np.abs(2 * u - 1) - np.abs(2 * v - 1)) > 1e-3  # off the diagonals
    u, v = u[keep], v[keep]
    du = (equal_area_hemisphere(u + h, v) - equal_area_hemisphere(u - h, v)) / (2 * h)
    dv = (equal_area_hemisphere(u, v + h) - equal_area_hemisphere(u, v - h)) / (2 * h)
    jac = np.linalg.norm(np.cross(du, dv), axis=1)
    np.testing.assert_allclose(jac, 2 * np.pi, rtol=1e-5)
    d = equal_area_hemisphere(u, v)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    assert (d[:, 2] >= 0).all()
    np.testing.assert_allclose(equal_area_hemisphere(np.array([0.5]), np.array([0.5])),
                               [[0, 0, 1]], atol=1e-15)
    t = np.linspace(0, 1, 9)
    border = equal_area_hemisphere(np.concatenate([t, t, 0 * t, 0 * t + 1]),
                                   np.concatenate([0 * t, 0 * t + 1, t, t]))
    np.testing.assert_allclose(border[:, 2], 0.0, atol=1e-15)
    # equal areas, equal solid angles: the cap z > cos 60° (π sr) fills half of the square
    rng = np.random.default_rng(2)
    cap = (equal_area_hemisphere(rng.random(10**6), rng.random(10**6))[:, 2] > 0.5).mean()
    assert abs(cap - 0.5) < 2e-3  # 4σ
    assert adaptive_grid(8192) == 64 and adaptive_grid(32768) == 128


def lambert(poly: np.ndarray) -> float:
    """∫ n·ω dω over the solid angle of a polygon seen from the origin, n = +z (Lambert)."""
    u = poly / np.linalg.norm(poly, axis=1, keepdims=True)
    s = 0.0
    for a, b in zip(u, np.roll(u, -1, axis=0), strict=True):
        g = np.cross(a, b)
        s += np.arccos(np.clip(a @ b, -1, 1)) * g[2] / np.linalg.norm(g)
    return 0.5 * abs(s)


def slab_scene(h: float, x0: float) -> tuple[BakeScene, np.ndarray]:
    """A floor patch around vertex 8 (the origin, normal +z) and a 10 × 10 occluding quad at
    height h facing down, its edge at x = x0 (a slot between it and the floor)."""
    quad = np.array([[x0, -5, h], [5, -5, h], [5, 5, h], [x0, 5, h]], float)
    floor = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float) * 0.01
    v = np.vstack([floor, quad, [[0.0, 0.0, 0.0]]])
    f = np.array([[0, 1, 8], [1, 2, 8], [2, 3, 8], [3, 0, 8], [4, 6, 5], [4, 7, 6]])
    n = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    n[4:8] = [0.0, 0.0, -1.0]
    return BakeScene(v, n, f, np.full((len(v), 3), 0.8), mesh_hash(v, f)), quad


def adaptive_row(sc: BakeScene, grid: int, levels: int, seed: int = 0, lmax: int = 2):
    c = RayCaster(sc.vertices, sc.faces)
    rows = np.array([8])
    org = c.local(sc.vertices[rows] + [0.0, 0.0, 1e-7])
    return trace_adaptive(TraceContext(sc, c, None, map, lmax, seed), rows, org, grid, levels)


@pytest.mark.parametrize(("h", "x0", "tol"), [(1.0, -5.0, 2e-3), (0.2, -0.3, 2e-4),
                                             (0.1, 0.05, 1e-4)])
def test_adaptive_against_lambert(h, x0, tol):
    """∫ V cos dω = π − (the quad's Lambert integral): within ``tol`` at G = 128 with three
    levels, and the levels cut the level-0 grid's error several times over."""
    sc, quad = slab_scene(h, x0)
    exact = np.pi - lambert(quad)
    errs = {}
    for levels in (0, 3):
        e = [adaptive_row(sc, 128, levels, seed)[0][0, 0] / Y00 / exact - 1 for seed in range(3)]
        errs[levels] = float(np.sqrt(np.mean(np.square(e))))
    assert errs[3] < tol, errs
    assert errs[3] < errs[0] / 4, errs


def test_adaptive_higher_bands_against_fibonacci():
    """Every coefficient to lmax 2 against a brute-force Fibonacci quadrature of 2²¹
    directions of the same scene, to 1e-3 of the l = 0 coefficient (they differ by ≤ 6e-4)."""
    sc, _ = slab_scene(0.2, -0.3)
    got = adaptive_row(sc, 128, 3)[0][0]
    c = RayCaster(sc.vertices, sc.faces)
    d = sample_directions(1 << 21, 3)
    up = d[:, 2] > 0
    d = d[up]
    free = ~c.occluded(np.tile([0.0, 0.0, 1e-7], (len(d), 1)), d)
    ref = (sh_basis(d[free], 2) * d[free, 2:]).sum(0) * (4 * np.pi / (1 << 21))
    np.testing.assert_allclose(got, ref, atol=1e-3 * abs(ref[0]))


def test_bake_dense_adaptive_matches_trace(tmp_path):
    """A dense vertex on the adaptive quadrature: its shadowed row is ρ/π times
    Lambert's closed form; its first bounce is ρ/π (∫_quad cos dω) T_0(quad), as the quad's
    corners all see the same open sky below (the floor patch is ~1e-5 of it); metadata says
    which quadrature ran."""
    sc, quad = slab_scene(0.2, -0.3)
    t = trace_bake(sc, PrtSettings(mode="interreflected", lmax=2, samples=1024, bounces=1),
                   dense=DenseVertices(vertex_mask(sc, 8), 32768, "adaptive"))[0]
    meta = t.metadata["dense_quadrature"]["adaptive"]
    assert meta["grid"] == 128 and meta["levels"] == 3 and meta["rays_per_vertex"] > 128**2
    t.save(tmp_path / "t.npz")
    assert load_transfer(tmp_path / "t.npz").metadata["dense_quadrature"] == {"adaptive": meta}
    t0 = t.select("shadowed").astype(np.float64)
    eps = OFFSET_FRACTION * np.linalg.norm(np.ptp(sc.vertices, axis=0))  # the ray origin's lift
    seen = quad - [0.0, 0.0, eps]
    exact = 0.8 / np.pi * (np.pi - lambert(seen)) * Y00
    assert abs(t0[8, 0] / exact - 1) < 2e-4
    np.testing.assert_allclose(t0[4:8], t0[4:5].repeat(4, 0), rtol=1e-5, atol=1e-7)
    first = t.select().astype(np.float64)[8] - t0[8]
    np.testing.assert_allclose(first, 0.8 / np.pi * lambert(seen) * t0[4], rtol=1e-3,
                               atol=1e-3 * abs(first[0]))
    with pytest.raises(ShprobeError, match="dense quadrature"):
        DenseVertices(vertex_mask(sc, 8), 64, "grid")


def vertex_mask(sc, *rows):
    mask = np.zeros(sc.n_vertices, dtype=bool)
    mask[list(rows)] = True
    return mask


def test_adaptive_bad_levels_and_memory(monkeypatch):
    """Levels out of range are refused in one line; a grid that would not fit is refused
    before it is allocated."""
    sc, _ = slab_scene(0.2, -0.3)
    for bad in (-1, 9, 2.5):
        with pytest.raises(ShprobeError, match="adaptive levels"):
            DenseVertices(vertex_mask(sc, 8), 64, "adaptive", bad)
    monkeypatch.setenv("SHPROBE_MAX_MEMORY", "64M")
    with pytest.raises(ShprobeError, match="would need about"):
        trace_bake(sc, PrtSettings(mode="shadowed", lmax=1, samples=1024, threads=1),
                   dense=DenseVertices(vertex_mask(sc, 8), 32768, "adaptive", 8))


def test_cli_accurate_contact(tmp_path, capsys):
    """`shprobe prt bake --ground --accurate-contact` = bake(..., refine=ACCURATE): the
    refinement's dense vertices get 32 × the samples on the 128² grid, the gather criterion's
    gate 0.1, recorded in the file (the default: 8 × as Fibonacci directions, gate 0.25); with
    --no-refine or an unshadowed bake it is refused in one line."""
    import trimesh

    from shprobe.cli.main import main

    p = tmp_path / "box.obj"
    box = trimesh.creation.box(extents=[0.4, 0.2, 0.4])
    box.apply_translation([0.0, 0.1, 0.0])
    box.export(p)
    out = tmp_path / "t.npz"
    assert main(["prt", "bake", str(p), "--ground", "--mode", "shadowed", "--lmax", "1",
                 "--accurate-contact", "-o", str(out)]) == 0
    meta = load_transfer(out).metadata  # the refined bake's dense vertices: 32 × 1024, G 128
    assert meta["dense_quadrature"]["adaptive"]["grid"] == 128
    assert meta["refine"]["dense_quadrature"] == "adaptive"
    assert meta["refine"]["dense_factor"] == 32 and meta["refine"]["dense_vertices"] > 0
    assert meta["refine"]["gather_gate"] == 0.1
    plain = tmp_path / "f.npz"
    assert main(["prt", "bake", str(p), "--ground", "--mode", "shadowed", "--lmax", "1",
                 "-o", str(plain)]) == 0
    meta = load_transfer(plain).metadata
    assert "dense_quadrature" not in meta and meta["dense_samples"] == 8192
    assert meta["refine"]["dense_quadrature"] == "fibonacci"
    assert meta["refine"]["gather_gate"] == 0.25
    for extra in (["--ground", "--no-refine"], ["--ground", "--mode", "unshadowed"]):
        capsys.readouterr()
        assert main(["prt", "bake", str(p), "--accurate-contact", *extra, "-o",
                     str(tmp_path / "x.npz")]) != 0
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err
