"""Reference scenes for probe grids: a closed room standing on an open ground, the case where
an irradiance volume leaks (light inside a room that no light reaches)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RoomScene", "room_on_ground"]


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

        g = self.ground
        ground = trimesh.Trimesh(
            vertices=[[-g, 0, -g], [g, 0, -g], [g, 0, g], [-g, 0, g]],
            faces=[[0, 2, 1], [0, 3, 2]], process=False)
        outer = trimesh.creation.box(bounds=self.outer)
        cavity = trimesh.creation.box(bounds=self.cavity)
        cavity.invert()
        return trimesh.util.concatenate([ground, outer, cavity])

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
