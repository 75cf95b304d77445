"""The lightmap view (``shprobe view --lightmap OUT.glb``): a baked scene drawn with its
normal maps and its ``SHPROBE_lightmap``, shaded per pixel by the library's generated GLSL
(`shprobe.lightmaps.shaders.lightmap_shader`, Habel & Wimmer 2010 eq. 15).

The page reads the .glb itself (geometry, materials, the stored coefficient textures as the
file holds them) and gets from the server what the library adds: the GLSL, the encodings the
stored one implies (`shprobe.lightmaps.derive.implied_encodings`, as RGBA16F textures
packed like the file's) and a default exposure. It shows one encoding, or H&W's Fig. 1
(plain lightmap · H6 without albedo · H6 with albedo) and Fig. 5 (H4 beside H6) as panels of
one camera, with the texel grid as an overlay.

A file with a transfer (``--transfer``) is relit live: the page turns the bake's sky SH
(stored as the transfer's ``"sky"``; for a file without it, the sky that best reproduces the
stored coefficients from the transfer, least squares) and sums Σ_j T_j L_j per texel on the GPU
from the transfer textures it reads out of the .glb. The encodings the stored one implies are
linear in its coefficients, so their transfers are the implied encodings of its transfer's
(sent packed like theirs, within `MAX_IMPLIED_TRANSFER`): they are relit too.
"""

from __future__ import annotations

import logging
import math
import os
from typing import Any

import numpy as np
from starlette.requests import Request
from starlette.responses import Response
from starlette.routing import Route

from ..errors import ShprobeError
from ..lightmaps import format as fmt
from ..lightmaps.derive import implied_encodings
from ..lightmaps.shaders import lightmap_shader
from .wire import pack_binary

__all__ = ["MAX_LIGHTMAP_FILE", "LightmapView", "load_lightmap_view"]

#: largest .glb the page is sent (bytes); the browser holds it and its textures
MAX_LIGHTMAP_FILE = 512 << 20
#: most bytes of implied encodings' transfers (RGBA16F) sent to relight them too; beyond it
#: only the stored encoding is relit
MAX_IMPLIED_TRANSFER = 192 << 20
_log = logging.getLogger("shprobe.viewer")


class LightmapView:
    """What ``shprobe view --lightmap`` serves: the file's bytes, its lightmap and the
    encodings it implies.

    Parameters
    ----------
    raw : bytes
        The .glb file.
    name : str
        Its name, for the page.
    """

    #: where the page is served (``shprobe.viewer.serve`` announces it)
    url_path = "/lightmap"

    def __init__(self, raw: bytes, name: str) -> None:
        doc, binary = fmt.parse_glb(raw, name)
        self.raw, self.name = raw, name
        self.stored = fmt.read_lightmap(doc, binary, name)
        ext = doc["extensions"][fmt.EXTENSION]
        self.layout = [[None if ic is None else [int(ic[0]), int(ic[1])]
                        for ic in t["components"]] for t in ext["textures"]]
        self.encodings = implied_encodings(self.stored.encoding, self.stored.coeffs)
        self.transfer = ext.get("transfer")
        self.sky = self._sky(doc, binary) if self.transfer is not None else None
        self._payload: bytes | None = None

    def _sky(self, doc: dict, binary: bytes) -> tuple[list, str]:
        """The sky SH (9, 3) the transfer relights from, and where it came from."""
        sky = self.transfer.get("sky")
        if sky is not None:
            k = np.asarray(sky, dtype=np.float64)
            if k.shape == (9, 3) and np.isfinite(k).all():
                return k.tolist(), "stored"
        from ..lightmaps.transfer_format import read_transfer

        t = read_transfer(doc, binary, self.name)  # (H, W, n, 9, 3)
        n = t.shape[2]
        t = t.reshape(-1, n, 9, 3)
        step = max(1, len(t) // 65536)  # 9 unknowns per colour: a strided 64k texels suffice
        t = t[::step].astype(np.float64)
        c = self.stored.coeffs.reshape(-1, n, 3)[::step].astype(np.float64)
        fit = [np.linalg.lstsq(t[..., c_].reshape(-1, 9), c[..., c_].ravel(), rcond=None)[0]
               for c_ in range(3)]
        return np.stack(fit, axis=1).tolist(), "fitted"

    def exposure(self) -> float:
        """Default exposure (stops): the 99.5th percentile of the plain irradiance / π over
        the lit texels maps to 0.8 (so a white surface there is nearly white, nothing clips
        much)."""
        e = self.encodings["plain"][..., 0, :].max(axis=-1)
        lit = e[e > 0]
        if lit.size == 0:
            return 0.0
        peak = float(np.percentile(lit, 99.5)) / math.pi
        return float(np.clip(math.log2(0.8 / peak), -30.0, 30.0)) if peak > 0 else 0.0

    def payload(self) -> bytes:
        """The page's data in one `pack_binary` message: the head (encodings, layouts,
        GLSL, size, scale, exposure) and, per implied encoding, its RGBA16F textures
        (``"<encoding>_<t>"``, stored values: × ``scale`` for irradiance)."""
        if self._payload is not None:
            return self._payload
        s = self.stored
        layouts = {e: (self.layout if e == s.encoding else
                       [[None if ic is None else list(ic) for ic in t]
                        for t in fmt.texture_layout(e)]) for e in self.encodings}
        arrays = {}
        for e, c in self.encodings.items():
            if e == s.encoding:
                continue  # the page reads the stored textures from the .glb
            lay = [[None if ic is None else tuple(ic) for ic in t] for t in layouts[e]]
            vals = c / s.scale
            if not np.isfinite(vals).all() or np.abs(vals).max(initial=0) > 65504.0:
                continue  # not representable in half floats: the page offers the others
            for t, tex in enumerate(fmt.pack(e, vals, lay)):
                arrays[f"{e}_{t}"] = tex
        offered = [e for e in self.encodings if e == s.encoding or f"{e}_0" in arrays]
        head = {"name": self.name, "encoding": s.encoding, "encodings": offered,
                "layouts": {e: layouts[e] for e in offered},
                "width": int(s.coeffs.shape[1]), "height": int(s.coeffs.shape[0]),
                "scale": s.scale, "exposure": self.exposure(),
                "glsl": lightmap_shader(offered, "glsl",
                                        {e: [[None if ic is None else tuple(ic) for ic in t]
                                             for t in layouts[e]] for e in offered}),
                "meta": {k: v for k, v in s.extra.items()
                         if isinstance(v, str | int | float | bool)}}
        if self.sky is not None:  # the page reads the stored transfer from the .glb
            implied = self._implied_transfers(offered, layouts, arrays)
            head["transfer"] = {"scale": float(self.transfer["scale"]), "sky": self.sky[0],
                                "sky_source": self.sky[1], "implied": implied}
        self._payload = pack_binary(head, arrays)
        return self._payload

    def _implied_transfers(self, offered: list[str], layouts: dict,
                           arrays: dict) -> dict[str, float]:
        """Add the implied encodings' transfers to ``arrays`` (``"<e>_T<j>_<t>"``, RGBA16F
        packed as ``layouts[e]``, stored value × scale) and return their scales."""
        s = self.stored
        others = [e for e in offered if e != s.encoding]
        h, w = s.coeffs.shape[:2]
        size = 9 * h * w * 8 * sum(len(layouts[e]) for e in others)
        if not others or size > MAX_IMPLIED_TRANSFER:
            return {}
        from ..lightmaps.transfer_format import read_transfer

        doc, binary = fmt.parse_glb(self.raw, self.name)
        t = read_transfer(doc, binary, self.name)  # (H, W, n, 9, 3)
        per = [implied_encodings(s.encoding, t[..., j, :]) for j in range(9)]
        scales = {}
        for e in others:
            lay = [[None if ic is None else tuple(ic) for ic in tx] for tx in layouts[e]]
            te = np.stack([p[e] for p in per])
            scale = fmt.choose_scale(te)
            if not np.isfinite(te).all():
                continue
            for j in range(9):
                for k, tex in enumerate(fmt.pack(e, te[j] / scale, lay)):
                    arrays[f"{e}_T{j}_{k}"] = tex
            scales[e] = scale
        return scales

    # ------------------------------------------------------------------ HTTP
    def routes(self, csp_of: Any, token: str, cookie: str) -> list[Route]:
        """The lightmap page at ``/`` (and ``/lightmap``), its data and the .glb."""
        from .app import static_dir
        from .handlers import page_response

        html = (static_dir() / "lightmap.html").read_text()
        csp = csp_of(html)

        async def page(req: Request) -> Response:
            return page_response(html, csp, cookie, token)

        async def data(req: Request) -> Response:
            from anyio import to_thread

            try:
                body = await to_thread.run_sync(self.payload)
            except Exception as err:  # a library bug: one line in the log, the server stays up
                line = str(err).splitlines()[0] if str(err) else type(err).__name__
                _log.error("GET /api/lightmap: %s: %s", type(err).__name__, line)
                return Response(line, 500)
            return Response(body, media_type="application/octet-stream")

        async def glb(req: Request) -> Response:
            return Response(self.raw, media_type="model/gltf-binary")

        return [Route("/", page), Route("/lightmap", page), Route("/api/lightmap", data),
                Route("/api/lightmap/scene.glb", glb)]


def load_lightmap_view(path: str | os.PathLike[str]) -> LightmapView:
    """Read a lightmap .glb for the page; a bad file is one line naming it.

    Parameters
    ----------
    path : str or PathLike
        A ``shprobe lightmap bake`` output.

    Returns
    -------
    LightmapView
        The view, its implied encodings computed.
    """
    p = os.fspath(path)
    try:
        size = os.path.getsize(p)
    except OSError as e:
        raise ShprobeError(f"cannot read: {e.strerror or e}", p) from None
    if size > MAX_LIGHTMAP_FILE:
        raise ShprobeError(f"{size / 2**20:.0f} MiB is over the viewer's "
                           f"{MAX_LIGHTMAP_FILE >> 20} MiB limit", p)
    with open(p, "rb") as f:
        raw = f.read()
    return LightmapView(raw, os.path.basename(p))
