"""A grid bake's time estimate counts the bounce work the scene really makes: the trial trace's
fractions against a closed-form solid angle and against the rays of a real bake, a bake whose
probes see only sky (or black surfaces) not announced as long whatever its settings, a large
bake announced. Timings are in bench/bench_grid_estimate.py, not here."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shprobe.grids import GridSettings, bake_grid, estimate_grid_bake
from shprobe.grids.bake import grid_scene
from shprobe.grids.trial import trial_fractions
from shprobe.limits import LONG_JOB_SECONDS
from shprobe.prt.directions import sample_directions
from shprobe.prt.geometry import load_scene

SKY = np.zeros((9, 3))
SKY[0] = 1.0


def _square(y: float, up: bool) -> trimesh.Trimesh:
    """A square of half-side 1 at height ``y``, facing +Y (``up``) or −Y."""
    v = [[-1, y, -1], [1, y, -1], [1, y, 1], [-1, y, 1]]
    f = [[0, 2, 1], [0, 3, 2]] if up else [[0, 1, 2], [0, 2, 3]]
    return trimesh.Trimesh(v, f, process=False)


def _fractions(sc, settings):
    return trial_fractions(sc.vertices, sc.faces, sc.albedo, settings.bounds, settings)


def test_trial_sees_the_solid_angle_of_a_square():
    """One probe 0.5 above the centre of a square of half-side 1 facing it: the square fills
    Ω = 4 arcsin(a²/(a² + h²)) of the sphere (the solid angle of a rectangle seen from above
    its centre), lit only where the albedo is not zero, and its gather rays meet nothing."""
    h = 0.5
    omega = 4 * np.arcsin(1 / (1 + h * h)) / (4 * np.pi)
    s = GridSettings((1, 1, 1), bounds=[[-1, h - 0.5, -1], [1, h + 0.5, 1]], bounces=2, gather=4)
    fr = _fractions(load_scene(_square(0.0, up=True)), s)
    print(fr, omega)
    assert fr.lit == pytest.approx(omega, abs=0.04) and fr.onward == 0.0
    black = _fractions(load_scene(_square(0.0, up=True), albedo=0.0), s)
    assert black.lit == 0.0
    # a ceiling facing the floor: twice the solid angle, and gather rays that go on
    both = load_scene([_square(0.0, up=True), _square(2 * h, up=False)])
    fr2 = _fractions(both, s)
    print(fr2)
    assert fr2.lit == pytest.approx(2 * omega, abs=0.06) and fr2.onward > 0.3


@pytest.mark.parametrize("scene", ["room", "bunny-on-ground"])
def test_trial_fraction_is_the_bakes_own(scene):
    """The trial's lit fraction (32 probes at cell centres, 64 directions) is the fraction of
    the real bake's probe rays (from its placed probes, all its directions) that meet a lit
    front face, within 20 %."""
    from shprobe.grids.rays import ProbeTracer

    sc, s = grid_scene([scene], GridSettings((4, 4, 4), samples=256, bounces=1, gather=0))
    g = bake_grid(sc, SKY, s)
    tracer = ProbeTracer(sc.vertices, sc.faces)
    h = tracer.trace(g.positions.reshape(-1, 3), sample_directions(s.samples, s.seed),
                     distances=False)
    front = (h.face >= 0) & ~h.back
    rho = tracer.interpolate(sc.albedo, np.maximum(h.face, 0), h.u, h.v).max(axis=-1)
    real = float((front & (rho > 0)).mean())
    fr = _fractions(sc, s)
    print(scene, fr, real)
    assert 0.8 * real < fr.lit < 1.2 * real


def test_bake_of_probes_seeing_sky_is_not_announced_long(bunny_path):
    """The bunny in a box 40 units wide at the largest bounces and gather: its probes see
    sky, the bounces do next to nothing, and it is not announced as long (without the trial it
    would be, by orders of magnitude)."""
    bunny = str(bunny_path)
    s = GridSettings((4, 4, 4), bounds=[[-20] * 3, [20] * 3], samples=16384, bounces=16,
                     gather=256)
    sc, s = grid_scene([bunny], s)
    cost, blind = estimate_grid_bake(len(sc.faces), s, sc), estimate_grid_bake(len(sc.faces), s)
    print(cost, blind)
    assert not cost.long and blind.seconds > 100 * LONG_JOB_SECONDS
    black, s2 = grid_scene(["room"], GridSettings((4, 4, 4), bounces=16, gather=256), [0.0])
    assert not estimate_grid_bake(len(black.faces), s2, black).long


def test_large_bake_is_announced_and_scales_with_its_work():
    """A large bake of the room is announced; its estimate less the fixed part is the small
    bake's scaled by the work (probes × samples × bounces × gather), within a factor of 3."""
    from shprobe.grids.bake import BAKE_BASE_SECONDS

    small, s1 = grid_scene(["room"], GridSettings((4, 4, 4), samples=4096, bounces=2, gather=2))
    big, s2 = grid_scene(["room"], GridSettings((8, 8, 8), samples=16384, bounces=4, gather=8))
    c1 = estimate_grid_bake(len(small.faces), s1, small)
    c2 = estimate_grid_bake(len(big.faces), s2, big)
    scale = (s2.n_probes * s2.samples * s2.bounces * s2.gather) / (
        s1.n_probes * s1.samples * s1.bounces * s1.gather)
    ratio = (c2.seconds - BAKE_BASE_SECONDS) / ((c1.seconds - BAKE_BASE_SECONDS) * scale)
    print(c1, c2, ratio)
    assert c2.long and not c1.long and 1 / 3 < ratio < 3
