"""One start-up for every page of the viewer: [`serve`][shprobe.viewer.serve]
(``shprobe.viewer.serve``) takes a page's model — a `Session` (the designer page) or a
`GridView` (the grid page) — listens, starts the page's loading,
builds the app while it loads, and runs the server once the page is ready; a start-up failure
(a port in use, a bad file) is one line and no URL.

The order matters for the first frame: the socket is bound first (a port in use fails before
anything starts), then the session's files start loading (its loader forks before any thread
starts and before the web framework is imported), then Starlette and uvicorn are imported and
the app is built while the files load.
"""

from __future__ import annotations

import socket
from collections.abc import Callable
from typing import Any

from ..errors import ShprobeError

__all__ = ["listen", "page_path", "serve"]


def listen(host: str, port: int) -> socket.socket:
    """A listening socket on ``host``:``port`` (0: a free port). The page's first connection
    waits in its backlog until the server runs.

    Parameters
    ----------
    host : str
        Address to bind.
    port : int
        Port (0: a free one).

    Returns
    -------
    socket.socket
        The bound, listening socket.

    Raises
    ------
    ShprobeError
        One line when it cannot be had (a port in use, an address not of this machine).
    """
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except (OSError, OverflowError) as e:
        sock.close()
        reason = getattr(e, "strerror", None) or str(e)
        raise ShprobeError(f"cannot listen on {host}:{port}: {reason}") from None
    sock.listen(128)
    return sock


def page_path(page: Any) -> str:
    """The URL path of ``page``: ``/grid`` for a grid view, ``/`` for the designer, else the
    page object's own ``url_path`` (the lightmap view's ``/lightmap``)."""
    from .session import Session

    if isinstance(page, Session):
        return "/"
    return getattr(page, "url_path", "/grid")


def serve(page: Any, host: str = "127.0.0.1", port: int = 0,
          on_ready: Callable[[str], None] | None = None, check_host: bool = True) -> None:
    """Serve ``page`` until the server is stopped (Ctrl-C).

    Parameters
    ----------
    page : Session or GridView
        The page's model. A session not loaded yet is loaded here (`Session.start`),
        its files read before ``on_ready`` is called; it is closed when the server stops.
    host : str
        Address to bind.
    port : int
        Port (0: a free one).
    on_ready : callable or None
        Called with the page's URL (with its token) once the page is ready (the CLI prints it
        and opens a browser).
    check_host : bool
        Check the Host header against the local names (False: any Host, e.g. ``0.0.0.0``).

    Raises
    ------
    ShprobeError
        One line when the port cannot be had or a file is bad (no URL is given then).
    """
    from . import new_token
    from .session import Session

    session = page if isinstance(page, Session) else None
    sock = listen(host, port)
    try:
        if session is not None:
            session.start()  # the loader forks now, before any thread and the web framework
        from .app import create_app, make_server

        port = sock.getsockname()[1]
        token = new_token()
        server = make_server(create_app(session, token, host, port, check_host=check_host,
                                        grid=None if session is not None else page))
        if session is not None:
            session.wait()
    except BaseException:
        sock.close()
        if session is not None:
            session.close()
        raise
    shown = "127.0.0.1" if host in ("0.0.0.0", "::") else host
    shown = f"[{shown}]" if ":" in shown else shown
    if on_ready is not None:
        on_ready(f"http://{shown}:{port}{page_path(page)}?token={token}")
    if session is not None:
        session.stamp("url")
    try:
        server.run(sockets=[sock])
    finally:
        if session is not None:
            session.close()
