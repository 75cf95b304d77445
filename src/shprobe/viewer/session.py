"""The viewer's session: what one ``shprobe view`` serves — the files named on the command line
(the probe and the mesh through the loader, `shprobe.viewer.loader`: forked or in threads, one
path), the files uploaded through the page (`shprobe.viewer.uploads`), the lighting source, the
page's designs (`shprobe.viewer.design`) and its long views; by concern, the probes kept for
blending (`shprobe.viewer.shelf`) and the mesh, transfer and H-basis bake
(`shprobe.viewer.scenefiles`). No HTTP here (`shprobe.viewer.app`)."""

from __future__ import annotations

import os
import secrets
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..lighting.edits import EditSpec
from ..progress import Fraction
from .design import Designed, Designer, design_coeffs
from .loader import fork_loader, inline_loader, mesh_to_load
from .payloads import background_payload
from .scenefiles import SceneFiles
from .shelf import ProbeShelf
from .source import Source, env_source, load_probe, preset_source
from .uploads import Uploads
from .views import hbasis_panel, is_rotation_only

__all__ = ["Session", "Task"]


@dataclass
class Task:
    """A long library call running off the event loop, and its outcome as the page polls it;
    ``done``, the fraction of the stage under way, is kept by `progress` (a
    [`shprobe.progress.Fraction`][shprobe.progress.Fraction] reporter handed to the library
    call)."""

    done: float = 0.0
    status: str = "idle"  # idle | running | done | error
    message: str = ""
    result: Any = None

    @property
    def progress(self) -> Fraction:
        """The reporter to give the library call: it sets `done`."""
        return Fraction(lambda f: setattr(self, "done", f))


class Session(ProbeShelf, SceneFiles):
    """Everything one ``shprobe view`` serves: sources (the probes kept for blending:
    `ProbeShelf`), mesh, transfer and H-basis bake
    (`SceneFiles`), uploads, designs."""

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
        """Record stage ``name`` at ``t`` (now) in `stamps`, when timing is on
        (``first``: only if not recorded yet)."""
        if self.stamps is not None and not (first and name in self.stamps):
            import time

            self.stamps[name] = time.time() if t is None else t

    def _mesh_arg(self) -> str | None:
        return mesh_to_load(*self._args[2:])

    def fork_loader(self) -> None:
        """Start loading the probe and the mesh named on the command line in a forked
        process (`shprobe.viewer.loader.fork_loader`; ``shprobe view`` calls it before
        any thread starts and before the server is imported): `load` then takes the
        lmax-2 coefficients and the page's mesh arrays from it (the first frame needs no
        more); the [`Env`][shprobe.probes.env.Env] (compare, H-basis, lmax > 2), its coefficients at
        `MAX_LMAX` and the background texture follow in a
        thread. The trimesh object is loaded in this process only when a view needs it
        (`mesh`); the Env is sent when a view first needs it (`Source.env` sets
        the loader's ``go``), so that until then the first frame has the cores. Without a
        fork (not Linux, or nothing to load) `load` reads the files itself."""
        loader = fork_loader(self._args[0], self.layout, self._mesh_arg())
        if loader is not None:
            self.stamp("load_start")
            self._child, self._go = loader

    def start(self) -> None:
        """Start reading the files named on the command line: the forked loader
        (`fork_loader`), then `load` in a thread; `wait` waits for it."""
        self.fork_loader()  # before any thread starts
        threading.Thread(target=self._load_quietly, daemon=True).start()

    def _load_quietly(self) -> None:
        try:
            self.load()
        except BaseException:  # kept in self.error; wait() raises it
            pass

    def wait(self) -> None:
        """Wait until the files named on the command line are read; their one-line error,
        if any, is raised."""
        self.ready.wait()
        if self.error is not None:
            raise self.error

    def load(self) -> None:
        """Read the files named on the command line: the probe and the mesh through the loader
        (the process `fork_loader` started, else `inline_loader`'s
        threads), a transfer and an H-basis bake here; sets `ready`, and `error`
        when one of them is bad (then re-raised)."""
        probe, preset, _, transfer = self._args
        mesh_path = self._mesh_arg()
        errors: list[BaseException] = []
        self.stamp("load_start", first=True)
        if self._child is None:  # not forked (fork_loader): the same loader, in threads
            loader = inline_loader(probe, self.layout, mesh_path)
            if loader is not None:
                self._child, self._go = loader
        from_loader = self._child is not None

        def geometry() -> None:
            try:
                if transfer:
                    self.load_transfer(transfer)
                if self._hbasis_arg:  # checked against the mesh below, once it is in
                    self._read_hbasis(self._hbasis_arg)
            except BaseException as e:  # re-raised below, in the caller's thread
                errors.append(e)

        th = threading.Thread(target=geometry, daemon=True)
        th.start()
        try:
            if from_loader:  # the probe (the source) and the mesh's page arrays
                self._load_from_loader(probe, mesh_path)
            if probe:
                pass
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

    def _load_from_loader(self, probe: str | None, mesh_path: str | None) -> None:
        """`load`'s probe and mesh from the loader (forked or in threads: the same
        messages, `shprobe.viewer.loader`): the one path of a command line's probe to the
        session."""
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
        if self._go is not None:  # a loader waiting to send the Env sends it (into a closed
            self._go.set()        # pipe) and ends now, not ENV_WAIT later
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
        """The page's design of ``spec`` (fast during a drag: `Designer`); exports use
        `design_exact`."""
        return self._designer.design(self.source, self.base, spec, self.blend_coeffs)

    def design_exact(self, spec: EditSpec) -> tuple[NDArray[np.float64], str | None]:
        """(L_lm, window description) of ``spec`` by the CLI's exact sequence of operations
        (`design_coeffs`)."""
        return design_coeffs(self.base(spec.lmax), spec, self.blend_coeffs)

    def hbasis(self, spec: EditSpec) -> tuple[bytes, dict[str, float]]:
        """The H-basis panel (`hbasis_panel`) for ``spec`` at
        lmax 4; with an H-basis bake loaded, its per-vertex coefficients under the lighting
        they were baked for (``spec`` does not apply: a bake holds its lighting)."""
        bk = self.hbasis_bake
        if bk is not None:  # the same picture whatever the edits: made once per bake
            hit = self._hbasis_made
            if hit is None or hit[0] is not bk:
                hit = self._hbasis_made = (bk, hbasis_panel(bk.lighting, None, np.eye(3),
                                                            self.mesh, baked=bk))
            return hit[1]
        spec4 = spec.with_lmax(4)
        L, _ = self.design_exact(spec4)
        # the probe itself (turned) where the design is the probe turned; else the edited SH
        env = self.source.env if is_rotation_only(spec4) else None
        return hbasis_panel(L, env, spec.rotation_matrix(), self.mesh)

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

    # pictures ---------------------------------------------------------------
    def background_bytes(self) -> bytes | None:
        """The source's background texture (`background_payload`), None for a preset."""
        src = self.source
        env = src.env  # first: a probe still loading brings its background with it
        if src.background is None:
            if env is None:
                return None
            src.background = background_payload(env)
        return src.background
