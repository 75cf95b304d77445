"""The viewer's session: what one ``shprobe view`` serves — the files named on the command line
(read by the forked loader, :mod:`.loader`, or here), the files uploaded through the page
(:mod:`.uploads`), the lighting source and the probes kept for blending, the mesh and the
optional PRT transfer, and the page's designs (:mod:`.design`). No HTTP here (:mod:`.app`)."""

from __future__ import annotations

import os
import secrets
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..lighting.edits import Blend, EditSpec
from .design import DESIGN_LMAX, Designed, Designer, design_coeffs
from .loader import fork_loader, mesh_to_load
from .payloads import background_payload, ground_mask, mesh_payload, view_cameras
from .source import Source, env_source, load_probe, preset_source
from .uploads import Uploads
from .views import hbasis_panel
from .wire import pack_binary

__all__ = ["Session", "Task"]


@dataclass
class Task:
    """A long library call running off the event loop, and its progress as the page polls
    it: a :class:`shprobe.progress.Progress` reporter (``done`` is the fraction of the stage
    under way)."""

    done: float = 0.0
    status: str = "idle"  # idle | running | done | error
    message: str = ""
    result: Any = None
    _total: float | None = None

    def begin(self, description: str, total: float | None = None) -> None:
        self._total, self.done = total, 0.0

    def update(self, done: float) -> None:
        self.done = min(done / self._total, 1.0) if self._total else 0.0

    def end(self) -> None:
        self.done = 1.0


class Session:
    """Everything one ``shprobe view`` serves: sources, mesh, transfer, uploads."""

    def __init__(self, probe: str | None = None, preset: str | None = None,
                 mesh: str | None = None, transfer: str | None = None,
                 layout: str = "auto", load: bool = True,
                 stamps: dict[str, float] | None = None, hbasis: str | None = None) -> None:
        self.layout = layout
        self._args = (probe, preset, mesh, transfer)
        self._hbasis_arg = hbasis
        #: a ``shprobe hbasis bake`` file's per-vertex coefficients (``--hbasis``, an upload)
        self.hbasis_bake: Any = None
        self.hbasis_name: str | None = None
        self._hbasis_made: Any = None  # (bake, its panel)
        self.uploads = Uploads()
        self.lock = threading.Lock()
        self.tasks: dict[str, Task] = {}
        self._designer = Designer()
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
        #: a timing hook: given a dict, the wall-clock times (time.time()) of the loading
        #: stages are recorded in it (``shprobe view`` with SHPROBE_VIEW_STAMPS set, for
        #: bench/bench_viewer.py); None records nothing
        self.stamps = stamps
        self._child: Any = None  # [(process, pipe)] of fork_loader
        self._go: Any = None  # its Go: send the Env now
        #: probes loaded (command line, uploads): id → (file name as the user gave it, Source)
        self.probes: dict[str, tuple[str, Source]] = {}
        self._probe_tag = f"p{secrets.token_hex(3)}"  # ids of another server never match
        if load:
            self.load()

    def stamp(self, name: str, t: float | None = None, first: bool = False) -> None:
        """Record stage ``name`` at ``t`` (now) in :attr:`stamps`, when timing is on
        (``first``: only if not recorded yet)."""
        if self.stamps is not None and not (first and name in self.stamps):
            import time

            self.stamps[name] = time.time() if t is None else t

    def _mesh_arg(self) -> str | None:
        return mesh_to_load(*self._args[2:])

    def fork_loader(self) -> None:
        """Start loading the probe and the mesh named on the command line in a forked
        process (:func:`shprobe.viewer.loader.fork_loader`; ``shprobe view`` calls it before
        any thread starts and before the server is imported): :meth:`load` then takes the
        lmax-2 coefficients and the page's mesh arrays from it (the first frame needs no
        more); the :class:`Env` (compare, H-basis, lmax > 2), its coefficients at
        :data:`~shprobe.viewer.source.MAX_LMAX` and the background texture follow in a
        thread. The trimesh object is loaded in this process only when a view needs it
        (:attr:`mesh`); the Env is sent when a view first needs it (:attr:`Source.env` sets
        the loader's ``go``), so that until then the first frame has the cores. Without a
        fork (not Linux, or nothing to load) :meth:`load` reads the files itself."""
        loader = fork_loader(self._args[0], self.layout, self._mesh_arg())
        if loader is not None:
            self.stamp("load_start")
            self._child, self._go = loader

    def load(self) -> None:
        """Read the files named on the command line (probe and mesh in parallel, or from the
        process :meth:`fork_loader` started); sets :attr:`ready`, and :attr:`error` when one
        of them is bad (then re-raised)."""
        probe, preset, _, transfer = self._args
        mesh_path = self._mesh_arg()
        errors: list[BaseException] = []
        self.stamp("load_start", first=True)
        forked = self._child is not None

        def geometry() -> None:
            try:
                if transfer:
                    self.load_transfer(transfer)
                if mesh_path and not forked:
                    self.load_mesh(mesh_path, os.path.basename(mesh_path))
                    self.stamp("geometry_done")
                if self._hbasis_arg:  # checked against the mesh below, once it is in
                    self._read_hbasis(self._hbasis_arg)
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
                self.source = preset_source(preset)
            elif self._hbasis_arg:  # the lighting the bake was made for
                th.join()
                if self.hbasis_bake is not None:
                    self.source = self._bake_source()
            elif not probe:
                from ..probes.environments import procedural_env

                self.source = env_source(procedural_env(256, 128), "procedural sky")
        except BaseException as e:
            errors.append(e)
        self.stamp("source_done", first=True)
        th.join()
        if self.hbasis_bake is not None and not errors:
            try:
                self._check_hbasis(self.hbasis_bake, self._hbasis_arg)
            except BaseException as e:
                errors.append(e)
        self.stamp("ready")
        if errors:
            e = errors[0]
            self.error = e if isinstance(e, ShprobeError) else ShprobeError(str(e))
            self.ready.set()
            raise self.error
        self.ready.set()

    def _load_forked(self, probe: str | None, mesh_path: str | None) -> None:
        """:meth:`load`'s probe and mesh from the forked processes
        (:func:`~shprobe.viewer.loader._load_child`)."""
        name = os.path.basename(mesh_path) if mesh_path else None
        src: Source | None = None
        try:
            for _, recv in self._child:
                while True:
                    kind, *data = recv.recv()
                    if kind == "error":
                        raise ShprobeError(data[0])
                    for k, t in data[-1].items():
                        self.stamp(k, t)
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
        self.uploads.close()

    # designs ----------------------------------------------------------------
    def design(self, spec: EditSpec) -> Designed:
        """The page's design of ``spec`` (fast during a drag: :class:`Designer`); exports use
        :meth:`design_exact`."""
        return self._designer.design(self.source, self.base, spec, self.blend_coeffs)

    def design_exact(self, spec: EditSpec) -> tuple[NDArray[np.float64], str | None]:
        """(L_lm, window description) of ``spec`` by the CLI's exact sequence of operations
        (:func:`~shprobe.viewer.design.design_coeffs`)."""
        return design_coeffs(self.base(spec.lmax), spec, self.blend_coeffs)

    def hbasis(self, spec: EditSpec) -> tuple[bytes, dict[str, float]]:
        """The H-basis panel (:func:`~shprobe.viewer.views.hbasis_panel`) for ``spec`` at
        lmax 4; with an H-basis bake loaded, its per-vertex coefficients under the lighting
        they were baked for (``spec`` does not apply: a bake holds its lighting)."""
        bk = self.hbasis_bake
        if bk is not None:  # the same picture whatever the edits: made once per bake
            hit = self._hbasis_made
            if hit is None or hit[0] is not bk:
                hit = self._hbasis_made = (bk, hbasis_panel(bk.lighting, None, np.eye(3),
                                                            self.mesh, baked=bk))
            return hit[1]
        L, _ = self.design_exact(spec.with_lmax(4))
        return hbasis_panel(L, self.source.env, spec.rotation_matrix(), self.mesh)

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

    def blend_coeffs(self, blend: Blend, lmax: int) -> NDArray[np.float64]:
        """A blend of the page's design: a preset, or a probe this session loaded (by id);
        never a file named by the page."""
        from ..lighting.source import blend_lighting

        if blend.kind == "probe":
            return self.probe_coeffs(blend.name, lmax)
        if blend.kind != "preset":
            raise ShprobeError("the page blends presets and the probes this server loaded")
        return blend_lighting(blend, lmax)

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
        return load_probe(path, self.layout, name,
                          lambda k: self.stamp(k, first=True))

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
        self.hbasis_bake = None  # per vertex of the mesh it was baked for

    def load_transfer(self, path: str, name: str | None = None) -> None:
        """A transfer file (``shprobe prt bake``), read by the library's checked reader; an
        H-basis bake given instead is named as one."""
        from ..hbasis.bakefile import is_bake
        from ..prt.transfer import load_transfer

        if is_bake(path):
            raise ShprobeError("is an H-basis bake (`shprobe hbasis bake`), not a PRT "
                               "transfer: open it with `shprobe view --hbasis FILE` or the "
                               "page's H-basis loader", name or path)
        self.transfer = load_transfer(path)
        self.transfer_name = name or os.path.basename(path)

    def _read_hbasis(self, path: str, name: str | None = None) -> None:
        """Read a ``shprobe hbasis bake`` file (:func:`~shprobe.hbasis.bakefile.load_bake`);
        a PRT transfer given instead is named as one."""
        from ..hbasis.bakefile import is_bake, load_bake

        shown = name or os.path.basename(path)
        if not is_bake(path) and str(path).lower().endswith(".npz"):
            from ..files import npz_headers

            try:
                heads = npz_headers(path, "bake file")
            except ShprobeError:
                heads = {}
            if "vertices" in heads:
                raise ShprobeError("is a PRT transfer (`shprobe prt bake`), not an H-basis "
                                   "bake: open it with `shprobe view --transfer FILE`",
                                   name or path)
        self.hbasis_bake = load_bake(path)
        self.hbasis_name = shown

    def _check_hbasis(self, bake: Any, path: Any) -> None:
        """Refuse a bake made for another mesh than the one shown (one line)."""
        from ..scene import mesh_hash

        m = self.mesh
        if m is None:
            raise ShprobeError("an H-basis bake is per vertex of its mesh: give that mesh "
                               "with --mesh", path)
        if mesh_hash(m.vertices, m.faces) != bake.mesh_hash:
            raise ShprobeError(f"was baked for another mesh than {self.mesh_name}: give the "
                               "mesh it was baked for with --mesh", path)

    def load_hbasis(self, path: str, name: str | None = None) -> None:
        """An H-basis bake (``shprobe hbasis bake``) for the mesh shown, checked against it
        (the bake shown before is kept when this one is refused)."""
        keep = (self.hbasis_bake, self.hbasis_name)
        try:
            self._read_hbasis(path, name)
            self._check_hbasis(self.hbasis_bake, name or path)
        except BaseException:
            self.hbasis_bake, self.hbasis_name = keep
            raise

    def _bake_source(self) -> Source:
        """The lighting an H-basis bake was made for (its radiance SH, to the design's
        highest degree) as the source."""
        L = np.asarray(self.hbasis_bake.lighting, np.float64)
        return Source(f"{self.hbasis_name} (baked lighting)", L[: (DESIGN_LMAX + 1) ** 2])

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
            raise ShprobeError("no transfer loaded: the session was opened without one")
        T = t.select(mode, bounces)
        v = np.asarray(t.vertices)
        # framed on the object; the ground plane (the last vertices) is seen around it
        flat = ground_mask(v, t.normals, bool(t.metadata.get("ground")))
        ng = int(flat.sum())
        obj = v[~flat] if ng < len(v) else v
        c = 0.5 * (obj.min(axis=0) + obj.max(axis=0))
        r = float(np.sqrt(((obj - c) ** 2).sum(axis=1).max()))
        return pack_binary(
            {"name": self.transfer_name, "lmax": t.lmax, "modes": list(t.modes),
             "max_bounces": t.max_bounces, "mode": mode or t.mode, "bounces": bounces,
             "ground_vertices": ng, "center": c.tolist(), "radius": r,
             **view_cameras(c, r, ground=ng > 0)},
            {"position": v, "normal": t.normals, "index": t.faces,
             "transfer": T.reshape(T.shape[0], -1)})

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
