"""What the page draws, made once: the mesh's arrays (`mesh_payload`, kept in shprobe's
on-disk cache by `cached_mesh_payload`) and the probe's background texture
(`background_payload`), each one `pack_binary` message."""

from __future__ import annotations

from pathlib import Path
from typing import Any, overload

import numpy as np

from .wire import camera_json, pack_binary

__all__ = ["BACKGROUND_H", "VIEW_AZIMUTH", "VIEW_ELEVATION", "background_payload",
           "cached_mesh_payload", "ground_mask", "mesh_payload", "view_cameras"]

#: lat-long size (H) of the background texture sent to the page
BACKGROUND_H = 512
#: where the page's orbit camera starts (degrees, :class:`shprobe.scene.Camera`'s angles):
#: a three-quarter view from above the horizon, so that a ground plane is seen as a floor
#: rather than edge-on
VIEW_AZIMUTH, VIEW_ELEVATION = 30.0, 25.0


#: a scene on a ground plane is framed this much wider than its object, so that the ground
#: (and the object's shadow on it) is seen around the object
GROUND_FRAMING = 1.6


def view_cameras(center: Any, radius: float, ground: bool = False) -> dict[str, Any]:
    """The page's two cameras for an object of bounding sphere (``center``, ``radius``):
    ``camera`` the library's default [`Camera`][shprobe.scene.Camera] (512×512, elevation 0:
    what the page's pixel reads compare with `shprobe.scene.render`) and
    ``view`` the orbit camera the page starts from (`VIEW_AZIMUTH`, `VIEW_ELEVATION`; on a
    ``ground``, `GROUND_FRAMING` times wider)."""
    from ..scene import Camera

    wide = GROUND_FRAMING if ground else 1.0
    return {"camera": camera_json(Camera(512, 512), center, radius),
            "view": camera_json(Camera(512, 512, azimuth=VIEW_AZIMUTH,
                                       elevation=VIEW_ELEVATION), center, wide * radius)}


def ground_mask(vertices: Any, normals: Any, has_ground: bool) -> np.ndarray:
    """The vertices of a PRT scene's ground plane
    ([`shprobe.prt.geometry.ground_plane`][shprobe.prt.ground_plane]: the plane y = const under the
    scene, normals exactly +Y), wherever they are in the list (a refined bake splits the plane's
    triangles and appends their new vertices); all False without one."""
    v, n = np.asarray(vertices), np.asarray(normals)
    if not has_ground or len(v) == 0:
        return np.zeros(len(v), dtype=bool)
    up = np.abs(n[:, 1] - 1.0) < 1e-9
    if not up.any():
        return up
    return up & (v[:, 1] == v[up, 1].min())


def mesh_payload(mesh: Any, name: str) -> bytes:
    """What the page draws, in one `pack_binary` message: positions, normals, albedo
    (V, 3) as the renderer reads them, faces, and the library camera framing the bounding
    sphere. ``mesh`` None: the renderer's analytic unit sphere (drawn as a fine icosphere)."""
    from ..scene import bounding_sphere, mesh_vertex_albedo, sphere_mesh

    m = mesh if mesh is not None else sphere_mesh(5)
    alb = mesh_vertex_albedo(m)
    v = np.asarray(m.vertices)
    if mesh is None:  # the analytic unit sphere of the renderer
        c, r = np.zeros(3), 1.0
    else:
        c, r = bounding_sphere(mesh)
    return pack_binary({"name": name, "center": c.tolist(), "radius": r,
                        **view_cameras(c, r)},
                       {"position": v, "normal": np.asarray(m.vertex_normals),
                        "albedo": np.ones_like(v) if alb is None else alb,
                        "index": np.asarray(m.faces)})


@overload
def cached_mesh_payload(path: str, name: str) -> bytes: ...
@overload
def cached_mesh_payload(path: str, name: str, make: bool) -> bytes | None: ...
def cached_mesh_payload(path: str, name: str, make: bool = True) -> bytes | None:
    """`mesh_payload` of the mesh file ``path``, kept in shprobe's on-disk cache
    ([`shprobe.files.read_cache`][shprobe.files.read_cache], kind ``viewer_mesh``) under the file's
    content and the code that makes the payload, so that a mesh opened before — the default bunny, a
    user's own model — reaches the page without importing trimesh (0.4 CPU-s on this machine, most
    of what the mesh costs the first frame). A bad file is never cached: it is read, and
    refused, each time. ``make=False``: None where it is not cached (nothing is read)."""
    from ..files import file_digest, read_cache, write_cache

    try:
        key = file_digest(path, name, _payload_code_stamp())
    except OSError:
        key = None  # unreadable: load_mesh names the problem
    if key is not None:
        data = read_cache("viewer_mesh", key)
        if data is not None or not make:
            return data
    elif not make:
        return None
    from ..scene import load_mesh

    data = mesh_payload(load_mesh(path), name)
    if key is not None:
        write_cache("viewer_mesh", key, data)
    return data


def _payload_code_stamp() -> str:
    """Identifies the code behind `mesh_payload` (this module, the wire format, the scene
    layer, trimesh, shprobe's version): any change of it, an edit or an upgrade, makes a new
    cache key. Read from the files' sizes and times, without importing trimesh."""
    import importlib.util

    from .. import __version__

    here = Path(__file__).resolve()
    files = [here, here.with_name("wire.py"),
             *sorted((here.parents[1] / "scene").glob("*.py"))]
    spec = importlib.util.find_spec("trimesh")
    if spec is not None and spec.origin:
        files.append(Path(spec.origin))
        files.append(Path(spec.origin).with_name("version.py"))
    stamp = [__version__, "mesh_payload 3"]
    for f in files:
        try:
            st = f.stat()
            stamp.append(f"{f.name}:{st.st_size}:{st.st_mtime_ns}")
        except OSError:
            stamp.append(f"{f.name}:-")
    return "|".join(stamp)


def background_payload(env: Any) -> bytes:
    """The probe resampled to a `BACKGROUND_H` × 2·`BACKGROUND_H` lat-long grid
    (the library's directions and bilinear lookup, [`Env.sample`][shprobe.probes.env.Env.sample];
    lat-long probes larger than it box-filtered), RGBA half floats in a `pack_binary` message."""
    from ..probes.layouts import LatLong

    h = BACKGROUND_H
    if env.layout.name == "latlong" and env.grid[0] % h == 0:
        k = env.grid[0] // h  # box filter: k×k pixel blocks (same solid-angle rows)
        rad = env.radiance
        img = np.zeros((h, 2 * h, 3), np.float32)
        for i in range(k):  # k² strided adds (float32): ~10× faster than a reshaped mean
            for j in range(k):
                img += rad[i::k, j::k]
        img *= np.float32(1.0 / (k * k))
    elif env.layout.name == "latlong" and env.grid[0] <= h:
        img = env.radiance
    else:
        img = env.sample(LatLong().pixel_directions((h, 2 * h)))
    rgba = np.ones((*img.shape[:2], 4), np.float16)  # half floats, ready for a texture
    rgba[..., :3] = np.minimum(img, 65504.0)
    return pack_binary({"layout": env.layout.name, "grid": list(env.grid)},
                       {"radiance": rgba})
