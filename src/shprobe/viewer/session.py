"""The viewer's model: what the page shows, computed by the library (no HTTP here).

A :class:`Session` holds the files named on the command line and those uploaded through the page
(kept in a private temporary folder under names the server chooses), the lighting source, the
mesh and the optional PRT transfer. The page's edit state is a small JSON document (see
:func:`check_state`) applied in the order of ``shprobe edit`` (blend, lights, per-coefficient and
per-band scales, rotation, window) by :func:`design_coeffs`; :func:`cli_args` spells the same
edits as ``shprobe edit`` arguments, so that an export from the page equals the CLI's file.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import tempfile
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, overload

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from .loader import fork_loader as _fork_loader
from .loader import mesh_to_load

__all__ = [
    "DESIGN_LMAX",
    "MAX_LMAX",
    "Session",
    "Source",
    "check_state",
    "cli_args",
    "design_coeffs",
    "pack_binary",
]

#: highest degree the compare view projects to (and the per-pixel view draws)
MAX_LMAX = 4
#: highest degree of a design (:func:`check_state`): the page's menu offers 0..MAX_LMAX; a PRT
#: transfer's baked degree, capped at this, sets a higher one (drawn per pixel by a second
#: generated GLSL function to this degree)
DESIGN_LMAX = 8
#: lat-long size (H) of the background texture sent to the page
BACKGROUND_H = 512
#: lat-long size (H) of the irradiance lookup textures (the normals of ``error_report``)
NORMAL_GRID = 32
#: largest upload accepted (bytes)
MAX_UPLOAD = 512 << 20
_PROBE_EXT = (".hdr", ".exr", ".pfm", ".tif", ".tiff", ".png", ".jpg", ".jpeg")
_MESH_EXT = (".obj", ".ply", ".gltf", ".glb", ".stl", ".off")
_COEFF_EXT = (".json", ".txt", ".glsl", ".hlsl", ".wgsl")


# ----------------------------------------------------------------------------- edit state

_DEFAULT_STATE: dict[str, Any] = {
    "lmax": 2, "weight": 1.0, "blends": [], "directional": [], "cone": [], "sky": None,
    "scale": {}, "scale_band": {}, "rotation": None, "window": None,
}


def _floats(v: Any, n: int | None, what: str) -> list[float]:
    try:
        a = np.asarray(v, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ShprobeError(f"{what} must be numbers") from None
    if (n is not None and a.size != n) or a.size == 0 or not np.all(np.isfinite(a)):
        raise ShprobeError(f"{what} must be {n or 'some'} finite numbers, got {v!r}")
    return [float(x) for x in a]


def check_state(state: Any) -> dict[str, Any]:
    """Validate the page's edit state (a JSON object) → a normalised copy; one-line
    :class:`ShprobeError` on anything malformed. Keys (all optional):

    ``lmax`` (0–:data:`DESIGN_LMAX`: the page's menu offers 0–:data:`MAX_LMAX`, the compare
    view's degree; a PRT transfer's baked degree, capped at :data:`DESIGN_LMAX`, sets a
    higher one; the per-pixel view draws every degree), ``weight``; ``blends``:
    [{"preset": NAME, "weight": w} | {"probe": ID, "weight": w}] (ID: a probe this server
    loaded, :meth:`Session.register_probe`);
    ``directional``: [{"dir": [x,y,z], "rgb": [r,g,b]}]; ``cone``: [{"dir", "aperture_deg",
    "rgb"}]; ``sky``: {"sky": rgb, "ground": rgb, "up": xyz} | null; ``scale``: {"l,m": f};
    ``scale_band``: {"l": f}; ``rotation``: {"axis": xyz, "degrees": d} | null; ``window``:
    null | "auto" | "KIND:STRENGTH".
    """
    from ..lighting.windows import WINDOWS
    from ..probes.presets import PRESETS

    if not isinstance(state, dict):
        raise ShprobeError("edit state must be a JSON object")
    unknown = set(state) - set(_DEFAULT_STATE)
    if unknown:
        raise ShprobeError(f"edit state has unknown keys: {', '.join(sorted(unknown))}")
    s = {**_DEFAULT_STATE, **state}
    out: dict[str, Any] = {}
    lmax = s["lmax"]
    if not isinstance(lmax, int) or not 0 <= lmax <= DESIGN_LMAX:
        raise ShprobeError(f"lmax must be an integer 0..{DESIGN_LMAX}, got {lmax!r}")
    out["lmax"] = lmax
    out["weight"] = _floats(s["weight"], 1, "weight")[0]
    out["blends"] = []
    for b in s["blends"] or []:
        w = _floats(b.get("weight", 1.0), 1, "blend weight")[0] if isinstance(b, dict) else 0
        if isinstance(b, dict) and b.get("preset") in PRESETS and "probe" not in b:
            out["blends"].append({"preset": b["preset"], "weight": w})
        elif isinstance(b, dict) and isinstance(b.get("probe"), str) and \
                _PROBE_ID.fullmatch(b["probe"]) and "preset" not in b:
            out["blends"].append({"probe": b["probe"], "weight": w})
        else:
            raise ShprobeError(f"blend must name a preset ({', '.join(PRESETS)}) or a probe "
                               f"this server loaded, got {b!r}")
    out["directional"] = [{"dir": _floats(d.get("dir"), 3, "light direction"),
                           "rgb": _floats(d.get("rgb", [1, 1, 1]), 3, "light colour")}
                          for d in _list(s["directional"], "directional")]
    out["cone"] = []
    for c in _list(s["cone"], "cone"):
        ap = _floats(c.get("aperture_deg"), 1, "cone aperture")[0]
        if not 0 < ap <= 180:
            raise ShprobeError(f"cone aperture must be in (0, 180] degrees, got {ap}")
        out["cone"].append({"dir": _floats(c.get("dir"), 3, "cone direction"),
                            "aperture_deg": ap, "rgb": _floats(c.get("rgb", [1, 1, 1]), 3,
                                                               "cone colour")})
    sky = s["sky"]
    out["sky"] = None if not sky else {
        "sky": _floats(sky.get("sky", [1, 1, 1]), 3, "sky colour"),
        "ground": _floats(sky.get("ground", [0, 0, 0]), 3, "ground colour"),
        "up": _floats(sky.get("up", [0, 1, 0]), 3, "sky up")}
    out["scale"] = {}
    for k, f in (s["scale"] or {}).items():
        try:
            l, m = (int(x) for x in str(k).split(","))
        except ValueError:
            raise ShprobeError(f"coefficient key must be 'l,m', got {k!r}") from None
        if not (0 <= l <= lmax and -l <= m <= l):
            raise ShprobeError(f"coefficient {k!r} is not in lmax {lmax}")
        out["scale"][f"{l},{m}"] = _floats(f, 1, "coefficient factor")[0]
    out["scale_band"] = {}
    for k, f in (s["scale_band"] or {}).items():
        if not str(k).isdigit() or int(k) > lmax:
            raise ShprobeError(f"band {k!r} is not in lmax {lmax}")
        out["scale_band"][str(int(k))] = _floats(f, 1, "band factor")[0]
    rot = s["rotation"]
    if rot:
        axis = _floats(rot.get("axis"), 3, "rotation axis")
        if not any(axis):
            raise ShprobeError("rotation axis must be a non-zero vector")
        out["rotation"] = {"axis": axis, "degrees": _floats(rot.get("degrees"), 1,
                                                            "rotation angle")[0]}
    else:
        out["rotation"] = None
    w = s["window"]
    if w in (None, "", "none"):
        out["window"] = None
    elif w == "auto":
        out["window"] = "auto"
    else:
        kind, _, st = str(w).partition(":")
        if kind not in WINDOWS:
            raise ShprobeError(f"window {w!r}: expected 'auto' or KIND:STRENGTH, KIND one of "
                               f"{', '.join(WINDOWS)}")
        out["window"] = f"{kind}:{_floats(st, 1, 'window strength')[0]!r}"
    return out


#: ids of the probes a session loaded (:meth:`Session.register_probe`): never a path
_PROBE_ID = re.compile(r"p[0-9a-f]{6}\.[0-9]{1,6}")


def _list(v: Any, what: str) -> list[dict[str, Any]]:
    if v is None:
        return []
    if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
        raise ShprobeError(f"{what} must be a list of objects")
    return v


def _r(x: float) -> str:
    return repr(float(x))


def _v(xs: list[float]) -> str:
    return ",".join(_r(x) for x in xs)


def cli_args(state: dict[str, Any], probe_names: dict[str, str] | None = None) -> list[str]:
    """The ``shprobe edit`` options doing the same edits as ``state`` (after the source);
    ``probe_names`` gives the file of each blended probe id (the name the user gave it)."""
    s = check_state(state)
    a = ["--lmax", str(s["lmax"])]
    if s["weight"] != 1.0:
        a += ["--weight", _r(s["weight"])]
    for b in s["blends"]:
        if "preset" in b:
            a += ["--blend", f"preset:{b['preset']}:{_r(b['weight'])}"]
        else:
            name = (probe_names or {}).get(b["probe"])
            if name is None:
                raise ShprobeError(f"blend probe {b['probe']} is not loaded in this server "
                                   "(load it again)")
            a += ["--blend", f"{name}:{_r(b['weight'])}"]
    for d in s["directional"]:
        a += ["--directional", f"{_v(d['dir'])}:{_v(d['rgb'])}"]
    for c in s["cone"]:
        a += ["--cone", f"{_v(c['dir'])}:{_r(c['aperture_deg'])}:{_v(c['rgb'])}"]
    if s["sky"]:
        k = s["sky"]
        a += ["--sky", f"{_v(k['sky'])}:{_v(k['ground'])}:{_v(k['up'])}"]
    for k, f in s["scale"].items():
        a += ["--scale", f"{k}={_r(f)}"]
    for k, f in s["scale_band"].items():
        a += ["--scale-band", f"{k}={_r(f)}"]
    if s["rotation"]:
        a += ["--rotate", f"{_v(s['rotation']['axis'])}:{_r(s['rotation']['degrees'])}"]
    if s["window"]:
        a += ["--window", s["window"]]
    return a


def _auto_desc(ch: Any) -> str:
    """How the page names an ``auto_window`` choice."""
    return f"auto -> {ch.kind}" + (
        f" {ch.strength:.4g}, bias {100 * ch.bias:.2f}%" if ch.kind != "none" else "")


ProbeCoeffs = Callable[[str, int], NDArray[np.float64]]


def _blend_coeffs(b: dict[str, Any], lmax: int, probes: ProbeCoeffs | None
                  ) -> NDArray[np.float64]:
    from ..probes.presets import get_preset

    if "preset" in b:
        return get_preset(b["preset"])
    if probes is None:
        raise ShprobeError(f"blend probe {b['probe']} is not loaded in this server")
    return probes(b["probe"], lmax)


def _edits(state: dict[str, Any], rotate: bool, window: bool,
           probes: ProbeCoeffs | None = None) -> Any:
    """The page's edit state as the library's :class:`~shprobe.lighting.design.Edits`, the one
    edit pipeline ``shprobe edit`` applies (so a download equals the CLI's file). ``probes``
    (id, lmax) → the coefficients of a blended probe (:meth:`Session.probe_coeffs`)."""
    from ..lighting.design import Edits

    spec = state["window"] if window else None
    if spec not in (None, "auto"):
        kind, _, strength = spec.partition(":")
        spec = (kind, float(strength))
    return Edits(
        blends=[(_blend_coeffs(b, state["lmax"], probes), b["weight"])
                for b in state["blends"]],
        directional=[(d["dir"], d["rgb"]) for d in state["directional"]],
        cones=[(c["dir"], c["aperture_deg"], c["rgb"]) for c in state["cone"]],
        sky=((state["sky"]["sky"], state["sky"]["ground"], state["sky"]["up"])
             if state["sky"] else None),
        scales=[(tuple(int(x) for x in k.split(",")), f) for k, f in state["scale"].items()],
        scale_bands=[(int(k), f) for k, f in state["scale_band"].items()],
        rotations=[rotation_matrix(state)] if rotate and state["rotation"] else [],
        window=spec)


def design_base(base: NDArray[np.float64] | None, state: dict[str, Any],
                probes: ProbeCoeffs | None = None) -> NDArray[np.float64]:
    """The edits before the rotation (blend, lights, scales) of ``shprobe edit``
    (:func:`shprobe.lighting.design.edit_lighting`)."""
    from ..lighting.design import edit_lighting

    return edit_lighting(base, _edits(state, False, False, probes), state["lmax"],
                         state["weight"]).coeffs


def rotation_matrix(state: dict[str, Any]) -> NDArray[np.float64]:
    """The state's lighting rotation as a 3×3 matrix (Rodrigues, right-hand rule)."""
    from ..sh.rotation import from_axis_angle

    r = state["rotation"]
    return np.eye(3) if not r else from_axis_angle(r["axis"], r["degrees"])


def design_coeffs(base: NDArray[np.float64] | None, state: dict[str, Any],
                  probes: ProbeCoeffs | None = None
                  ) -> tuple[NDArray[np.float64], str | None]:
    """(L_lm (K, 3), window description): ``state`` applied to the source coefficients
    ``base`` by the library's edit pipeline, in the order of ``shprobe edit``; ``probes``
    resolves blended probes (:meth:`Session.probe_coeffs`)."""
    from ..lighting.design import edit_lighting

    res = edit_lighting(base, _edits(state, True, True, probes), state["lmax"],
                        state["weight"])
    return res.coeffs, res.window


# ----------------------------------------------------------------------------- binary payloads


def pack_binary(header: dict[str, Any], arrays: dict[str, NDArray]) -> bytes:
    """One binary message: uint32 header length, JSON header (with each array's dtype, shape
    and byte offset), padding to 4 bytes, then the arrays (little-endian float16 / float32 /
    uint32), each padded to 4 bytes."""
    parts, meta, off = [], {}, 0
    for name, a in arrays.items():
        kind = "f2" if a.dtype == np.float16 else "f4" if a.dtype.kind == "f" else "u4"
        a = np.ascontiguousarray(a, dtype="<" + kind)
        meta[name] = {"dtype": kind, "shape": list(a.shape), "offset": off}
        parts.append(a.tobytes())
        off += a.nbytes + (-a.nbytes % 4)
        parts.append(b"\0" * (-a.nbytes % 4))
    head = json.dumps({**header, "arrays": meta}).encode()
    head += b" " * (-(len(head) + 4) % 4)
    return len(head).to_bytes(4, "little") + head + b"".join(parts)


# ----------------------------------------------------------------------------- session


class Source:
    """A lighting source: its name (as ``shprobe`` commands give it), the probe (None for
    presets) and its coefficients: ``coeffs2`` at lmax 2, the base ``shprobe edit`` starts
    from, and :attr:`coeffs` at :data:`MAX_LMAX`, projected on first use (projecting to a
    higher degree changes the low coefficients in the last bits, so both are kept).

    ``pending=True``: a probe whose :class:`Env` is still on its way from the loader process
    (the lmax-2 coefficients came first, for the first frame); :attr:`env` waits for it."""

    def __init__(self, name: str, coeffs2: NDArray[np.float64], env: Any = None,
                 pending: bool = False) -> None:
        self.name, self.coeffs2 = name, coeffs2
        self._env = env
        self.has_env = env is not None or pending
        self.layout_name = None if env is None else env.layout.name
        self._coeffs: NDArray[np.float64] | None = None if self.has_env else coeffs2
        self._by_lmax: dict[int, NDArray[np.float64]] = {}
        #: why a pending probe never arrived (one line), raised by :attr:`env`
        self.error: str | None = None
        self._arrived = threading.Event()
        if not pending:
            self._arrived.set()
        #: called before waiting for a pending probe (asks the loader to send it now)
        self.request: Callable[[], None] | None = None
        self._lock = threading.Lock()
        #: the page's background texture (:func:`background_payload`), once made
        self.background: bytes | None = None
        self.decoded_at = 0.0  # when the probe was decoded (time.time(), for the benchmark)

    @property
    def env(self) -> Any:
        """The probe (None for presets); waits for one still being loaded; a one-line
        :class:`ShprobeError` when its loading failed."""
        if not self._arrived.is_set() and self.request is not None:
            self.request()
        self._arrived.wait()
        if self.error is not None:
            raise ShprobeError(self.error)
        return self._env

    def arrive(self, env: Any, coeffs: NDArray[np.float64] | None = None,
               background: bytes | None = None, error: str | None = None) -> None:
        """The pending probe (None: its loading failed, ``error`` saying why), its
        lmax-:data:`MAX_LMAX` coefficients and background texture, from the loader process."""
        with self._lock:
            self._env = env
            self.error = error
            if coeffs is not None:
                self._coeffs = coeffs
            if background is not None:
                self.background = background
            self.has_env = env is not None
        self._arrived.set()

    @property
    def coeffs(self) -> NDArray[np.float64]:
        """The coefficients at :data:`MAX_LMAX` (the compare view's)."""
        env = self.env
        with self._lock:
            if self._coeffs is None:
                from ..lighting.projection import project

                if env is None:
                    raise ShprobeError(f"{self.name}: the probe could not be loaded")
                self._coeffs = np.asarray(project(env, MAX_LMAX), np.float64)
            return self._coeffs

    def coeffs_at(self, lmax: int) -> NDArray[np.float64]:
        """The probe projected to exactly ``lmax`` (R&H eq. 10; cached): :attr:`coeffs2` at 2,
        :attr:`coeffs` at :data:`MAX_LMAX` — as ``shprobe edit --blend FILE:W`` projects a
        blended probe to the edit's degree."""
        if lmax == 2:
            return self.coeffs2
        if lmax == MAX_LMAX:
            return self.coeffs
        with self._lock:
            c = self._by_lmax.get(lmax)
        if c is None:
            from ..lighting.projection import project

            env = self.env
            if env is None:
                with self._lock:  # keep_coeffs_only may have cached it and let the image go
                    c = self._by_lmax.get(lmax)
                if c is not None:
                    return c
                raise ShprobeError(f"{self.name}: the probe could not be loaded")
            c = np.asarray(project(env, lmax), np.float64)
            with self._lock:
                self._by_lmax[lmax] = c
        return c

    def keep_coeffs_only(self, lmax: int) -> None:
        """Project to every degree 0…``lmax`` (cached, :meth:`coeffs_at`), then drop the
        probe image and background: what a blend source needs, without its memory."""
        try:
            for l in range(lmax + 1):
                self.coeffs_at(l)
        except ShprobeError:  # a probe that failed to load has nothing to keep
            return
        with self._lock:
            self._env, self.background = None, None

    def __repr__(self) -> str:
        return f"Source({self.name!r}, env={self.has_env})"


@dataclass
class Task:
    """Progress of a long library call running off the event loop."""

    done: float = 0.0
    status: str = "idle"  # idle | running | done | error
    message: str = ""
    result: Any = None


class Session:
    """Everything one ``shprobe view`` serves: sources, mesh, transfer, uploads."""

    def __init__(self, probe: str | None = None, preset: str | None = None,
                 mesh: str | None = None, transfer: str | None = None,
                 layout: str = "auto", load: bool = True) -> None:
        self.layout = layout
        self._args = (probe, preset, mesh, transfer)
        self._dir = tempfile.TemporaryDirectory(prefix="shprobe-view-")
        self._n_uploads = 0
        self.lock = threading.Lock()
        self.tasks: dict[str, Task] = {}
        self._design_cache: dict[str, Any] = {}
        self.transfer = None
        self.transfer_name = None
        self._mesh: Any = None
        self._mesh_path: str | None = None  # loaded on first use (see :attr:`mesh`)
        self._mesh_bytes: bytes | None = None
        self._mesh_lock = threading.RLock()  # mesh_bytes holds it while reading .mesh
        self.mesh_name = "sphere"
        self._source: Source | None = None
        self.ready = threading.Event()
        self.error: ShprobeError | None = None
        #: wall-clock stamps (time.time()) of the loading stages, for the first-frame benchmark
        self.timings: dict[str, float] = {}
        self._child: Any = None  # [(process, pipe)] of fork_loader
        self._go: Any = None  # its Go: send the Env now
        #: probes loaded (command line, uploads): id → (file name as the user gave it, Source)
        self.probes: dict[str, tuple[str, Source]] = {}
        self._probe_tag = f"p{secrets.token_hex(3)}"  # ids of another server never match
        if load:
            self.load()

    def _mesh_arg(self) -> str | None:
        return mesh_to_load(*self._args[2:])

    def fork_loader(self) -> None:
        """Start loading the probe and the mesh named on the command line in a forked
        process (:func:`shprobe.viewer.loader.fork_loader`; ``shprobe view`` calls it before
        any thread starts and before the server is imported): :meth:`load` then takes the lmax-2
        coefficients and the page's mesh arrays from it (the first frame needs no more); the
        :class:`Env` (compare, H-basis, lmax > 2), its lmax-:data:`MAX_LMAX` coefficients and
        the background texture follow in a thread. The trimesh object is loaded in this
        process only when a view needs it (:attr:`mesh`); the Env is sent when a view first
        needs it (:attr:`Source.env` sets the loader's ``go``), so that until then the first
        frame has the cores. Without a fork (not Linux, or nothing to load) :meth:`load` reads
        the files itself."""
        import time

        loader = _fork_loader(self._args[0], self.layout, self._mesh_arg())
        if loader is not None:
            self.timings["load_start"] = time.time()
            self._child, self._go = loader

    def load(self) -> None:
        """Read the files named on the command line (probe and mesh in parallel, or from the
        process :meth:`fork_loader` started); sets :attr:`ready`, and :attr:`error` when one
        of them is bad (then re-raised)."""
        import time

        probe, preset, _, transfer = self._args
        mesh_path = self._mesh_arg()
        errors: list[BaseException] = []
        stamp = self.timings
        stamp.setdefault("load_start", time.time())
        forked = self._child is not None

        def geometry() -> None:
            try:
                if transfer:
                    self.load_transfer(transfer)
                if mesh_path and not forked:
                    self.load_mesh(mesh_path, os.path.basename(mesh_path))
                    stamp["geometry_done"] = time.time()
            except BaseException as e:  # re-raised below, in the caller's thread
                errors.append(e)

        th = threading.Thread(target=geometry, daemon=True)
        th.start()
        try:
            if forked:
                self._load_forked(probe, mesh_path)
            if probe and not forked:
                self.source = self.probe_source(probe)
                self.register_probe(self.source, probe)
            elif preset:
                self.source = self.preset_source(preset)
            elif not probe:
                from ..probes.environments import procedural_env

                self.source = self.env_source(procedural_env(256, 128), "procedural sky")
        except BaseException as e:
            errors.append(e)
        stamp.setdefault("source_done", time.time())
        th.join()
        stamp["ready"] = time.time()
        if errors:
            e = errors[0]
            self.error = e if isinstance(e, ShprobeError) else ShprobeError(str(e))
            self.ready.set()
            raise self.error
        self.ready.set()

    def _load_forked(self, probe: str | None, mesh_path: str | None) -> None:
        """:meth:`load`'s probe and mesh from the forked processes (:func:`_load_child`)."""
        name = os.path.basename(mesh_path) if mesh_path else None
        src: Source | None = None
        try:
            for _, recv in self._child:
                while True:
                    kind, *data = recv.recv()
                    if kind == "error":
                        raise ShprobeError(data[0])
                    self.timings.update(data[-1])
                    if kind == "source":
                        src = Source(probe, data[0], pending=True)
                        src.layout_name = data[1]
                        if self._go is not None:
                            src.request = self._go.set
                        self.source = src
                        self.register_probe(src, probe)
                    elif kind == "mesh":
                        with self._mesh_lock:
                            self._mesh, self._mesh_path, self.mesh_name = None, mesh_path, name
                            self._mesh_bytes = data[0]
                    elif kind == "ready":
                        break
        except BaseException as e:
            self._stop_loader()
            if src is not None:  # its Env will not come: Source.env must not wait for it
                src.arrive(None, error=f"{probe}: the probe could not be loaded")
            if isinstance(e, EOFError):
                raise ShprobeError("the loading process ended unexpectedly") from None
            raise
        child = self._child

        def rest() -> None:  # the Env and what is made from it, after the first frame's data
            got, err = None, None
            try:
                if src is not None:
                    kind, *data = child[0][1].recv()
                    if kind == "env":
                        got = data
                    elif kind == "error":  # one line naming the file already
                        err = str(data[0])
                    else:
                        err = f"{probe}: unexpected message {kind!r} from the loading process"
            except (EOFError, OSError):
                err = f"{probe}: the loading process ended before the probe arrived"
            except BaseException as e:  # unpickling, MemoryError: one line, never a hang
                err = f"{probe}: {type(e).__name__}: {e}".splitlines()[0]
            finally:
                if src is not None:  # Source.env waits for this
                    if got:
                        src.arrive(*got[:3])
                    else:
                        src.arrive(None, error=err or f"{probe}: the probe could not be loaded")
                self._stop_loader(child)
                self._trim_probes()  # replaced as the source before it arrived: trim it now

        threading.Thread(target=rest, daemon=True).start()

    def _stop_loader(self, done: Any = None) -> None:
        """Close the receive ends of the loader's pipes (a grandchild still sending then
        fails and exits) and end the loader process (terminate + join: no zombie); once,
        by whoever comes first. ``done``: the pipes of a loader that sent everything (the
        Env thread): it is joined, not terminated."""
        with self.lock:
            child = self._child
            if child is None or (done is not None and child is not done):
                return
            self._child = None
        for _, recv in child:
            recv.close()
        for proc in {id(p): p for p, _ in child}.values():  # one loader, 1-2 pipes
            if done is None and proc.is_alive():
                proc.terminate()
            proc.join(None if done is not None else 5)
            if proc.exitcode is not None:
                proc.close()  # its sentinel fd
        if self._go is not None:  # a Source's request() is a no-op from now on
            self._go.close()

    def close(self) -> None:
        self._stop_loader()
        self._dir.cleanup()

    # sources ----------------------------------------------------------------
    def env_source(self, env: Any, name: str) -> Source:
        from ..lighting.projection import project

        return Source(name, np.asarray(project(env, 2), np.float64), env)

    def design(self, state: dict[str, Any]) -> tuple[NDArray[np.float64], str | None, Any]:
        """(L_lm, window description, min E certificate) of ``state`` for the page, fast during
        a drag: everything but the rotation is cached per (source, state without rotation) —
        the edits before it, the window factors (``auto``: chosen on the unrotated lighting)
        and :func:`~shprobe.lighting.windows.min_irradiance`, all invariant under rotation —
        so a drag step is one Wigner rotation. Exports use :func:`design_coeffs` (the CLI's
        exact sequence of operations)."""
        from ..lighting.design import rotate_lighting
        from ..lighting.windows import apply_window, auto_window, min_irradiance, window_factors
        from ..sh import lmax_of

        src = self.source
        key = json.dumps({**state, "rotation": None}, sort_keys=True)
        hit = self._design_cache.get(key)
        if hit is None or hit[0] is not src:
            L0 = design_base(self.base(state["lmax"]), state, self.probe_coeffs)
            f, wdesc = None, None
            if state["window"] == "auto":
                ch = auto_window(L0)
                f, wdesc = ch.factors, _auto_desc(ch)
            elif state["window"]:
                kind, _, st = state["window"].partition(":")
                f, wdesc = window_factors(kind, lmax_of(L0.shape[0]), float(st)), state["window"]
            cert = min_irradiance(L0 if f is None else apply_window(L0, f))
            hit = (src, L0, f, wdesc, cert)
            if len(self._design_cache) > 64:
                self._design_cache.clear()
            self._design_cache[key] = hit
        _, L0, f, wdesc, cert = hit
        L = rotate_lighting(L0, rotation_matrix(state)) if state["rotation"] else L0
        self.last_base = (L0, f)  # what the page rotates itself during a drag (lmax ≤ 2)
        return (L if f is None else apply_window(L, f)), wdesc, cert

    @property
    def source(self) -> Source:
        """The lighting the edits start from."""
        if self._source is None:
            raise ShprobeError("no lighting source is loaded yet")
        return self._source

    @source.setter
    def source(self, src: Source) -> None:
        self._source = src
        self._trim_probes()

    def register_probe(self, src: Source, name: str) -> str:
        """Keep a loaded probe for blending; → its id (what the page names it by)."""
        with self.lock:
            pid = f"{self._probe_tag}.{len(self.probes)}"
            self.probes[pid] = (name, src)
        self._trim_probes(keep=src)  # it may become the source next
        return pid

    def _trim_probes(self, keep: Source | None = None) -> None:
        """A probe that is only a blend source now (not :attr:`source`, not ``keep``) keeps
        its coefficients at every degree a design can ask for and lets its decoded image go
        (in a thread: up to :data:`DESIGN_LMAX` + 1 projections), so that uploads do not pile
        up images in memory: at most the source's and the latest upload's are held."""
        current = self._source
        old = [src for _, (_, src) in self._probe_items()
               if src is not current and src is not keep and src._arrived.is_set()
               and src._env is not None]
        if old:
            threading.Thread(target=lambda: [o.keep_coeffs_only(DESIGN_LMAX) for o in old],
                             daemon=True).start()

    def _probe_items(self) -> list[tuple[str, tuple[str, Source]]]:
        with self.lock:  # register_probe adds from a worker thread
            return list(self.probes.items())

    def probe_names(self) -> dict[str, str]:
        return {k: v[0] for k, v in self._probe_items()}

    def probe_list(self) -> list[dict[str, str]]:
        return [{"id": k, "name": os.path.basename(v[0]) or v[0]}
                for k, v in self._probe_items()]

    def probe_coeffs(self, pid: str, lmax: int) -> NDArray[np.float64]:
        """A registered probe projected to ``lmax`` (:meth:`Source.coeffs_at`)."""
        with self.lock:
            hit = self.probes.get(pid)
        if hit is None:
            raise ShprobeError(f"blend probe {pid} is not loaded in this server (load it "
                               "again)")
        return hit[1].coeffs_at(lmax)

    def base(self, lmax: int) -> NDArray[np.float64]:
        """The coefficients the edits start from at degree ``lmax``: a probe projected to
        max(lmax, 2), as ``shprobe edit`` projects its source."""
        s = self.source
        if lmax > 2 and s.error is not None:
            raise ShprobeError(s.error)
        return s.coeffs2 if lmax <= 2 or not s.has_env else s.coeffs_at(lmax)

    def probe_source(self, path: str | list[str], name: str | None = None) -> Source:
        src = load_probe(path, self.layout, name)
        self.timings.setdefault("decoded", src.decoded_at)
        return src

    def coeffs_source(self, path: str, name: str) -> Source:
        """Coefficients in any export format (``lighting.export.import_coeffs``)."""
        from ..lighting.export import import_coeffs

        c = import_coeffs(path)
        if c.shape[1] == 1:
            c = np.repeat(c, 3, axis=1)
        if c.shape[1] != 3:
            raise ShprobeError(f"needs 1 or 3 channels, got {c.shape[1]}", name)
        return Source(name, c)

    def preset_source(self, name: str) -> Source:
        from ..probes.presets import get_preset

        return Source(f"preset:{name}", get_preset(name))

    # mesh / transfer --------------------------------------------------------
    @property
    def mesh(self) -> Any:
        """The trimesh mesh drawn (None: the built-in sphere); a mesh the loading process
        read for the first frame is loaded here on first use."""
        with self._mesh_lock:
            if self._mesh is None and self._mesh_path is not None:
                from ..scene import load_mesh

                self._mesh = load_mesh(self._mesh_path)
            return self._mesh

    def load_mesh(self, path: str, name: str | None = None) -> None:
        from ..scene import load_mesh

        m = load_mesh(path)
        with self._mesh_lock:
            self._mesh, self._mesh_path, self._mesh_bytes = m, None, None
            self.mesh_name = name or os.path.basename(path)

    def load_transfer(self, path: str, name: str | None = None) -> None:
        from ..prt.transfer import load_transfer

        self.transfer = load_transfer(path)
        self.transfer_name = name or os.path.basename(path)

    def mesh_bytes(self) -> bytes:
        """The page's mesh (:func:`mesh_payload`), made once per mesh (under the mesh lock: an
        upload meanwhile waits, so the payload cached is always the current mesh's)."""
        with self._mesh_lock:
            if self._mesh_bytes is None:
                self._mesh_bytes = mesh_payload(self.mesh, self.mesh_name)
            return self._mesh_bytes

    def transfer_bytes(self, mode: str | None, bounces: int | None) -> bytes:
        t = self.transfer
        if t is None:
            raise ShprobeError("no transfer: start `shprobe view --transfer T.npz`")
        T = t.select(mode, bounces)
        from ..scene.render import Camera

        v = np.asarray(t.vertices)
        c = 0.5 * (v.min(axis=0) + v.max(axis=0))
        r = float(np.sqrt(((v - c) ** 2).sum(axis=1).max()))
        return pack_binary(
            {"name": self.transfer_name, "lmax": t.lmax, "modes": list(t.modes),
             "max_bounces": t.max_bounces, "mode": mode or t.mode, "bounces": bounces,
             "camera": camera_json(Camera(512, 512), c, r)},
            {"position": v, "normal": t.normals, "index": t.faces,
             "transfer": T.reshape(T.shape[0], -1)})

    # uploads ----------------------------------------------------------------
    def save_upload(self, filename: str, data: bytes, kinds: tuple[str, ...]) -> tuple[str, str]:
        """Write uploaded bytes to the session's private folder under a name the server picks
        (only the extension of ``filename`` is kept, and only a known one); → (path, shown
        name). No path from the page is ever opened."""
        base = os.path.basename(str(filename).replace("\\", "/")) or "upload"
        ext = os.path.splitext(base)[1].lower()
        allowed = {"probe": _PROBE_EXT, "mesh": _MESH_EXT, "coeffs": _COEFF_EXT,
                   "transfer": (".npz",)}
        ok = tuple(e for k in kinds for e in allowed[k])
        if ext not in ok:
            raise ShprobeError(f"{base}: cannot load a {'/'.join(kinds)} with extension "
                               f"{ext or '(none)'!r}; expected one of {' '.join(ok)}")
        if len(data) > MAX_UPLOAD:
            raise ShprobeError(f"{base}: upload of {len(data) >> 20} MiB is over the "
                               f"{MAX_UPLOAD >> 20} MiB limit")
        with self.lock:
            self._n_uploads += 1
            p = Path(self._dir.name) / f"upload-{self._n_uploads}{ext}"
        p.write_bytes(data)
        return str(p), base

    def save_cube_upload(self, data: bytes) -> tuple[list[str], list[str]]:
        """Six cube faces in one upload (:func:`unpack_files`), each stored as
        :meth:`save_upload` stores a probe; → (paths, shown names), in the page's order
        +X −X +Y −Y +Z −Z."""
        saved = [self.save_upload(n, d, ("probe",)) for n, d in unpack_files(data)]
        return [p for p, _ in saved], [s for _, s in saved]

    # pictures ---------------------------------------------------------------
    def background_bytes(self) -> bytes | None:
        """The source's background texture (:func:`background_payload`), None for a preset."""
        src = self.source
        env = src.env  # first: a probe still loading brings its background with it
        if src.background is None:
            if env is None:
                return None
            src.background = background_payload(env)
        return src.background


def unpack_files(data: bytes, most: int = 6) -> list[tuple[str, bytes]]:
    """Several files in one request body, as the page packs them: uint32 (little-endian)
    length of a JSON header ``{"files": [{"name": str, "size": int}, ...]}``, the header, then
    the files' bytes one after another. Malformed bodies are a one-line ShprobeError."""
    bad = ShprobeError("malformed multi-file upload")
    if len(data) < 4:
        raise bad
    n = int.from_bytes(data[:4], "little")
    if not 0 < n <= min(len(data) - 4, 1 << 16):
        raise bad
    try:
        files = json.loads(data[4: 4 + n].decode())["files"]
        items = [(str(f["name"]), int(f["size"])) for f in files]
    except (ValueError, KeyError, TypeError, OverflowError, UnicodeDecodeError):
        raise bad from None  # OverflowError: "size": 1e999 → int(inf)
    if not 0 < len(items) <= most or any(s < 0 for _, s in items) \
            or sum(s for _, s in items) != len(data) - 4 - n:
        raise bad
    out, off = [], 4 + n
    for name, size in items:
        out.append((name, data[off: off + size]))
        off += size
    return out


def load_probe(path: str | list[str], layout: str = "auto", name: str | None = None) -> Source:
    """A probe — one file, or six cube-face files +X −X +Y −Y +Z −Z — as a :class:`Source`,
    read by the library's one resolver (:func:`shprobe.lighting.source.resolve_lighting`:
    decoded, projected to lmax 2) and checked; one-line :class:`ShprobeError` naming the file
    when it is bad."""
    import time

    from ..lighting.source import resolve_lighting

    lit = resolve_lighting(path, layout=None if layout == "auto" else layout, lmax=2,
                           need_env=True)
    decoded = time.time()
    env = lit.env
    where = name or lit.source
    rad = env.radiance
    if not np.all(np.isfinite(rad)):
        raise ShprobeError("probe has non-finite (NaN or Inf) pixels", where)
    if float(rad.min()) < 0:
        raise ShprobeError("probe has negative pixels", where)
    src = Source(where, np.asarray(lit.coeffs, np.float64), env)
    if not np.all(np.isfinite(src.coeffs2)):
        raise ShprobeError("probe projects to non-finite coefficients", where)
    src.decoded_at = decoded
    return src


def mesh_payload(mesh: Any, name: str) -> bytes:
    """What the page draws, in one :func:`pack_binary` message: positions, normals, albedo
    (V, 3) as the renderer reads them, faces, and the library camera framing the bounding
    sphere. ``mesh`` None: the renderer's analytic unit sphere (drawn as a fine icosphere)."""
    from ..scene import Camera, bounding_sphere, mesh_vertex_albedo, sphere_mesh

    m = mesh if mesh is not None else sphere_mesh(5)
    alb = mesh_vertex_albedo(m)
    v = np.asarray(m.vertices)
    if mesh is None:  # the analytic unit sphere of the renderer
        c, r = np.zeros(3), 1.0
    else:
        c, r = bounding_sphere(mesh)
    return pack_binary({"name": name, "center": c.tolist(), "radius": r,
                        "camera": camera_json(Camera(512, 512), c, r)},
                       {"position": v, "normal": np.asarray(m.vertex_normals),
                        "albedo": np.ones_like(v) if alb is None else alb,
                        "index": np.asarray(m.faces)})


@overload
def cached_mesh_payload(path: str, name: str) -> bytes: ...
@overload
def cached_mesh_payload(path: str, name: str, make: bool) -> bytes | None: ...
def cached_mesh_payload(path: str, name: str, make: bool = True) -> bytes | None:
    """:func:`mesh_payload` of the mesh file ``path``, kept in shprobe's on-disk cache
    (:func:`shprobe.files.read_cache`, kind ``viewer_mesh``) under the file's content and the
    code that makes the payload, so that a mesh opened before — the default bunny, a user's
    own model — reaches the page without importing trimesh (0.4 CPU-s on this machine, most
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
    """Identifies the code behind :func:`mesh_payload` (this module, the scene layer, trimesh,
    shprobe's version): any change of it, an edit or an upgrade, makes a new cache key. Read
    from the files' sizes and times, without importing trimesh."""
    import importlib.util

    from .. import __version__

    here = Path(__file__).resolve()
    files = [here, *sorted((here.parents[1] / "scene").glob("*.py"))]
    spec = importlib.util.find_spec("trimesh")
    if spec is not None and spec.origin:
        files.append(Path(spec.origin))
        files.append(Path(spec.origin).with_name("version.py"))
    stamp = [__version__, "mesh_payload 1"]
    for f in files:
        try:
            st = f.stat()
            stamp.append(f"{f.name}:{st.st_size}:{st.st_mtime_ns}")
        except OSError:
            stamp.append(f"{f.name}:-")
    return "|".join(stamp)


def background_payload(env: Any) -> bytes:
    """The probe resampled to a :data:`BACKGROUND_H` × 2·:data:`BACKGROUND_H` lat-long grid
    (the library's directions and bilinear lookup, :meth:`Env.sample`; lat-long probes larger
    than it box-filtered), RGBA half floats in a :func:`pack_binary` message."""
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


def camera_json(cam: Any, center: NDArray, radius: float) -> dict[str, Any]:
    """The library camera (:class:`shprobe.scene.render.Camera`) as the page needs it."""
    c, d, _ = cam.framing(center, radius)
    fwd, _, up = cam.basis()
    eye = c - d * fwd
    return {"eye": eye.tolist(), "target": list(map(float, c)), "up": up.tolist(),
            "fov": cam.fov, "width": cam.width, "height": cam.height,
            "azimuth": cam.azimuth, "elevation": cam.elevation,
            "near": max(d - 2.0 * radius * cam.margin, 1e-3 * d), "far": d + 50.0 * radius}


def compare_data(src: Source, progress: Any = None) -> dict[str, Any]:
    """The compare view's numbers and lookup textures, all from the library: the brute-force
    irradiance (``reference_irradiance``) and the SH irradiance of every lmax 1..N
    (``irradiance``) on the normals of ``error_report`` (a (2N)×N lat-long grid, N =
    :data:`NORMAL_GRID`), and R&H's error metric per lmax (``error_report``, §3.1)."""
    from ..lighting.irradiance import irradiance
    from ..lighting.projection import total_intensity
    from ..lighting.reference import error_report, reference_irradiance
    from ..probes.layouts import LatLong
    from ..sh import num_coeffs

    env = src.env
    if env is None:
        raise ShprobeError(f"{src.name} has no probe image: the exact irradiance needs one")
    h = NORMAL_GRID
    nrm = LatLong().pixel_directions((h, 2 * h)).reshape(-1, 3)
    ref = reference_irradiance(env, nrm, progress=progress)
    lmaxes = tuple(range(1, MAX_LMAX + 1))
    rep = error_report(env, lmaxes, reference=ref, normal_grid=h)
    maps = {lm: irradiance(src.coeffs[: num_coeffs(lm)], nrm).reshape(h, 2 * h, 3)
            for lm in lmaxes}
    from ..lighting.glsl import glsl_uniform_values

    return {"grid": [h, 2 * h], "reference": ref.reshape(h, 2 * h, 3),
            # E_lm of the probe at lmax N: the page's per-pixel SH at each lmax 1..N
            "irradiance": glsl_uniform_values(src.coeffs, MAX_LMAX).tolist(),
            "maps": maps, "total_intensity": total_intensity(env).tolist(),
            "rows": [{"lmax": r.lmax, "mean_frac": r.mean_frac, "max_frac": r.max_frac,
                      "mean_rel": r.mean_rel} for r in rep.rows]}


def hbasis_panel(session: Session, state: dict[str, Any], size: int = 160
                 ) -> tuple[bytes, dict[str, float]]:
    """Irradiance normal mapping (Habel & Wimmer 2010) as ``shprobe hbasis render`` draws it,
    for the page's lighting: the mesh with a procedural bump, shaded by per-vertex H6, H4 and
    tangent-space SH9 baked from the lighting at lmax 4 (the page's edits and rotation
    applied), against the reference E(n′) — brute force over the probe (box-filtered to 64×128
    and turned by the page's rotation; the other edits are not applied to it) or, for a preset,
    the lighting's own SH expansion. → (PNG of ``panel_image``, relative RMS per basis)."""
    import io

    from PIL import Image

    from ..hbasis.rendering import panel_image, render_normal_mapped
    from ..probes.env import Env
    from ..probes.layouts import LatLong
    from ..probes.tonemap import auto_exposure, tonemap
    from ..scene import sphere_mesh

    st = {**state, "lmax": 4}
    L, _ = design_coeffs(session.base(4), st, session.probe_coeffs)
    env = session.source.env
    if env is not None:  # the probe turned by the page's rotation: L'(p) = L(Rᵀp)
        h = 64
        dirs = LatLong().pixel_directions((h, 2 * h))
        lighting = Env(np.asarray(env.sample(dirs @ rotation_matrix(state)), np.float32),
                       LatLong())
    else:
        lighting = L
    mesh = session.mesh if session.mesh is not None else sphere_mesh(4)
    res = render_normal_mapped(mesh, lighting, size=size)
    stops = auto_exposure(res.irradiance[res.mask], target=1.0)
    buf = io.BytesIO()
    Image.fromarray(tonemap(panel_image(res), stops)).save(buf, format="PNG")
    return buf.getvalue(), res.info["rel_rms"]
