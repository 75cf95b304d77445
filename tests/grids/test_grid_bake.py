"""Grid bakes against closed forms: probes that see the lighting unoccluded, an infinite
ground of albedo ρ under a uniform sky, a closed box, a probe left inside a solid (filled from
its neighbours); the octahedral maps; the settings, estimate and progress."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shprobe.errors import ShprobeError
from shprobe.grids import GridSettings, bake_grid, estimate_grid_bake
from shprobe.grids.octahedral import (
    octahedral_decode,
    octahedral_encode,
    octahedral_lookup,
    texel_directions,
)
from shprobe.grids.placement import dilate
from shprobe.progress import Recorder
from shprobe.prt.geometry import load_scene

Y00 = 0.5 / np.sqrt(np.pi)
Y1 = np.sqrt(3 / (4 * np.pi))


def _speck():
    """A triangle a thousandth of a unit across at the origin: geometry that hides nothing."""
    return trimesh.Trimesh([[0, 0, 0], [1e-3, 0, 0], [0, 0, 1e-3]], [[0, 2, 1]], process=False)


def test_unoccluded_probes_equal_the_lighting(rng):
    """Probes that see nothing of the scene hold the lighting's own coefficients (a preset,
    lmax 2: the quadrature of a degree-2 polynomial)."""
    from shprobe.probes.presets import get_preset

    c = get_preset("stpeters")
    g = bake_grid(_speck(), c, GridSettings((3, 2, 3), bounds=[[-2, -1, -2], [2, 1, 2]],
                                            bounces=1, samples=1024))
    got = np.asarray(g.coeffs, dtype=np.float64).reshape(-1, 9, 3)
    assert np.abs(got - c[None]).max() < 2e-3 * np.abs(c).max()


def test_unoccluded_probes_equal_the_probe_images_projection(grace_path):
    """Under a probe image each ray that leaves the scene brings the SH moments of the image
    over its own cell of the sphere: unoccluded probes hold the image's projection (R&H
    eq. 10) pixel for pixel, bright windows a few pixels wide included."""
    from shprobe.lighting.source import resolve_lighting

    light = resolve_lighting(grace_path, lmax=2)
    g = bake_grid(_speck(), light, GridSettings((2, 1, 2), bounds=[[-2, -1, -2], [2, 1, 2]],
                                                bounces=0, samples=4096))
    got = np.asarray(g.coeffs, dtype=np.float64).reshape(-1, 9, 3)
    err = np.abs(got - light.coeffs[None]).max()
    assert err < 1e-4 * light.coeffs[0].max(), err


@pytest.mark.parametrize("gather", [0, 2])
@pytest.mark.parametrize("bounces", [0, 1, 2])
def test_ground_under_a_uniform_sky(bounces, gather):
    """A wide ground of albedo ρ under a uniform sky L: a probe sees L above and, from one
    bounce on, ρL below (the ground sees only sky: E = πL). Projection: L00 = 2π·Y00·(L +
    ρ'L), L1,-1 = π·Y1·(L − ρ'L) (the y band), every other coefficient 0."""
    rho, L = 0.6, 1.5
    ground = trimesh.Trimesh([[-1e3, 0, -1e3], [1e3, 0, -1e3], [1e3, 0, 1e3], [-1e3, 0, 1e3]],
                             [[0, 2, 1], [0, 3, 2]], process=False)
    sky = np.zeros((9, 3))
    sky[0] = L / Y00
    g = bake_grid(load_scene(ground, albedo=rho), sky,
                  GridSettings((2, 2, 2), bounds=[[-1, 0, -1], [1, 2, 1]], bounces=bounces,
                               samples=4096, gather=gather))
    below = rho * L if bounces else 0.0
    want = np.zeros((9, 3))
    want[0] = 2 * np.pi * Y00 * (L + below)
    want[1] = np.pi * Y1 * (L - below)
    got = np.asarray(g.coeffs, dtype=np.float64).reshape(-1, 9, 3)
    assert np.abs(got - want[None]).max() < 5e-3 * want[0, 0]  # a step at the horizon
    e = g.irradiance([[0.3, 0.0, 0.2]], [[0, 1, 0]])  # the ground's irradiance πL
    assert np.allclose(e, np.pi * L, rtol=2e-3)


@pytest.mark.parametrize("albedo", [0.0, 0.9])
def test_probes_in_a_closed_box_see_nothing(albedo):
    box = trimesh.creation.box(bounds=[[-1, -1, -1], [1, 1, 1]])
    box.invert()  # faces towards the inside, where the probes are
    sky = np.zeros((4, 3))
    sky[0] = 3.0
    g = bake_grid(load_scene(box, albedo=albedo), sky,
                  GridSettings((2, 2, 2), bounds=[[-0.8] * 3, [0.8] * 3], lmax=1, bounces=2,
                               samples=256))
    assert g.lmax == 1 and np.all(g.coeffs == 0)
    assert g.meta["moved"] == 0 and g.meta["invalid"] == 0


def test_a_probe_buried_in_a_solid_is_invalid_and_filled_from_its_neighbours():
    """A solid cube filling a whole cell: no free point in the cell, so the probe is marked
    invalid and holds the mean of its 26-neighbours (all valid here)."""
    cube = trimesh.creation.box(bounds=[[-1.05, -1.05, -1.05], [1.05, 1.05, 1.05]])
    sky = np.zeros((9, 3))
    sky[0], sky[2] = 2.0, 0.5
    g = bake_grid(cube, sky, GridSettings((3, 3, 3), bounds=[[-3] * 3, [3] * 3], bounces=1,
                                          samples=512))
    v = np.asarray(g.validity)
    assert v[1, 1, 1] == 0 and v.sum() == 26 and g.meta["invalid"] == 1
    c = np.asarray(g.coeffs, dtype=np.float64)
    others = np.delete(c.reshape(27, 9, 3), 13, axis=0)
    assert np.allclose(c[1, 1, 1], others.mean(axis=0), atol=1e-6)


def test_dilation_grows_ring_by_ring():
    c = np.zeros((5, 1, 1, 4, 3))
    c[0] = 1.0
    valid = np.array([1, 0, 0, 0, 0], np.float32).reshape(5, 1, 1)
    out = dilate(c, valid)
    assert np.all(out == 1.0)


def test_octahedral_map_round_trip_and_lookup(rng):
    d = rng.normal(size=(5000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    assert np.abs(octahedral_decode(octahedral_encode(d)) - d).max() < 1e-12
    n = 16
    maps = texel_directions(n, 1)[:, :, 0][None]  # a map holding its own directions
    got = octahedral_lookup(maps, np.zeros(len(d), np.int64), d)
    # bilinear across the folded edges: within a texel's angle everywhere (a wrong border
    # would put a direction's opposite in)
    assert np.abs(got - d).max() < 2.5 / n


def test_settings_refuse_bad_values_in_one_line():
    for kw, needle in ((dict(resolution=(0, 4, 4)), "1 to 512"),
                       (dict(resolution=(10**6, 1, 1)), "1 to 512"),
                       (dict(resolution=(2, 2)), "three integers"),
                       (dict(resolution=(2, 2, 2), lmax=3), "lmax"),
                       (dict(resolution=(2, 2, 2), bounds=[[0, 0, 0], [1, 0, 1]]), "max > min"),
                       (dict(resolution=(2, 2, 2), bounds=[[0, 0, np.nan], [1, 1, 1]]),
                        "finite"),
                       (dict(resolution=(2, 2, 2), samples=10), "samples")):
        with pytest.raises(ShprobeError, match=needle):
            GridSettings(**kw)


def test_bounds_without_geometry_and_nan_lighting_are_refused():
    sky = np.zeros((9, 3))
    sky[0] = 1.0
    with pytest.raises(ShprobeError, match="contain no geometry"):
        bake_grid(_speck(), sky, GridSettings((2, 2, 2), bounds=[[5, 5, 5], [6, 6, 6]]))
    sky[3] = np.nan
    with pytest.raises(ShprobeError):
        bake_grid(_speck(), sky, GridSettings((2, 2, 2)))


def test_progress_estimate_and_meta():
    sky = np.zeros((9, 3))
    sky[0] = 1.0
    s = GridSettings((2, 2, 2), bounds=[[-1, 0, -1], [1, 1, 1]], bounces=2, samples=256)
    rec = Recorder()
    g = bake_grid(_speck(), sky, s, progress=rec)
    assert [x.split(": ", 1)[0] for x in rec.stages] == [f"{i}/6" for i in range(1, 7)]
    assert g.meta["bounces"] == 2 and g.meta["samples"] == 256 and g.depth.shape[3:] == (16, 16, 2)
    cost = estimate_grid_bake(1, s)
    big = estimate_grid_bake(1, GridSettings((64, 64, 64), samples=4096))
    assert 0 < cost.seconds < big.seconds and cost.nbytes < big.nbytes
    assert big.nbytes > 1e10  # a 64³ grid at 4096 rays keeps ~10⁹ rays' hits: refused early


def test_the_weights_kernel_is_the_numpy_rule(rng):
    """The numba kernel of the leak-controlled weights gives the numpy reference's weights
    (points inside and outside the grid, random normals, a grid with a moved probe)."""
    from shprobe.grids.visibility import visibility_weights, visibility_weights_reference

    cube = trimesh.creation.box(bounds=[[-0.3, -0.3, -0.3], [0.3, 0.3, 0.3]])
    sky = np.zeros((9, 3))
    sky[0] = 1.0
    g = bake_grid(cube, sky, GridSettings((3, 3, 3), bounds=[[-1.5] * 3, [1.5] * 3],
                                          bounces=0, samples=256))
    assert g.meta["moved"] == 1
    p = rng.uniform(-2, 2, (4000, 3))
    n = rng.normal(size=(4000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    i1, w1 = visibility_weights(g, p, n)
    i2, w2 = visibility_weights_reference(g, p, n)
    assert np.array_equal(i1, i2) and np.allclose(w1, w2, atol=1e-12)
    assert np.allclose(w1.sum(axis=1), 1.0)


def test_gather_directions_are_cosine_distributed(rng):
    """E[cos θ] = 2/3 and E[cos² θ] = 1/2 under the cosine density, all in the hemisphere."""
    from shprobe.grids.gather import cosine_directions

    n = rng.normal(size=(50, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    d = cosine_directions(n, 4000, rng)
    c = np.einsum("nkc,nc->nk", d, n)
    assert np.allclose(np.linalg.norm(d, axis=-1), 1.0) and c.min() >= 0
    assert abs(c.mean() - 2 / 3) < 3e-3 and abs((c * c).mean() - 0.5) < 3e-3
