"""The grid view (``shprobe view --grid``): a probe grid (irradiance volume) in the page — the
page's model, as the session is the designer page's (its routes: `shprobe.viewer.gridhandlers`).

The page draws what the library computes: each probe as a small sphere lit by its own SH (its
irradiance coefficients E_lm = Â_l L_lm, R&H 2001 eq. 7, summed per pixel by the library's
generated GLSL, `glsl_irradiance`), the volume's box, the scene the
grid was baked from (optional), and an object moved through the volume, lit per vertex by
[`ProbeGrid.irradiance`][shprobe.grids.ProbeGrid.irradiance] at its vertices — with
leak control (visibility-aware weights, where the grid has depth data) or plain trilinear, as
the page's toggle asks. Every body is bounded before it is read; a bad request is one line,
``{"error": ...}``, status 400.
"""

from __future__ import annotations

import logging
import os
import threading
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..grids import ProbeGrid, load_grid
from .wire import pack_binary

__all__ = ["MAX_SHADE", "MAX_VIEW_PROBES", "PAGE_MAX", "GridView", "Placement", "check_viewable",
           "load_grid_view", "parse_placement"]

#: most probes the page draws (each a sphere of ~100 vertices)
MAX_VIEW_PROBES = 16384
#: most vertices of the moving object (each shading request interpolates at all of them)
MAX_OBJECT_VERTICES = 1 << 20
#: largest shading request body (bytes): a position, a size and a flag
MAX_SHADE = 4096
_log = logging.getLogger("shprobe.viewer")
#: the object's vertices lit at each place :meth:`GridView.leak_spot` tries (thinned to this)
_SPOT_VERTICES = 96
#: normals over which the brightest probe irradiance is found (the page's default exposure)
_EXPOSURE_NORMALS = 512


class Placement:
    """Where the object stands: its bounding sphere's centre at ``position`` (3,), its radius
    ``size``; ``leak_control`` as [`ProbeGrid.irradiance`][shprobe.grids.ProbeGrid.irradiance] takes
    it."""

    __slots__ = ("leak_control", "position", "size")

    def __init__(self, position: NDArray[np.float64], size: float, leak_control: bool) -> None:
        self.position, self.size, self.leak_control = position, size, leak_control

    def place(self, local: NDArray[np.float64]) -> NDArray[np.float64]:
        """World positions of ``local`` points (the object in its unit bounding sphere)."""
        return local * self.size + self.position


def parse_placement(body: Any, grid: ProbeGrid) -> Placement:
    """A shading request's JSON object ``{"position": [x, y, z], "size": r, "leak_control":
    bool}`` checked against ``grid``: the position inside the volume's bounds, the size
    positive and at most the volume's diagonal. One line on anything else."""
    if not isinstance(body, dict) or set(body) - {"position", "size", "leak_control"}:
        raise ShprobeError("shading request: want an object with position, size and "
                           "leak_control only")
    pos = body.get("position")
    if not (isinstance(pos, list) and len(pos) == 3
            and all(isinstance(v, int | float) and not isinstance(v, bool) for v in pos)):
        raise ShprobeError("shading request: position must be three numbers")
    p = np.asarray(pos, dtype=np.float64)
    lo, hi = grid.bounds
    slack = 1e-9 * float(np.max(hi - lo))
    if not np.all(np.isfinite(p)) or np.any(p < lo - slack) or np.any(p > hi + slack):
        raise ShprobeError(f"shading request: position {np.round(p, 4).tolist()} is outside "
                           f"the volume {np.round(lo, 4).tolist()}..{np.round(hi, 4).tolist()}")
    size = body.get("size")
    diag = float(np.linalg.norm(hi - lo))
    if not (isinstance(size, int | float) and not isinstance(size, bool)
            and np.isfinite(size) and 0 < size <= diag):
        raise ShprobeError(f"shading request: size must be a number in (0, {diag:.4g}] "
                           "(the volume's diagonal)")
    leak = body.get("leak_control", True)
    if not isinstance(leak, bool):
        raise ShprobeError("shading request: leak_control must be true or false")
    return Placement(p, float(size), leak)


#: largest magnitude of a position or coefficient the page is sent: it draws in 32-bit floats
#: (about ±3.4e38), and sums of a few products of them must stay finite
PAGE_MAX = 1e30


def check_viewable(grid: ProbeGrid, name: str) -> None:
    """Refuse, in one line naming the file, a grid the page cannot draw or shade: a depth
    array that is not (NX, NY, NZ, D, D, 2), a ``normal_bias`` that is not a number in
    [0, 0.5], bounds or coefficients beyond `PAGE_MAX` (non-finite once sent as the
    page's 32-bit floats).

    Parameters
    ----------
    grid : ProbeGrid
        The grid as read by ``load_grid``.
    name : str
        The file's name, for the message.

    Raises
    ------
    ShprobeError
        When the grid cannot be shown.
    """
    d = grid.depth
    if d is not None:
        shape = np.shape(d)
        if len(shape) != 6 or shape[3] != shape[4] or shape[3] < 2 or shape[5] != 2:
            raise ShprobeError(f"grid depth has shape {tuple(shape)}, not (NX, NY, NZ, D, D, 2) "
                               "(mean and mean-square distance per octahedral texel)", name)
    bias = grid.meta.get("normal_bias")
    if bias is not None and (isinstance(bias, bool) or not isinstance(bias, int | float)
                             or not 0.0 <= float(bias) <= 0.5):
        shown = repr(bias)[:40]
        raise ShprobeError(f"grid meta normal_bias must be a number in [0, 0.5], got {shown}",
                           name)
    lo, hi = grid.bounds
    if np.max(np.abs(grid.bounds)) > PAGE_MAX or not np.all(np.isfinite(hi - lo)):
        raise ShprobeError(f"grid bounds beyond ±{PAGE_MAX:g} cannot be drawn (the page "
                           "draws in 32-bit floats)", name)
    for what, a in (("coefficients", grid.coeffs), ("positions", grid.positions)):
        if a is not None and (not np.all(np.isfinite(a))
                              or float(np.max(np.abs(a), initial=0.0)) > PAGE_MAX):
            raise ShprobeError(f"grid {what} beyond ±{PAGE_MAX:g} cannot be shown (the page "
                               "draws in 32-bit floats)", name)


class GridView:
    """Everything one ``shprobe view --grid`` serves: the grid, the object moved through it
    (``obj`` a trimesh mesh, None: the unit sphere) and the scene it was baked from (None:
    not drawn)."""

    def __init__(self, grid: ProbeGrid, name: str, obj: Any = None, obj_name: str = "sphere",
                 scene: Any = None, scene_name: str | None = None) -> None:
        from ..scene import bounding_sphere, mesh_vertex_albedo, sphere_mesh

        n = int(np.prod(grid.resolution))
        if n > MAX_VIEW_PROBES:
            raise ShprobeError(f"the grid has {n} probes; the viewer draws at most "
                               f"{MAX_VIEW_PROBES}", name)
        check_viewable(grid, name)
        self.grid, self.name = grid, name
        m = obj if obj is not None else sphere_mesh(4)
        if len(m.vertices) > MAX_OBJECT_VERTICES:
            raise ShprobeError(f"the object has {len(m.vertices)} vertices; the grid view "
                               f"lights at most {MAX_OBJECT_VERTICES}", obj_name)
        c, r = bounding_sphere(obj)
        self.local = (np.asarray(m.vertices, dtype=np.float64) - c) / r
        self.normals = np.asarray(m.vertex_normals, dtype=np.float64)
        alb = mesh_vertex_albedo(m)
        self.albedo = np.ones_like(self.local) if alb is None else np.asarray(alb)
        self.faces = np.asarray(m.faces)
        self.obj_name, self.scene, self.scene_name = obj_name, scene, scene_name
        self._payload: bytes | None = None
        self._defaults: dict[str, Any] | None = None
        self._lock = threading.Lock()

    # ------------------------------------------------------------------ what the page draws
    def defaults(self) -> dict[str, Any]:
        """The object's first placement, radius half the smallest cell: on a grid with depth
        data, where leak control changes its lighting most (`leak_spot`: the first view
        shows what the toggle does), else the volume's centre.

        Returns
        -------
        dict
            ``position`` (3 numbers), ``size`` and ``leak_control``, as the shading request
            takes them.
        """
        if self._defaults is None:
            lo, hi = self.grid.bounds
            size = 0.5 * float(np.min(self.grid.spacing))
            pos = 0.5 * (lo + hi) if self.grid.depth is None else self.leak_spot(size)
            self._defaults = {"position": [float(x) for x in pos], "size": size,
                              "leak_control": True}
        return dict(self._defaults)

    def leak_spot(self, size: float, per_axis: int = 8) -> NDArray[np.float64]:
        """Where an object of radius ``size`` is lit most differently with leak control on
        and off: over a lattice of ``per_axis``³ places inside the volume (the object kept
        inside it), the largest mean |E_on − E_off| (summed over R, G, B) over its vertices
        (at most about `_SPOT_VERTICES` of them), E from
        [`ProbeGrid.irradiance`][shprobe.grids.ProbeGrid.irradiance], among the places where both
        settings light it at least a tenth as brightly as the brightest place: inside a closed room
        lit from outside, where leak control gives black and plain trilinear a dim leak, the
        difference cannot be seen.

        Parameters
        ----------
        size : float
            The object's radius.
        per_axis : int
            Lattice places along each axis.

        Returns
        -------
        ndarray (3,)
            The chosen centre.
        """
        lo, hi = self.grid.bounds
        m = np.minimum(size, 0.49 * (hi - lo))  # the object inside the volume
        t = (np.arange(per_axis) + 0.5) / per_axis
        axes = [lo[a] + m[a] + t * (hi[a] - lo[a] - 2 * m[a]) for a in range(3)]
        c = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 1, 3)
        step = max(1, len(self.local) // _SPOT_VERTICES)  # the object's own vertices, thinned
        loc, d = self.local[::step], self.normals[::step]
        pts = (c + size * loc).reshape(-1, 3)
        nrm = np.broadcast_to(d, (len(c), *d.shape)).reshape(-1, 3)
        on = self.grid.irradiance(pts, nrm, leak_control=True)
        off = self.grid.irradiance(pts, nrm, leak_control=False)
        on_m = on.sum(axis=-1).reshape(len(c), -1).mean(axis=1)
        off_m = off.sum(axis=-1).reshape(len(c), -1).mean(axis=1)
        score = np.abs(on - off).sum(axis=-1).reshape(len(c), -1).mean(axis=1)
        # both lit enough to be seen: a closed room that leaks a little light with leak
        # control off is still black on the screen (a tenth of the brightest place at least)
        seen = np.minimum(on_m, off_m) >= 0.1 * float(np.max(np.maximum(on_m, off_m)))
        return c[int(np.argmax(np.where(seen, score, -1.0) if seen.any() else score)), 0]

    def probe_irradiance_coeffs(self) -> NDArray[np.float64]:
        """E_lm = Â_l L_lm (N, K, 3) of every probe (flat index (ix·NY + iy)·NZ + iz, as
        [`plain_weights`][shprobe.grids.plain_weights] numbers them)."""
        from ..lighting.irradiance import irradiance_coeffs

        g = self.grid
        return irradiance_coeffs(np.asarray(g.coeffs, dtype=np.float64)
                                 .reshape(-1, *g.coeffs.shape[-2:]))

    def brightest(self) -> float:
        """The largest irradiance E (any channel) of any probe over a set of normals: what the
        page's default exposure maps to white (interpolated irradiance is a convex blend of
        the probes', so nothing the page draws is brighter)."""
        from ..prt.directions import sample_directions
        from ..sh.basis import sh_basis

        y = sh_basis(sample_directions(_EXPOSURE_NORMALS), self.grid.lmax)
        e = np.einsum("mk,nkc->nmc", y, self.probe_irradiance_coeffs())
        return float(max(np.max(e), 0.0))

    def payload(self) -> bytes:
        """The page's data in one `pack_binary` message (made once)."""
        with self._lock:
            if self._payload is None:
                self._payload = self._make_payload()
            return self._payload

    def _make_payload(self) -> bytes:
        from ..lighting.glsl import glsl_irradiance

        g = self.grid
        n = int(np.prod(g.resolution))
        pos = g.probe_positions().reshape(n, 3)
        cen = g.centres().reshape(n, 3)
        val = (np.ones(n) if g.validity is None else np.asarray(g.validity).reshape(n))
        moved = np.linalg.norm(pos - cen, axis=1) > 1e-6 * float(np.min(g.spacing))
        head = {
            "name": self.name, "resolution": list(g.resolution), "lmax": g.lmax,
            "bounds": g.bounds.tolist(), "spacing": g.spacing.tolist(), "probes": n,
            "has_depth": g.depth is not None, "meta": _json_safe(dict(g.meta)),
            "invalid": int(np.sum(val < 0.5)), "relocated": int(np.sum(moved)),
            "brightest": self.brightest(), "object": self.obj_name, "scene": self.scene_name,
            "defaults": self.defaults(),
            # the library's per-pixel E(n) (R&H eq. 7), its E_lm read per probe by the page
            "glsl": glsl_irradiance(g.lmax)}
        arrays = {"probe_position": pos, "probe_centre": cen, "validity": val,
                  "probe_e": self.probe_irradiance_coeffs(),
                  "object_position": self.local, "object_normal": self.normals,
                  "object_albedo": self.albedo, "object_index": self.faces}
        if self.scene is not None:
            arrays["scene_position"] = np.asarray(self.scene.vertices)
            arrays["scene_normal"] = np.asarray(self.scene.vertex_normals)
            arrays["scene_index"] = np.asarray(self.scene.faces)
        return pack_binary(head, arrays)

    def shade(self, placement: Placement) -> tuple[NDArray[np.float64], bool]:
        """Irradiance E (V, 3) at the object's vertices placed by ``placement``
        ([`ProbeGrid.irradiance`][shprobe.grids.ProbeGrid.irradiance]) and whether leak control was
        applied (it needs the grid's depth data)."""
        e = self.grid.irradiance(placement.place(self.local), self.normals,
                                 leak_control=placement.leak_control)
        return e, placement.leak_control and self.grid.depth is not None

    def other_mean(self, placement: Placement) -> NDArray[np.float64] | None:
        """The object's mean irradiance (3,) with the other leak-control setting (None
        without depth data: both are plain trilinear), so that the page shows both."""
        if self.grid.depth is None:
            return None
        e = self.grid.irradiance(placement.place(self.local), self.normals,
                                 leak_control=not placement.leak_control)
        return e.mean(axis=0)


def load_grid_view(grid_path: str, mesh_path: str | None = None,
                   scene_path: str | None = None) -> GridView:
    """Read what ``shprobe view --grid`` shows: the grid file, the object (``mesh_path``; the
    viewer's default mesh where none is given) and the scene (``scene_path``, optional: a mesh
    file or a reference scene's name, `named_scene`). A bad file
    is one line naming it."""
    from ..grids.scenes import named_scene
    from ..scene import load_mesh
    from .loader import mesh_to_load

    try:
        grid = load_grid(grid_path)
    except ShprobeError:
        raise
    except (ValueError, TypeError, KeyError, OverflowError, RecursionError) as e:
        # a file the reader did not foresee (its meta's types): one line, not a traceback
        raise ShprobeError(f"not a readable shprobe grid file ({type(e).__name__}: "
                           f"{str(e).splitlines()[0][:80] if str(e) else 'bad data'})",
                           grid_path) from None
    obj_path = mesh_to_load(mesh_path, None)
    obj = None if obj_path is None else load_mesh(obj_path)
    scene = None
    if scene_path is not None:
        named = named_scene(scene_path)
        scene = load_mesh(scene_path) if named is None else named[0]
    return GridView(grid, os.path.basename(grid_path), obj,
                    "sphere" if obj_path is None else os.path.basename(obj_path),
                    scene, None if scene_path is None else os.path.basename(scene_path))


def _json_safe(meta: dict[str, Any]) -> dict[str, Any]:
    """The grid's bake settings as the page shows them (scalars and short lists only)."""
    out: dict[str, Any] = {}
    for k, v in meta.items():
        if isinstance(v, float) and not np.isfinite(v):
            continue  # JSON has no NaN or ∞
        if isinstance(v, str | int | float | bool) or v is None:
            out[str(k)] = v if not isinstance(v, str) else v[:200]
        elif isinstance(v, list | tuple) and len(v) <= 16:
            out[str(k)] = [x for x in v if isinstance(x, str | int | bool)
                           or (isinstance(x, float) and np.isfinite(x))]
    return out
