"""The viewer's ASGI application (Starlette): a thin HTTP shell over `shprobe.viewer.session`.

Security: every request must carry the session token (``?token=`` once — the page then holds it
in a same-site cookie — or the ``X-Shprobe-Token`` header), as Jupyter does; the Host header must
name the address the server was started on and an Origin, when sent, must be that same origin
(no DNS rebinding, no cross-site requests). The server opens only the files named on the
command line and the uploads it stored itself; no path from the page is ever opened.

The handlers are `shprobe.viewer.handlers.Handlers` (and ``/api/snippet`` here: the page's "Copy as
Python", `python_text`); heavy work (decoding, projection, the brute-force
reference) runs in worker threads off the event loop.
"""

from __future__ import annotations

import secrets
from functools import partial
from typing import Any

from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import PlainTextResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles
from starlette.types import ASGIApp, Receive, Scope, Send

from ..lighting.edits import EditSpec
from .handlers import Handlers, api, read_spec
from .session import Session
from .web import csp_of, static_dir

__all__ = ["create_app", "make_server", "python_text", "static_dir"]

#: longest query string accepted (the token and a few short parameters)
MAX_QUERY = 4096
#: longest request line or header block the server reads before it answers (a longer one is
#: read whole and refused, rather than the connection being reset under the client)
MAX_HEAD = 4 << 20
COOKIE = "shprobe_token_{port}"  # cookies ignore ports: one name per server


class Guard:
    """ASGI middleware: token, Host and Origin checks on every HTTP request."""

    def __init__(self, app: ASGIApp, token: str, hosts: set[str] | None, cookie: str) -> None:
        self.app, self.token, self.hosts, self.cookie = app, token, hosts, cookie

    def _ok_host(self, host: str) -> bool:
        return self.hosts is None or host.lower() in self.hosts

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        req = Request(scope)
        host = req.headers.get("host", "")
        if len(scope.get("query_string", b"")) > MAX_QUERY:
            await PlainTextResponse("request URI too long", 414)(scope, receive, send)
            return
        if not self._ok_host(host):
            await PlainTextResponse("forbidden host", 403)(scope, receive, send)
            return
        origin = req.headers.get("origin")
        if origin is not None and not (origin.startswith("http://")
                                       and self._ok_host(origin[7:]) and origin[7:] == host):
            await PlainTextResponse("forbidden origin", 403)(scope, receive, send)
            return
        given = (req.query_params.get("token") or req.headers.get("x-shprobe-token")
                 or req.cookies.get(self.cookie) or "")
        if not secrets.compare_digest(given.encode(), self.token.encode()):
            await PlainTextResponse("forbidden: this server needs the token printed by "
                                    "`shprobe view` (?token=...)", 403)(scope, receive, send)
            return
        await self.app(scope, receive, send)


def create_app(session: Session | None, token: str, host: str = "127.0.0.1", port: int = 0,
               check_host: bool = True, grid: Any = None) -> Starlette:
    """The viewer app for ``session``. ``port`` is the port it will listen on (for the Host
    check; ``check_host=False`` accepts any Host, e.g. ``--host 0.0.0.0``). ``grid`` (a
    `shprobe.viewer.grid.GridView`; session None): the grid page and its routes instead."""
    static = static_dir()
    index = (static / "index.html").read_text()
    h = Handlers(session, index, csp_of(index), token, COOKIE.format(port=port))
    routes = [*h.routes(), Route("/api/snippet", h.ready(partial(api(_snippet), h)),
                                 methods=["POST"]),
              Mount("/static", StaticFiles(directory=str(static)), name="static")]
    if grid is not None:  # `shprobe view --grid`: the grid page and its API, not the viewer's
        from .gridhandlers import GridHandlers

        cookie = COOKIE.format(port=port)
        # a page object with its own routes (the lightmap view), else the grid page's model
        own = grid.routes(csp_of, token, cookie) if hasattr(grid, "routes") else None
        routes = [*(own or GridHandlers(grid, token, cookie).routes()), routes[-1]]
    app = Starlette(routes=routes)
    hosts = None
    if check_host:
        hosts = {f"{h}:{port}" for h in ("127.0.0.1", "localhost", "[::1]")}
        if host not in ("127.0.0.1", "localhost", "0.0.0.0", "::"):
            hosts.add(f"{host}:{port}".lower())
    app.add_middleware(Guard, token=token, hosts=hosts, cookie=COOKIE.format(port=port))
    app.state.session = session
    return app


#: the base coefficients of the session's procedural sky (no probe given) in a snippet
PROCEDURAL = ("procedural sky", "shprobe.project(shprobe.procedural_env(256, 128), {lmax})")


def python_text(session: Session, spec: EditSpec) -> str:
    """The page's "Copy as Python": ``spec`` applied to the session's source, as library code
    (`shprobe.lighting.snippet.python_snippet`)."""
    from ..lighting.snippet import SnippetSource, python_snippet

    src = session.source
    code = PROCEDURAL[1] if src.name == PROCEDURAL[0] else None
    return python_snippet(spec, SnippetSource(src.name, src.has_env, session.layout, code),
                          session.probe_names())


async def _snippet(h: Handlers, req: Request) -> Response:
    """POST /api/snippet: the edit state in, its Python (text) out."""
    spec = await read_spec(req)
    return Response(python_text(h.session, spec), media_type="text/plain; charset=utf-8")


def make_server(app: ASGIApp) -> Any:
    """The uvicorn server of the viewer: h11 reading request heads of up to
    `MAX_HEAD` bytes (so that a long one is answered, 414, not reset)."""
    import uvicorn

    return uvicorn.Server(uvicorn.Config(app, log_level="warning", access_log=False,
                                         http="h11", h11_max_incomplete_event_size=MAX_HEAD))
