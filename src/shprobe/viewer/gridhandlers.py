"""The grid page's HTTP handlers (``shprobe view --grid``), in the designer page's shape
(`shprobe.viewer.handlers`): one method per route, each a thin shell over the page's model
(`GridView`), every body bounded before it is read, every error one
line (`api`)."""

from __future__ import annotations

import time

from anyio import to_thread
from starlette.requests import Request
from starlette.responses import Response
from starlette.routing import Route

from .grid import MAX_SHADE, GridView, parse_placement
from .web import api, csp_of, page_response, read_json, static_dir
from .wire import pack_binary

__all__ = ["GridHandlers"]


class GridHandlers:
    """The routes of the grid page over ``view``.

    Parameters
    ----------
    view : GridView
        The page's model.
    token, cookie : str
        The server's token and the name of its cookie.
    """

    def __init__(self, view: GridView, token: str, cookie: str) -> None:
        self.view, self.token, self.cookie = view, token, cookie
        self.html = (static_dir() / "grid.html").read_text()
        self.csp = csp_of(self.html)

    def routes(self) -> list[Route]:
        """The grid page at ``/`` (and ``/grid``), its data and the shading endpoint.

        Returns
        -------
        list of Route
            The page's routes (the app adds the static files).
        """
        return [Route("/", self.page), Route("/grid", self.page),
                Route("/api/grid", self.data),
                Route("/api/grid/shade", self.shade, methods=["POST"])]

    async def page(self, req: Request) -> Response:
        return page_response(self.html, self.csp, self.cookie, self.token)

    @api
    async def data(self, req: Request) -> Response:
        """GET /api/grid: the page's data (`GridView.payload`)."""
        data = await to_thread.run_sync(self.view.payload)
        return Response(data, media_type="application/octet-stream")

    @api
    async def shade(self, req: Request) -> Response:
        """POST /api/grid/shade: the object's irradiance at a placement, and its mean with the
        other leak-control setting."""
        spec = parse_placement(await read_json(req, MAX_SHADE, "shading request"),
                               self.view.grid)
        t = time.perf_counter()
        e, leak = await to_thread.run_sync(self.view.shade, spec)
        ms = 1e3 * (time.perf_counter() - t)
        other = await to_thread.run_sync(self.view.other_mean, spec)
        head = {"leak_control": leak, "mean": e.mean(axis=0).tolist(), "ms": ms,
                "mean_other": None if other is None else other.tolist()}
        return Response(pack_binary(head, {"irradiance": e}),
                        media_type="application/octet-stream")
