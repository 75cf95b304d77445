"""The viewer's HTTP handlers: one method per route, each a thin shell over the session.

Every body is bounded before it is read: an edit state by `MAX_STATE` and checked once,
at the edge, by the library's schema (`read_state`); an upload by
its declared length and streamed into a file of the session's upload folder, never held whole.
A bad request is one line, ``{"error": ...}``, status 400 (413 over a size limit); nothing a
client sends or breaks off gives a traceback.
"""

from __future__ import annotations

import json
import logging
import re
import threading
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

import numpy as np
from anyio import to_thread
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route

from ..errors import ShprobeError
from ..lighting.edits import EditSpec
from .design import DESIGN_LMAX, read_state
from .session import Session, Task
from .source import MAX_LMAX
from .uploads import MAX_UPLOAD, Uploads
from .views import compare_data
from .web import Refused, api, declared, error_response, one_line, page_response, read_json
from .wire import pack_binary

__all__ = ["MAX_STATE", "Handlers", "Refused", "page_response", "read_json"]

#: largest edit-state body (bytes)
MAX_STATE = 1 << 20
#: upload kinds: what the page may send to /api/upload/{kind}
KINDS = ("probe", "blend", "cube", "mesh", "transfer", "coeffs", "preset", "hbasis")

_log = logging.getLogger("shprobe.viewer")
Handler = Callable[[Request], Awaitable[Response]]


async def read_spec(req: Request) -> EditSpec:
    """The request's edit state: bounded, strict JSON, checked by the schema."""
    return read_state(await read_json(req, MAX_STATE, "edit state"))


async def receive(req: Request, path: Path, name: str) -> None:
    """Stream the request's body into ``path``, refusing it (413) once it passes its declared
    length or the upload limit; the partial file is removed on any failure."""
    length = declared(req, MAX_UPLOAD, name, need=True)
    got = 0
    try:
        with open(path, "wb") as f:
            async for chunk in req.stream():
                got += len(chunk)
                if length is not None and got > length:
                    raise Refused(f"{name}: more bytes than its declared length")
                f.write(chunk)
    except BaseException:
        path.unlink(missing_ok=True)
        raise


class Handlers:
    """The routes of one viewer app over ``session``."""

    def __init__(self, session: Session, index: str, csp: str, token: str,
                 cookie: str) -> None:
        self.session, self.index, self.csp, self.token, self.cookie = (session, index, csp,
                                                                       token, cookie)
        self.shader_text = self._shaders()

    def routes(self) -> list[Route]:
        r = self.ready
        return [
            Route("/", self.page),
            Route("/api/shaders", self.shaders),
            Route("/api/init", r(self.init)),
            Route("/api/mesh", r(self.mesh)),
            Route("/api/background", r(self.background)),
            Route("/api/design", r(self.design), methods=["POST"]),
            Route("/api/export/{fmt}", r(self.export), methods=["POST"]),
            Route("/api/upload/{kind}", r(self.upload), methods=["POST"]),
            Route("/api/compare", r(self.compare)),
            Route("/api/transfer", r(self.transfer)),
            Route("/api/irradiance", r(self.irradiance), methods=["POST"]),
            Route("/api/hbasis", r(self.hbasis), methods=["POST"]),
        ]

    def ready(self, fn: Handler) -> Handler:
        """Wait (off the loop) for the command line's files; their error, if any."""
        async def wrapped(req: Request) -> Response:
            if not self.session.ready.is_set():
                await to_thread.run_sync(self.session.ready.wait)
            if self.session.error is not None:
                return error_response(self.session.error, 500)
            return await fn(req)
        return wrapped

    # -- the page and what it needs first -------------------------------------------------
    async def page(self, req: Request) -> Response:
        return page_response(self.index, self.csp, self.cookie, self.token)

    @staticmethod
    def _shaders() -> bytes:
        """The page's shader functions, made now: the page asks for them first, before the
        files are read (and the modules the first design needs are imported with them)."""
        from ..lighting import design as _design  # noqa: F401
        from ..lighting import windows as _windows  # noqa: F401
        from ..lighting.export import export_coeffs
        from ..lighting.glsl import glsl_irradiance

        return JSONResponse({
            # shprobe's own GLSL export (R&H eq. 11-13), its constants made uniforms
            "glsl": export_coeffs(np.zeros((9, 3)), "glsl", source="viewer"),
            # above l = 2: the library's generated per-pixel function (lighting.glsl), to the
            # compare view's degree and, for designs above it (a PRT transfer's), the highest
            "glsl_sh": glsl_irradiance(MAX_LMAX), "max_lmax": MAX_LMAX,
            "glsl_sh_design": glsl_irradiance(DESIGN_LMAX), "design_lmax": DESIGN_LMAX}).body

    async def shaders(self, req: Request) -> Response:
        return Response(self.shader_text, media_type="application/json")

    def _source_info(self) -> dict[str, Any]:
        s = self.session.source
        return {"name": s.name, "has_env": s.has_env, "layout": s.layout_name}

    def _transfer_info(self) -> dict[str, Any] | None:
        t = self.session.transfer
        return None if t is None else {
            "name": self.session.transfer_name, "lmax": t.lmax, "modes": list(t.modes),
            "max_bounces": t.max_bounces, "mode": t.mode, "n_vertices": t.n_vertices,
            # the design's degree for it (a default bake's lmax 10 is over DESIGN_LMAX)
            "design_lmax": min(t.lmax, DESIGN_LMAX)}

    def _hbasis_info(self) -> dict[str, Any] | None:
        bk = self.session.hbasis_bake
        return None if bk is None else {
            "name": self.session.hbasis_name, "basis": bk.basis, "bands": bk.bands,
            "n_vertices": int(bk.h.shape[0])}

    @api
    async def init(self, req: Request) -> Response:
        from ..lighting.export import FORMATS
        from ..lighting.windows import WINDOWS
        from ..probes.presets import PRESETS

        s = self.session
        return JSONResponse({
            "source": self._source_info(), "formats": list(FORMATS), "windows": list(WINDOWS),
            "presets": list(PRESETS), "mesh": s.mesh_name, "transfer": self._transfer_info(),
            "hbasis": self._hbasis_info(), "timings": s.stamps or {}, "probes": s.probe_list(),
            # the degrees the page offers: a design's (the lmax menu), the compare view's
            "design_lmax": DESIGN_LMAX, "compare_lmax": MAX_LMAX})

    @api
    async def mesh(self, req: Request) -> Response:
        data = await to_thread.run_sync(self.session.mesh_bytes)
        return Response(data, media_type="application/octet-stream")

    @api
    async def background(self, req: Request) -> Response:
        data = await to_thread.run_sync(self.session.background_bytes)
        if data is None:
            raise Refused(f"{self.session.source.name} has no probe image", 404)
        return Response(data, media_type="application/octet-stream")

    # -- designs --------------------------------------------------------------------------
    @api
    async def design(self, req: Request) -> Response:
        from ..lighting.glsl import glsl_uniform_values

        spec = await read_spec(req)
        d = await to_thread.run_sync(self.session.design, spec)
        return JSONResponse({
            "coeffs": d.coeffs.tolist(), "lmax": spec.lmax, "window": d.window,
            # E_lm = Â_l L_lm for the generated per-pixel GLSL (lmax > 2)
            "irradiance": glsl_uniform_values(d.coeffs, max(MAX_LMAX, spec.lmax)).tolist(),
            # the edits before the rotation and the window's band factors: the page turns
            # these itself while dragging (lmax <= 2)
            "unrotated": d.unrotated.tolist(),
            "factors": None if d.factors is None else list(map(float, d.factors)),
            "min_e": d.minimum.minimum.tolist(), "min_exact": bool(d.minimum.exact),
            "min_method": d.minimum.method,
            "cli": spec.to_text(self.session.probe_names()),
            "source": self.session.source.name})

    @api
    async def export(self, req: Request) -> Response:
        from ..lighting.export import FORMATS, export_coeffs
        from ..lighting.filenames import export_name

        fmt = req.path_params["fmt"]
        if fmt not in FORMATS:
            raise Refused(f"unknown export format {fmt[:40]!r}", 404)
        spec = await read_spec(req)
        s = self.session
        text = await to_thread.run_sync(lambda: export_coeffs(
            s.design_exact(spec)[0], fmt, source=s.source.name))
        name = export_name(s.source.name, spec, fmt, s.probe_names())  # the CLI's name
        return Response(text, media_type="text/plain; charset=utf-8", headers={
            "Content-Disposition": f'attachment; filename="{name}"'})

    @api
    async def irradiance(self, req: Request) -> Response:
        """The library's irradiance at given normals, for the page's LightProbe check."""
        from ..lighting.irradiance import irradiance

        spec = await read_spec(req)
        L, _ = await to_thread.run_sync(self.session.design_exact, spec)
        nrm = np.array([[0, 1, 0], [1, 0, 0], [0, 0, 1], [0.6, -0.8, 0], [0, 0, -1.0]])
        return JSONResponse({"normals": nrm.tolist(), "irradiance": irradiance(L[:9],
                                                                               nrm).tolist()})

    @api
    async def hbasis(self, req: Request) -> Response:
        spec = await read_spec(req)
        data, rms = await to_thread.run_sync(self.session.hbasis, spec)
        return Response(data, media_type="application/octet-stream",
                        headers={"X-Shprobe-Rel-Rms": json.dumps(rms)})

    # -- uploads --------------------------------------------------------------------------
    @api
    async def upload(self, req: Request) -> Response:
        kind = req.path_params["kind"]
        if kind not in KINDS:
            raise Refused(f"unknown upload kind {kind[:40]!r}", 404)
        s = self.session
        if kind == "preset":
            from ..probes.presets import PRESETS
            from .source import preset_source

            name = req.query_params.get("name", "")
            if name not in PRESETS:
                raise Refused(f"unknown preset {name[:40]!r}")
            s.source = preset_source(name)
            s.tasks.pop("compare", None)
            return JSONResponse({"source": self._source_info()})
        if kind == "cube":  # six faces +X −X +Y −Y +Z −Z in one body
            body, _ = s.uploads.reserve("faces.hdr", ("probe",))
            await receive(req, body, "cube faces")
            paths, names = await to_thread.run_sync(s.uploads.split, body)
            path: Any = paths
            shown = f"cube faces {names[0]} … {names[-1]}" if len(names) > 1 else names[0]
        else:
            p, shown = s.uploads.reserve(req.headers.get("x-filename", ""),
                                         {"blend": ("probe",), "hbasis": ("transfer",)}
                                         .get(kind, (kind,)))
            await receive(req, p, shown)
            path, paths, names = str(p), [str(p)], [shown]
        try:
            new = await to_thread.run_sync(self._load, kind, path, shown)
        except ShprobeError as e:
            raise ShprobeError(_shown(str(e), paths, names)) from None
        except Exception as e:  # a library bug must not take the server down
            raise ShprobeError(_shown(f"{shown}: could not load: {one_line(e)}", paths,
                                      names)) from None
        pid = None
        if isinstance(new, tuple):
            new, pid = new
        if new is not None and kind != "blend":
            s.source = new
            s.tasks.pop("compare", None)
        return JSONResponse({"source": self._source_info(), "mesh": s.mesh_name,
                             "transfer": self._transfer_info(), "probe_id": pid,
                             "hbasis": self._hbasis_info(),
                             "probes": s.probe_list()})

    def _load(self, kind: str, path: Any, shown: str) -> Any:
        """Read an upload (in a worker thread): the new source, (source, probe id) for a
        probe kept for blending, or None."""
        s = self.session
        if kind == "cube":  # a source (blends name single files, as the CLI does)
            return s.probe_source(path, shown)
        if kind in ("probe", "blend"):  # kept for blending either way
            src = s.probe_source(path, shown)
            return src, s.register_probe(src, shown)
        if kind == "coeffs":
            from .source import coeffs_source

            return coeffs_source(path, shown)
        if kind == "mesh":
            s.load_mesh(path, shown)
        elif kind == "hbasis":
            Uploads.check_npz(Path(path), shown)
            s.load_hbasis(path, shown)
        else:
            Uploads.check_npz(Path(path), shown)
            s.load_transfer(path, shown)
        return None

    # -- long views -----------------------------------------------------------------------
    @api
    async def compare(self, req: Request) -> Response:
        s = self.session
        task = s.tasks.get("compare")
        if task is None:
            task = s.tasks["compare"] = Task(status="running")
            threading.Thread(target=_run_compare, args=(task, s.source), daemon=True).start()
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

    @api
    async def transfer(self, req: Request) -> Response:
        mode = req.query_params.get("mode") or None
        if mode is not None and not re.fullmatch(r"[a-z]{1,20}", mode):
            raise Refused(f"mode must be a PRT mode name, got {mode[:20]!r}")
        b = req.query_params.get("bounces")
        if b not in (None, "") and not re.fullmatch(r"[0-9]{1,4}", b):  # ASCII: not "①"
            raise Refused(f"bounces must be a small integer, got {b[:20]!r}")
        bounces = None if b in (None, "") else int(b)
        data = await to_thread.run_sync(self.session.transfer_bytes, mode, bounces)
        return Response(data, media_type="application/octet-stream")


def _run_compare(task: Task, src: Any) -> None:
    """The compare view's numbers in a thread, its progress and outcome on ``task``."""
    try:
        task.result = compare_data(src, task.progress)
        task.status, task.done = "done", 1.0
    except Exception as e:  # reported to the page, one line
        task.status, task.message = "error", one_line(e)


def _shown(msg: str, paths: list[str], names: list[str]) -> str:
    """A message with the user's file names, not the private copies'."""
    for p, s in zip(paths, names, strict=True):
        msg = msg.replace(p, s)
    return msg
