"""The grid page's first view shows what leak control does without any control touched: on a
grid with depth data the object starts where leak control on and off light it most
differently (beside a wall of the room, not inside the closed room where both are black), and
each shading answer carries the other setting's mean as well; without depth data it starts at
the volume's centre."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.viewer.grid import GridView, parse_placement

from .test_viewer_grid import make_grid


@pytest.fixture(scope="module")
def room():
    from shprobe.grids import GridSettings, bake_grid
    from shprobe.grids.scenes import room_on_ground
    from shprobe.lighting.source import resolve_lighting
    from shprobe.prt.geometry import load_scene

    r = room_on_ground()
    g = bake_grid(load_scene(r.mesh(), albedo=0.5), resolve_lighting(preset="grace"),
                  GridSettings((7, 4, 7), bounds=r.bounds, bounces=0, samples=256))
    return r, g


def _means(view, pos, size):
    pts = view.local * size + np.asarray(pos)
    on = view.grid.irradiance(pts, view.normals, leak_control=True).mean(axis=0)
    off = view.grid.irradiance(pts, view.normals, leak_control=False).mean(axis=0)
    return on, off


def test_first_place_shows_the_leak_difference(room):
    r, g = room
    view = GridView(g, "room.npz")
    d = view.defaults()
    lo, hi = g.bounds
    assert np.all(np.asarray(d["position"]) - d["size"] >= lo - 1e-9)
    assert np.all(np.asarray(d["position"]) + d["size"] <= hi + 1e-9)
    on, off = _means(view, d["position"], d["size"])
    centre_on, centre_off = _means(view, 0.5 * (lo + hi), d["size"])
    print(f"first place {np.round(d['position'], 2)}: on {on.round(3)} off {off.round(3)}; "
          f"centre: on {centre_on.round(3)} off {centre_off.round(3)}")
    diff = np.abs(on - off).sum()
    assert diff > 0.25 * max(on.sum(), off.sum())  # a difference the eye sees
    assert diff > 3 * np.abs(centre_on - centre_off).sum()  # far more than at the centre
    assert not r.inside(np.asarray(d["position"])[None])[0]  # not inside the closed room
    # the shading answer of that place gives both settings
    p = parse_placement(d, g)
    e, leak = view.shade(p)
    assert leak and np.allclose(e.mean(axis=0), on)
    assert np.allclose(view.other_mean(p), off)


def test_without_depth_the_centre():
    g = make_grid(depth=False)
    view = GridView(g, "plain.npz")
    lo, hi = g.bounds
    assert np.allclose(view.defaults()["position"], 0.5 * (lo + hi))
    assert view.other_mean(parse_placement(view.defaults(), g)) is None
