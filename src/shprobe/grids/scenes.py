"""Reference scenes for probe grids: a closed room standing on an open ground, the case where
an irradiance volume leaks (light inside a room that no light reaches), and the packaged bunny
on a ground. The command line names them (`SCENE_NAMES`, `named_scene`)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["SCENE_NAMES", "RoomLeak", "RoomScene", "bunny_on_ground", "named_scene",
           "room_on_ground"]

#: The reference scenes by the names a scene argument takes (``shprobe grid bake room``,
#: ``shprobe view --grid GRID --scene room``) where no file of that name exists.
SCENE_NAMES = ("room", "bunny-on-ground")


@dataclass(frozen=True)
class RoomLeak:
    """Mean irradiance E (mean of R, G, B) inside the room and on the open ground around it, as
    a grid interpolates it: ``floor`` on the cavity floor (normal +Y), ``volume`` through the
    cavity (random normals), ``outside`` on the ground ≥ 0.5 from the walls (normal +Y)."""

    floor: float
    volume: float
    outside: float

    @property
    def floor_ratio(self) -> float:
        """Cavity floor / open ground (a grid that does not leak: ≪ 1 %)."""
        return self.floor / self.outside

    @property
    def volume_ratio(self) -> float:
        """Cavity volume / open ground."""
        return self.volume / self.outside

    def __repr__(self) -> str:
        return (f"RoomLeak(floor {self.floor_ratio:.3%}, volume {self.volume_ratio:.3%} of the "
                f"ground outside, E {self.outside:.4g})")


@dataclass(frozen=True)
class RoomScene:
    """A closed room with walls ``wall`` thick (outer box ``outer``, cavity ``cavity``, both
    (2, 3) min/max corners) on a square ground plane y = 0 of half-size ``ground``, with the
    grid bounds the tests and benchmarks bake (``bounds``, (2, 3))."""

    outer: np.ndarray
    cavity: np.ndarray
    ground: float
    bounds: np.ndarray

    def mesh(self):
        """One trimesh: the ground (normal +Y), the room's outer box (normals out) and its
        cavity (normals into the cavity), so every face is front-facing from free space."""
        import trimesh

        from ..prt.geometry import ground_plane

        ground = ground_plane((0.0, 0.0), 2 * self.ground, 0.0, resolution=1)
        outer = trimesh.creation.box(bounds=self.outer)
        cavity = trimesh.creation.box(bounds=self.cavity)
        cavity.invert()
        return trimesh.util.concatenate([ground, outer, cavity])

    def leak_points(self, n: int = 2000, seed: int = 1
                    ) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """(points, normals) on the cavity floor (1 cm up, facing up), through the cavity
        (random normals) and on the ground inside the grid bounds ≥ 0.5 from the walls (1 cm
        up, facing up); seeded, so every measure of a leak uses the same points."""
        rng = np.random.default_rng(seed)
        cav, b = self.cavity, self.bounds
        floor = np.column_stack([rng.uniform(cav[0, 0], cav[1, 0], n),
                                 np.full(n, cav[0, 1] + 0.01),
                                 rng.uniform(cav[0, 2], cav[1, 2], n)])
        volume = rng.uniform(cav[0], cav[1], (n, 3))
        normals = rng.normal(size=(n, 3))
        ground = np.column_stack([rng.uniform(b[0, 0], b[1, 0], 4 * n), np.full(4 * n, 0.01),
                                  rng.uniform(b[0, 2], b[1, 2], 4 * n)])
        near = np.all((ground[:, [0, 2]] > self.outer[0, [0, 2]] - 0.5)
                      & (ground[:, [0, 2]] < self.outer[1, [0, 2]] + 0.5), axis=1)
        ground = ground[~near][:n]
        up = np.tile([0.0, 1.0, 0.0], (n, 1))
        return (floor, up), (volume, normals), (ground, up[: len(ground)])

    def leak(self, grid, leak_control: bool = True) -> RoomLeak:
        """How much of the outside light ``grid`` (a [`ProbeGrid`][shprobe.grids.ProbeGrid] of this
        scene) lets into the room through its interpolation."""
        (fp, fn), (vp, vn), (gp, gn) = self.leak_points()

        def mean(p, n):
            return float(np.mean(grid.irradiance(p, n, leak_control=leak_control)))

        return RoomLeak(mean(fp, fn), mean(vp, vn), mean(gp, gn))

    def inside(self, points: np.ndarray) -> np.ndarray:
        """True for points inside the cavity."""
        p = np.asarray(points, dtype=np.float64)
        return np.all((p > self.cavity[0]) & (p < self.cavity[1]), axis=-1)


def room_on_ground(half: float = 2.0, height: float = 2.6, wall: float = 0.2,
                   ground: float = 6.0) -> RoomScene:
    """The room of the leak test: outer box [−half, half] × [0, height] × [−half, half], walls,
    floor and roof ``wall`` thick, on a ground plane 2·``ground`` a side; grid bounds
    [−ground, 0, −ground]..[ground, 4, ground] (with a 7×4×7 grid, 18 probes fall in the
    cavity, 9 in the roof and the rest outside)."""
    outer = np.array([[-half, 0.0, -half], [half, height, half]])
    cavity = outer + np.array([[wall, wall, wall], [-wall, -wall, -wall]])
    bounds = np.array([[-ground, 0.0, -ground], [ground, 4.0, ground]])
    return RoomScene(outer=outer, cavity=cavity, ground=float(ground), bounds=bounds)


def bunny_on_ground(height: float = 1.5, ground: float = 4.0):
    """The packaged Stanford bunny scaled to ``height`` tall, standing at the origin on a
    square ground plane 2·``ground`` a side (normal +Y): the benchmarks' second scene. Returns
    (trimesh, bounds (2, 3)): the grid bounds [−1.5, 0, −1.5]..[1.5, 2, 1.5] (for the default
    height) hold the bunny with room around it."""
    import trimesh

    from ..prt.geometry import ground_plane
    from ..scene.mesh import packaged_bunny

    bunny = packaged_bunny()
    lo, hi = bunny.bounds
    s = height / (hi[1] - lo[1])
    v = (np.asarray(bunny.vertices) - [(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2]) * s
    plane = ground_plane((0.0, 0.0), 2 * float(ground), 0.0, resolution=1)
    mesh = trimesh.util.concatenate([plane, trimesh.Trimesh(v, bunny.faces, process=False)])
    r = height
    return mesh, np.array([[-r, 0.0, -r], [r, height * 4 / 3, r]])


def named_scene(arg: str | os.PathLike[str]) -> tuple[Any, np.ndarray] | None:
    """(trimesh, grid bounds (2, 3)) of the reference scene ``arg`` names — ``room``
    (`room_on_ground`) or ``bunny-on-ground`` (`bunny_on_ground`) — unless a file
    of that name exists; None for anything else (a mesh file)."""
    name = os.fspath(arg)
    if name not in SCENE_NAMES or os.path.exists(name):
        return None
    if name == "room":
        room = room_on_ground()
        return room.mesh(), room.bounds
    return bunny_on_ground()
