"""Leak control: the closed room on the open ground, baked under grace.hdr. Inside the room
the interpolated irradiance stays under 1 % of the ground's outside with the depth-moment
weights; the plain trilinear interpolation (three.js's sampling) of the same probes leaks."""

from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import data_file
from tests.grids.grid_bakes import room_grid


@pytest.fixture(scope="module")
def baked():
    return room_grid(str(data_file("probes", "grace.hdr")))


def _ratios(grid, room, leak_control):
    lk = room.leak(grid, leak_control)
    return lk.floor_ratio, lk.volume_ratio, lk.outside


def test_inside_is_under_one_percent_of_outside_with_leak_control(baked):
    room, grid = baked
    floor, volume, outside = _ratios(grid, room, True)
    print(f"\nleak control: cavity floor {floor:.3%}, cavity volume {volume:.3%} of the "
          f"ground outside ({outside:.3f})")
    assert outside > 0.5
    assert floor < 0.01 and volume < 0.01


def test_plain_interpolation_leaks(baked):
    """The same probes blended by plain trilinear weights (what engines do) let the outside
    in: several times the leak-controlled figure."""
    room, grid = baked
    floor, volume, _ = _ratios(grid, room, False)
    _lc_floor, lc_volume, _ = _ratios(grid, room, True)
    print(f"\nplain trilinear: cavity floor {floor:.3%}, cavity volume {volume:.3%}")
    assert volume > 5 * lc_volume and volume > 0.01


def test_probes_in_the_cavity_are_dark_and_the_roof_probes_moved(baked):
    room, grid = baked
    pos = grid.probe_positions().reshape(-1, 3)
    c = np.asarray(grid.coeffs).reshape(-1, grid.coeffs.shape[-2], 3)
    inside = room.inside(pos)
    assert inside.sum() >= 18
    assert np.abs(c[inside, 0]).max() < 0.01 * np.abs(c[~inside, 0]).mean()
    assert grid.meta["moved"] == 9 and grid.meta["invalid"] == 0
    centres = grid.centres().reshape(-1, 3)
    moved = np.linalg.norm(pos - centres, axis=1) > 0
    assert moved.sum() == 9
    solid = ~room.inside(centres) & np.all((centres > room.outer[0]) & (centres < room.outer[1]),
                                           axis=1)
    assert np.array_equal(moved, solid)  # exactly the probes in the roof slab
    roof = pos[moved]  # now in free space, inside their cells
    in_slab = (roof[:, 1] > room.cavity[1, 1]) & (roof[:, 1] < room.outer[1, 1])
    assert not in_slab.any()
    assert np.all(np.abs(pos - centres) <= 0.5 * grid.spacing + 1e-9)
