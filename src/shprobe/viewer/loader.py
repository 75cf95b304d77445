"""The viewer's file loader: what reads the probe and the mesh named on the command line while
the server starts and the page loads. One interface (`Loader`: per file a (worker,
receiving end) pair sending the same messages, and the `Go` that asks for the Env), two
implementations: a forked process (`fork_loader`, ``shprobe view`` on Linux) and threads
of this process (`inline_loader`, everywhere else); the session reads either the same
way (`shprobe.viewer.session.Session.load`), so a probe has one path to it.

``shprobe view`` forks it as soon as numpy, the viewer's model and the lighting layer are
imported (both sides need them: imported once, shared by the fork), before the server is
imported or built, so that the loader's work starts at once on the second core. The probe is
decoded and projected by NumPy alone (no compiled kernel to start: a 2048×1024 .hdr in about
0.15 s); a mesh opened before needs no trimesh: its page arrays come from shprobe's on-disk
cache (`shprobe.viewer.payloads.cached_mesh_payload`). The children send the first
frame's data (the probe's lmax-2 coefficients, the page's mesh arrays) first; the Env, its
higher coefficients and the background texture follow when the server asks
(`shprobe.viewer.session.Session.fork_loader` takes them).
"""

from __future__ import annotations

import os
import threading
from pathlib import Path
from typing import Any, NamedTuple

from ..errors import ShprobeError

__all__ = ["ENV_WAIT", "Go", "Loader", "default_mesh_path", "fork_loader", "inline_loader",
           "mesh_to_load", "start_loader"]


def default_mesh_path() -> Path | None:
    """The packaged Stanford bunny ([`shprobe.scene.mesh.bunny_path`][shprobe.scene.bunny_path])."""
    from ..scene.mesh import bunny_path

    return bunny_path()


def mesh_to_load(mesh: str | None, transfer: str | None) -> str | None:
    """The mesh file ``shprobe view`` loads: ``--mesh``; none with ``--transfer`` alone (the
    transfer carries its geometry); else `default_mesh_path`."""
    if mesh or transfer:
        return mesh
    p = default_mesh_path()
    return None if p is None else str(p)


#: The probe's Env (and what is made from it) is sent when the server asks for it
#: (:class:`Loader` ``.go``) or this many seconds after the first frame's data at the latest.
ENV_WAIT = 2.0


class Go:
    """The server's "send the Env now" to the loader: one byte down a pipe, which the loader
    waits for with a timeout. A pipe, not a ``multiprocessing.Event``: the loader may be
    killed at any moment (a new probe, Ctrl-C), and a process killed inside an Event's wait,
    or between a set() and its wake-up, takes the event's lock with it — every later set()
    then hangs. Writing to a pipe whose reader is gone just fails (ignored)."""

    def __init__(self) -> None:
        self._r, self._w = os.pipe()
        os.set_blocking(self._w, False)
        self._lock = threading.Lock()

    def set(self) -> None:
        """Tell the loader (any thread; a no-op once closed, when the pipe is full — it was
        told already — or when the loader is gone)."""
        with self._lock:
            if self._w >= 0:
                try:
                    os.write(self._w, b"g")
                except OSError:  # EAGAIN: told already; EPIPE: the loader has ended
                    pass

    def wait(self, timeout: float) -> bool:
        """In the loader: True once told, False after ``timeout`` seconds."""
        import select

        return bool(select.select([self._r], [], [], timeout)[0])

    def close_reader(self) -> None:
        """The server's side, after the fork: it only writes."""
        if self._r >= 0:
            os.close(self._r)
            self._r = -1

    def close(self) -> None:
        """Close the writing end (the server's side when the loader is stopped, and the
        loader's copy at its start); set() is a no-op from then on (the descriptor number is
        never written again)."""
        with self._lock:
            if self._w >= 0:
                os.close(self._w)
                self._w = -1


class Loader(NamedTuple):
    """The forked loader: one (process, receiving pipe end) per file, the probe's first, and
    the `Go` that lets the probe's process send the Env (set when a view needs it:
    until then the first frame has the two cores)."""

    child: list[tuple[Any, Any]]
    go: Go


def fork_loader(probe: str | None, layout: str, mesh: str | None) -> Loader | None:
    """Fork the loader of ``probe`` and ``mesh`` (`_loader`; call before any thread
    starts); ``None`` where there is nothing to load or no fork (not Linux)."""
    ctx = _fork_context()
    if ctx is None or not (probe or mesh):
        return None
    name = os.path.basename(mesh) if mesh else None
    go = Go()
    pipes = [ctx.Pipe(duplex=False) if p else (None, None) for p in (probe, mesh)]
    proc = ctx.Process(target=_loader, args=(pipes[0][1], pipes[1][1], probe, layout, mesh,
                                             name, [r for r, _ in pipes if r], go), daemon=True)
    proc.start()
    go.close_reader()
    child = []
    for recv, send in pipes:  # [probe's pipe,] [mesh's pipe]
        if send is not None:
            send.close()
            child.append((proc, recv))
    return Loader(child, go)


def start_loader(probe: str | None, layout: str, mesh: str | None) -> Loader | None:
    """The loader of ``probe`` and ``mesh``: forked where the platform allows
    (`fork_loader`), else in threads (`inline_loader`); None with nothing to load.

    Parameters
    ----------
    probe : str or None
        The probe file named on the command line.
    layout : str
        Its layout ('auto' to detect).
    mesh : str or None
        The mesh file.

    Returns
    -------
    Loader or None
        The running loader.
    """
    return fork_loader(probe, layout, mesh) or inline_loader(probe, layout, mesh)


class _Conn:
    """One end of an in-process one-way pipe (`inline_loader`): ``send`` on the worker's
    side, ``recv`` on the session's (EOFError once the sender closed and all is read); a send
    after the receiver closed is dropped, as a send into a closed pipe fails."""

    _END = object()

    def __init__(self) -> None:
        import queue

        self._q: Any = queue.SimpleQueue()
        self._gone = False

    def send(self, msg: Any) -> None:
        if self._gone:
            raise BrokenPipeError("the receiving end is closed")
        self._q.put(msg)

    def recv(self) -> Any:
        msg = self._q.get()
        if msg is _Conn._END:
            self._q.put(msg)  # every later recv ends too
            raise EOFError
        return msg

    def close(self) -> None:
        """The sender's close (the end of its messages) or the receiver's (later sends are
        dropped): both, as each side closes its own copy of a real pipe."""
        self._gone = True
        self._q.put(_Conn._END)


class _Worker:
    """A loader thread with the part of a process's interface the session uses."""

    def __init__(self, target: Any, args: tuple[Any, ...]) -> None:
        self._thread = threading.Thread(target=target, args=args, daemon=True)
        self.exitcode: int | None = None

    def start(self) -> None:
        self._thread.start()

    def is_alive(self) -> bool:
        return self._thread.is_alive()

    def terminate(self) -> None:
        """A thread cannot be killed: its receiver is closed, so its next send ends it."""

    def join(self, timeout: float | None = None) -> None:
        self._thread.join(timeout)
        if not self._thread.is_alive():
            self.exitcode = 0

    def close(self) -> None:
        pass


def inline_loader(probe: str | None, layout: str, mesh: str | None) -> Loader | None:
    """The loader in threads of this process (no fork: not Linux, or a session made by a
    program or a test), sending what `fork_loader`'s processes send, in the same order,
    through in-process pipes; ``None`` where there is nothing to load.

    Parameters
    ----------
    probe : str or None
        The probe file.
    layout : str
        Its layout ('auto' to detect).
    mesh : str or None
        The mesh file.

    Returns
    -------
    Loader or None
        The running loader.
    """
    if not (probe or mesh):
        return None
    go = Go()
    name = os.path.basename(mesh) if mesh else None
    child = []
    for which in ("probe", "mesh"):
        path = probe if which == "probe" else mesh
        if not path:
            continue
        conn = _Conn()
        args = ((conn, probe, layout, None) if which == "probe"
                else (conn, None, layout, (mesh, name)))
        worker = _Worker(_load_child, (*args, 0, go if which == "probe" else None, None,
                                       False))
        worker.start()
        child.append((worker, conn))
    return Loader(child, go)


def _fork_context() -> Any:
    """multiprocessing's fork context on Linux, else None (macOS has fork, but forking a
    process that has loaded system frameworks is unsafe there)."""
    import multiprocessing
    import sys

    if not sys.platform.startswith("linux"):
        return None
    try:
        return multiprocessing.get_context("fork")
    except ValueError:
        return None


def _loader(pconn: Any, mconn: Any, probe: str | None, layout: str, mesh: str | None,
            mesh_name: str | None, theirs: list[Any], go: Go | None = None) -> None:
    """The process `fork_loader` starts (``theirs``: the parent's pipe ends, closed
    here). A mesh whose page arrays are cached is sent from here at once; otherwise, given
    both files, it forks again, so that the probe and the mesh (trimesh) load on two cores
    (`_load_child`)."""
    import signal
    import time

    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    for c in theirs:  # the parent's ends: a send fails (and the process ends) once it is gone
        c.close()
    if go is not None:  # the parent's end (the loader only reads)
        go.close()
    if mesh:
        from .payloads import cached_mesh_payload

        try:
            data = cached_mesh_payload(mesh, mesh_name or os.path.basename(mesh), make=False)
        except Exception:  # the cache is optional: _load_child reports a bad file
            data = None
        if data is not None:
            stamp = {"geometry_done": time.time()}
            if not probe:
                _send_mesh(mconn, data, stamp)
                os._exit(0)
            # sent after the probe's coefficients: the server reads that pipe first (a
            # payload larger than a pipe's buffer sent now would wait for it: a deadlock)
            _load_child(pconn, probe, layout, None, go=go, then=(mconn, data, stamp))
    if probe and mesh:
        pid = os.fork()
        if pid == 0:  # the mesh's process
            pconn.close()
            _load_child(mconn, None, layout, (mesh, mesh_name))

        def stop(signum: int, frame: Any) -> None:  # terminate() ends the mesh's process too
            try:  # (it holds the loader's sentinel: a join would wait for it)
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
            os._exit(1)

        signal.signal(signal.SIGTERM, stop)
        mconn.close()
        _load_child(pconn, probe, layout, None, wait=pid, go=go)
    _load_child(pconn if probe else mconn, probe, layout,
                (mesh, mesh_name) if mesh else None, go=go)


def _send_mesh(conn: Any, data: bytes, stamp: dict[str, float]) -> None:
    """The cached page arrays of the mesh, and the end of that pipe's first-frame data."""
    try:
        conn.send(("mesh", data, stamp))
        conn.send(("ready", {}))
        conn.close()
    except OSError:  # the server has gone
        pass


def _load_child(conn: Any, probe: str | None, layout: str,
                mesh: tuple[str, str | None] | None, wait: int = 0, go: Go | None = None,
                then: tuple[Any, bytes, dict[str, float]] | None = None,
                forked: bool = True) -> None:
    """In the loader's process (or its fork): the probe's lmax-2 coefficients, the page's
    mesh arrays (``mesh``: its path and shown name; or, given ``then``, the cached ones down
    their own pipe, read next), then —
    once ``go`` is set, or `ENV_WAIT` seconds later — the [`Env`][shprobe.probes.env.Env], its
    lmax-`MAX_LMAX` coefficients and the background texture, each sent when ready
    (with wall-clock stamps); a failure is one ("error", line) message. A forked process ends
    itself (``os._exit``, after reaping the process ``wait``): nothing of the parent's
    (threads, exit handlers, the CLI's signal handlers) runs there; ``forked=False`` (a
    thread, `inline_loader`) returns."""
    import time

    try:
        from .payloads import background_payload, cached_mesh_payload
        from .source import load_probe

        src = None
        if probe:
            stamps: dict[str, float] = {}
            src = load_probe(probe, layout, mark=lambda k: stamps.setdefault(k, time.time()))
            conn.send(("source", src.coeffs2, src.layout_name,
                       {**stamps, "source_done": time.time()}))
        if mesh:
            path, shown = mesh
            data = cached_mesh_payload(path, shown or os.path.basename(path))
            conn.send(("mesh", data, {"geometry_done": time.time()}))
        conn.send(("ready", {}))
        if then is not None:  # the server reads this pipe next
            _send_mesh(*then)
        if src is not None:
            if go is not None:  # the first frame first: its data is out, the Env waits
                go.wait(ENV_WAIT)
            env = src.env
            conn.send(("env", env, src.coeffs, background_payload(env),
                       {"env_sent": time.time()}))
    except (BrokenPipeError, ConnectionResetError):  # the session has gone: nothing to tell
        pass
    except ShprobeError as e:
        _tell(conn, ("error", str(e)))
    except Exception as e:  # a library bug: one line, the server stops
        _tell(conn, ("error", f"{type(e).__name__}: {e}".splitlines()[0]))
    finally:
        conn.close()
        if wait:
            os.waitpid(wait, 0)
        if forked:  # (``forked=False``: a thread of the session's process, which returns)
            os._exit(0)


def _tell(conn: Any, msg: Any) -> None:
    try:
        conn.send(msg)
    except OSError:  # the session has gone
        pass
