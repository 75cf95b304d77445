"""The scene names the fitting package uses, imported in this one place (the scene layer is
being split into camera / mesh / raycast / render modules; repoint these lines when it is)."""

from __future__ import annotations

from ..scene.render import Camera, load_mesh, render, sphere_mesh, trace

__all__ = ["Camera", "load_mesh", "render", "sphere_mesh", "trace"]
