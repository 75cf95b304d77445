"""The viewer's HTTP pieces every page uses (below `shprobe.viewer.app`, `shprobe.viewer.handlers`
and `shprobe.viewer.grid`, which import them): the page files (`static_dir`), a page's answer with
its Content-Security-Policy and token cookie (`page_response`, `csp_of`), a bounded
strict-JSON body (`read_json`) and the one-line refusals (`Refused`)."""

from __future__ import annotations

import base64
import hashlib
import logging
import re
from collections.abc import Awaitable, Callable
from importlib import resources
from pathlib import Path
from typing import Any

from starlette.requests import ClientDisconnect, Request
from starlette.responses import JSONResponse, Response

from ..errors import ShprobeError

__all__ = ["CSP", "Refused", "api", "csp_of", "declared", "error_response", "one_line",
           "page_response", "read_json", "size_text", "static_dir"]

_log = logging.getLogger("shprobe.viewer")

CSP = ("default-src 'self'; script-src 'self' {importmap}; style-src 'self'; "
       "img-src 'self' blob: data:; connect-src 'self'; object-src 'none'; base-uri 'none'; "
       "frame-ancestors 'none'")


class Refused(ShprobeError):
    """A request refused with an HTTP ``status`` (400 unless said)."""

    def __init__(self, message: str, status: int = 400) -> None:
        super().__init__(message)
        self.status = status


def one_line(e: BaseException) -> str:
    """The first line of an error's message (its type's name when it has none)."""
    return str(e).splitlines()[0] if str(e) else type(e).__name__


def error_response(e: BaseException, status: int = 400) -> JSONResponse:
    """``{"error": <one line>}`` with ``status``."""
    return JSONResponse({"error": one_line(e)}, status)


def static_dir() -> Path:
    """The pages and their vendored libraries (package data).

    Returns
    -------
    Path
        The ``static`` folder.

    Raises
    ------
    ShprobeError
        In a checkout where ``tools/vendor_js.sh`` has not been run.
    """
    d = Path(str(resources.files("shprobe.viewer") / "static"))
    if not (d / "vendor" / "three" / "three.min.js").is_file():
        raise ShprobeError("the viewer's JavaScript libraries are not installed: run "
                           "tools/vendor_js.sh (it installs three.js from npm)", d / "vendor")
    return d


def csp_of(html: str) -> str:
    """A page's Content-Security-Policy: only this origin, plus the hash of the page's inline
    import map (which points ``three`` at the vendored copy).

    Parameters
    ----------
    html : str
        The page.

    Returns
    -------
    str
        The header's value.
    """
    m = re.search(r'<script type="importmap">(.*?)</script>', html, re.S)
    h = ""
    if m is not None:
        digest = hashlib.sha256(m.group(1).encode()).digest()
        h = f"'sha256-{base64.b64encode(digest).decode()}'"
    return CSP.format(importmap=h)


def page_response(html: str, csp: str, cookie: str, token: str) -> Response:
    """A page of the viewer: its CSP, never cached, no referrer, and the token's cookie (the
    page's API calls carry it).

    Parameters
    ----------
    html, csp : str
        The page and its policy (`csp_of`).
    cookie, token : str
        The token cookie's name and value.

    Returns
    -------
    Response
        The HTML answer.
    """
    r = Response(html, media_type="text/html",
                 headers={"Content-Security-Policy": csp, "Cache-Control": "no-store",
                          "Referrer-Policy": "no-referrer"})
    r.set_cookie(cookie, token, httponly=True, samesite="strict")
    return r


def size_text(n: int) -> str:
    """A byte count as MiB or KiB."""
    return f"{n >> 20} MiB" if n >= 1 << 20 else f"{n >> 10} KiB"


def declared(req: Request, limit: int, what: str, need: bool = False) -> int | None:
    """The body's declared length (None: not declared; refused, 411, where ``need``),
    refused (413) over ``limit`` before anything is read."""
    text = req.headers.get("content-length")
    if text is None:
        if need:
            raise Refused(f"{what}: send the length of the body (Content-Length)", 411)
        return None
    if not text.isdigit() or len(text) > 18:
        raise Refused(f"{what}: bad Content-Length")
    n = int(text)
    if n > limit:
        raise Refused(f"{what}: {size_text(n)} is over the {size_text(limit)} limit", 413)
    return n


async def read_json(req: Request, limit: int, what: str) -> Any:
    """The request's body as strict JSON, refused (413) past ``limit`` bytes — declared or
    read — before it is parsed.

    Parameters
    ----------
    req : Request
        The request.
    limit : int
        Most bytes read.
    what : str
        What the body is, for the messages.

    Returns
    -------
    Any
        The parsed document.
    """
    from ..lighting.document import parse_json

    declared(req, limit, what)
    body = bytearray()
    async for chunk in req.stream():
        body += chunk
        if len(body) > limit:
            raise Refused(f"{what}: over the {size_text(limit)} limit", 413)
    return parse_json(body.decode("utf-8", "replace") or "{}", what)


def api(fn: Callable[[Any, Request], Awaitable[Response]]) -> Callable[..., Any]:
    """A handler method's errors as one-line answers: [`ShprobeError`][shprobe.errors.ShprobeError]
    400 (or its status), a client gone silence, anything else 500 (logged in one line: a library bug
    must not take the server down).

    Parameters
    ----------
    fn : async method (self, request) -> Response
        The handler.

    Returns
    -------
    callable
        The wrapped handler.
    """
    async def wrapped(self: Any, req: Request) -> Response:
        try:
            return await fn(self, req)
        except ClientDisconnect:
            return Response(status_code=400)  # nobody reads it
        except ShprobeError as e:
            return error_response(e, getattr(e, "status", 400))
        except Exception as e:
            _log.error("%s %s: %s: %s", req.method, req.url.path, type(e).__name__, one_line(e))
            return error_response(e, 500)
    wrapped.__name__, wrapped.__doc__ = fn.__name__, fn.__doc__
    return wrapped
