"""The viewer's ASGI application (Starlette): a thin HTTP shell over :mod:`.session`.

Security: every request must carry the session token (``?token=`` once — the page then holds it
in a same-site cookie — or the ``X-Shprobe-Token`` header), as Jupyter does; the Host header must
name the address the server was started on and an Origin, when sent, must be that same origin
(no DNS rebinding, no cross-site requests). The server opens only the files named on the
command line and the uploads it stored itself; no path from the page is ever opened.

Heavy work (decoding, projection, the brute-force reference) runs in worker threads off the event
loop; long tasks report progress at ``/api/task/{name}``.
"""

from __future__ import annotations

import json
import secrets
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from anyio import to_thread
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import JSONResponse, PlainTextResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles
from starlette.types import ASGIApp, Receive, Scope, Send

from ..errors import ShprobeError
from ..progress import Fraction
from .session import (
    DESIGN_LMAX,
    MAX_LMAX,
    Session,
    Task,
    check_state,
    cli_args,
    compare_data,
    design_coeffs,
    pack_binary,
)

__all__ = ["create_app", "static_dir"]

COOKIE = "shprobe_token_{port}"  # cookies ignore ports: one name per server
CSP = ("default-src 'self'; script-src 'self' {importmap}; style-src 'self'; "
       "img-src 'self' blob: data:; connect-src 'self'; object-src 'none'; base-uri 'none'; "
       "frame-ancestors 'none'")


def _csp(index: str) -> str:
    """The page's Content-Security-Policy: only this origin, plus the hash of the inline
    import map (which points ``three`` at the vendored copy)."""
    import base64
    import hashlib
    import re

    m = re.search(r'<script type="importmap">(.*?)</script>', index, re.S)
    h = ""
    if m is not None:
        digest = hashlib.sha256(m.group(1).encode()).digest()
        h = f"'sha256-{base64.b64encode(digest).decode()}'"
    return CSP.format(importmap=h)


def static_dir() -> Path:
    """The page and its vendored libraries (package data); refuses a checkout where
    ``tools/vendor_js.sh`` has not been run."""
    d = Path(str(resources.files("shprobe.viewer") / "static"))
    if not (d / "vendor" / "three" / "three.min.js").is_file():
        raise ShprobeError("the viewer's JavaScript libraries are not installed: run "
                           "tools/vendor_js.sh (it installs three.js from npm)", d / "vendor")
    return d


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


def _error(e: Exception, status: int = 400) -> JSONResponse:
    msg = str(e).splitlines()[0] if str(e) else type(e).__name__
    return JSONResponse({"error": msg}, status)


async def _state(req: Request) -> dict[str, Any]:
    from ..lighting.document import parse_json

    body = (await req.body()).decode("utf-8", "replace")
    return check_state(parse_json(body or "{}", "edit state"))


def create_app(session: Session, token: str, host: str = "127.0.0.1", port: int = 0,
               check_host: bool = True) -> Starlette:
    """The viewer app for ``session``. ``port`` is the port it will listen on (for the Host
    check; ``check_host=False`` accepts any Host, e.g. ``--host 0.0.0.0``)."""
    static = static_dir()
    index = (static / "index.html").read_text()
    csp = _csp(index)

    async def page(req: Request) -> Response:
        r = Response(index, media_type="text/html",
                     headers={"Content-Security-Policy": csp, "Cache-Control": "no-store",
                              "Referrer-Policy": "no-referrer"})
        r.set_cookie(COOKIE.format(port=port), token, httponly=True, samesite="strict")
        return r

    def src_info() -> dict[str, Any]:
        s = session.source
        return {"name": s.name, "has_env": s.has_env, "layout": s.layout_name}

    def transfer_info() -> dict[str, Any] | None:
        t = session.transfer
        return None if t is None else {
            "name": session.transfer_name, "lmax": t.lmax, "modes": list(t.modes),
            "max_bounces": t.max_bounces, "mode": t.mode, "n_vertices": t.n_vertices,
            # the design's degree for it (a default bake's lmax 10 is over check_state's 8)
            "design_lmax": min(t.lmax, DESIGN_LMAX)}

    # the page's shader functions, made now: the page asks for them first, before the files
    # are read, and the modules the first design needs are imported with them
    from ..lighting import design as _design  # noqa: F401
    from ..lighting import windows as _windows  # noqa: F401
    from ..lighting.export import export_coeffs
    from ..lighting.glsl import glsl_irradiance

    shader_text = JSONResponse({
        # shprobe's own GLSL export (R&H eq. 11-13), its constants made uniforms
        "glsl": export_coeffs(np.zeros((9, 3)), "glsl", source="viewer"),
        # above l = 2: the library's generated per-pixel function (lighting.glsl), to the
        # compare view's degree and, for designs above it (a PRT transfer's), to the highest
        "glsl_sh": glsl_irradiance(MAX_LMAX), "max_lmax": MAX_LMAX,
        "glsl_sh_design": glsl_irradiance(DESIGN_LMAX), "design_lmax": DESIGN_LMAX}).body

    async def shaders(req: Request) -> Response:
        """The page's shader functions (no file needed: served before the files are read)."""
        return Response(shader_text, media_type="application/json")

    async def init(req: Request) -> Response:
        from ..lighting.export import FORMATS
        from ..lighting.windows import WINDOWS
        from ..probes.presets import PRESETS

        return JSONResponse({
            "source": src_info(), "formats": list(FORMATS), "windows": list(WINDOWS),
            "presets": list(PRESETS), "mesh": session.mesh_name,
            "transfer": transfer_info(), "timings": session.timings,
            "probes": session.probe_list()})

    async def mesh(req: Request) -> Response:
        data = await to_thread.run_sync(session.mesh_bytes)
        return Response(data, media_type="application/octet-stream")

    async def background(req: Request) -> Response:
        data = await to_thread.run_sync(session.background_bytes)
        if data is None:
            return JSONResponse({"error": f"{session.source.name} has no probe image"}, 404)
        return Response(data, media_type="application/octet-stream")

    async def design(req: Request) -> Response:
        try:
            st = await _state(req)

            def run():
                L, wdesc, m = session.design(st)
                return L, wdesc, m, session.last_base
            L, wdesc, m, (L0, f) = await to_thread.run_sync(run)
        except ShprobeError as e:
            return _error(e)
        from ..lighting.glsl import glsl_uniform_values

        return JSONResponse({"coeffs": L.tolist(), "lmax": st["lmax"], "window": wdesc,
                             # E_lm = Â_l L_lm for the generated per-pixel GLSL (lmax > 2)
                             "irradiance": glsl_uniform_values(
                                 L, max(MAX_LMAX, st["lmax"])).tolist(),
                             # the edits before the rotation and the window's band factors:
                             # the page turns these itself while dragging (lmax <= 2)
                             "unrotated": L0.tolist(),
                             "factors": None if f is None else list(map(float, f)),
                             "min_e": m.minimum.tolist(), "min_exact": bool(m.exact),
                             "min_method": m.method,
                             "cli": cli_args(st, session.probe_names()),
                             "source": session.source.name})

    async def export(req: Request) -> Response:
        from ..lighting.export import FORMATS, SUFFIX, export_coeffs

        fmt = req.path_params["fmt"]
        if fmt not in FORMATS:
            return _error(ShprobeError(f"unknown export format {fmt!r}"), 404)
        try:
            st = await _state(req)
            text = await to_thread.run_sync(lambda: export_coeffs(
                design_coeffs(session.base(st["lmax"]), st, session.probe_coeffs)[0], fmt,
                source=session.source.name))
        except ShprobeError as e:
            return _error(e)
        return Response(text, media_type="text/plain; charset=utf-8", headers={
            "Content-Disposition": f'attachment; filename="shprobe{SUFFIX[fmt]}"'})

    async def upload(req: Request) -> Response:
        kind = req.path_params["kind"]
        if kind not in ("probe", "blend", "cube", "mesh", "transfer", "coeffs", "preset"):
            return _error(ShprobeError(f"unknown upload kind {kind!r}"), 404)
        try:
            if kind == "preset":
                name = req.query_params.get("name", "")
                from ..probes.presets import PRESETS

                if name not in PRESETS:
                    raise ShprobeError(f"unknown preset {name!r}")
                session.source = session.preset_source(name)
                session.tasks.pop("compare", None)
                return JSONResponse({"source": src_info()})
            data = await req.body()
            if kind == "cube":  # six faces +X −X +Y −Y +Z −Z in one body
                paths, names = session.save_cube_upload(data)
                path: Any = paths
                shown = (f"cube faces {names[0]} … {names[-1]}" if len(names) > 1
                         else names[0])
            else:
                path, shown = session.save_upload(req.headers.get("x-filename", ""), data,
                                                  ("probe",) if kind == "blend" else (kind,))
                paths, names = [path], [shown]

            def load():
                if kind == "cube":  # a source (blends name single files, as the CLI does)
                    return session.probe_source(path, shown)
                if kind in ("probe", "blend"):  # kept for blending either way
                    src = session.probe_source(path, shown)
                    return src, session.register_probe(src, shown)
                if kind == "coeffs":
                    return session.coeffs_source(path, shown)
                if kind == "mesh":
                    session.load_mesh(path, shown)
                else:
                    session.load_transfer(path, shown)
                return None
            def shown_names(msg: str) -> str:  # the user's file names, not the private copies
                for p, s in zip(paths, names, strict=True):
                    msg = msg.replace(p, s)
                return msg

            try:
                new = await to_thread.run_sync(load)
            except ShprobeError as e:
                raise ShprobeError(shown_names(str(e))) from None
            except Exception as e:  # a library bug must not take the server down
                line = f"{e}".splitlines()[0] if str(e) else type(e).__name__
                raise ShprobeError(shown_names(f"{shown}: could not load: {line}")) from None
        except ShprobeError as e:
            return _error(e)
        pid = None
        if isinstance(new, tuple):
            new, pid = new
        if new is not None and kind != "blend":
            session.source = new
            session.tasks.pop("compare", None)
        return JSONResponse({"source": src_info(), "mesh": session.mesh_name,
                             "transfer": transfer_info(), "probe_id": pid,
                             "probes": session.probe_list()})

    async def compare(req: Request) -> Response:
        task = session.tasks.get("compare")
        if task is None:
            task = session.tasks["compare"] = Task(status="running")
            src = session.source

            progress = Fraction(lambda f: setattr(task, "done", f))

            def run() -> None:
                try:
                    task.result = compare_data(src, progress)
                    task.status, task.done = "done", 1.0
                except Exception as e:  # reported to the page, one line
                    task.status, task.message = "error", str(e).splitlines()[0] if str(e) \
                        else type(e).__name__

            import threading

            threading.Thread(target=run, daemon=True).start()
        if task.status != "done":
            return JSONResponse({"status": task.status, "done": task.done,
                                 "error": task.message or None})
        r = task.result
        arrays = {"reference": r["reference"]}
        arrays.update({f"sh{lm}": m for lm, m in r["maps"].items()})
        return Response(pack_binary({"status": "done", "grid": r["grid"], "rows": r["rows"],
                                     "irradiance": r["irradiance"],
                                     "total_intensity": r["total_intensity"]}, arrays),
                        media_type="application/octet-stream")

    async def transfer(req: Request) -> Response:
        mode = req.query_params.get("mode") or None
        b = req.query_params.get("bounces")
        try:
            bounces = None if b in (None, "") else int(b)
            data = await to_thread.run_sync(lambda: session.transfer_bytes(mode, bounces))
        except (ShprobeError, ValueError) as e:
            return _error(e)
        return Response(data, media_type="application/octet-stream")

    async def hbasis(req: Request) -> Response:
        from .session import hbasis_panel

        try:
            st = await _state(req)
            png, rms = await to_thread.run_sync(lambda: hbasis_panel(session, st))
        except ShprobeError as e:
            return _error(e)
        return Response(png, media_type="image/png",
                        headers={"X-Shprobe-Rel-Rms": json.dumps(rms)})

    async def three_check(req: Request) -> Response:
        """The library's irradiance at given normals, for the page's LightProbe check."""
        from ..lighting.irradiance import irradiance

        try:
            st = await _state(req)
            L, _ = design_coeffs(session.base(st["lmax"]), st, session.probe_coeffs)
            nrm = np.array([[0, 1, 0], [1, 0, 0], [0, 0, 1], [0.6, -0.8, 0], [0, 0, -1.0]])
            E = irradiance(L[:9], nrm)
        except ShprobeError as e:
            return _error(e)
        return JSONResponse({"normals": nrm.tolist(), "irradiance": E.tolist()})

    def ready(fn):
        """Wait (off the loop) for the command line's files; their error, if any."""
        async def wrapped(req: Request) -> Response:
            if not session.ready.is_set():
                await to_thread.run_sync(session.ready.wait)
            if session.error is not None:
                return _error(session.error, 500)
            return await fn(req)
        return wrapped

    routes = [
        Route("/", page),
        Route("/api/shaders", shaders),
        Route("/api/init", ready(init)),
        Route("/api/mesh", ready(mesh)),
        Route("/api/background", ready(background)),
        Route("/api/design", ready(design), methods=["POST"]),
        Route("/api/export/{fmt}", ready(export), methods=["POST"]),
        Route("/api/upload/{kind}", ready(upload), methods=["POST"]),
        Route("/api/compare", ready(compare)),
        Route("/api/transfer", ready(transfer)),
        Route("/api/irradiance", ready(three_check), methods=["POST"]),
        Route("/api/hbasis", ready(hbasis), methods=["POST"]),
        Mount("/static", StaticFiles(directory=str(static)), name="static"),
    ]
    app = Starlette(routes=routes)
    hosts = None
    if check_host:
        hosts = {f"{h}:{port}" for h in ("127.0.0.1", "localhost", "[::1]")}
        if host not in ("127.0.0.1", "localhost", "0.0.0.0", "::"):
            hosts.add(f"{host}:{port}".lower())
    app.add_middleware(Guard, token=token, hosts=hosts, cookie=COOKIE.format(port=port))
    app.state.session = session
    return app

