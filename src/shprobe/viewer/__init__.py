"""Layer: the viewer (``shprobe view``), a local web application over the library: a Starlette
app (:mod:`.app`, its routes :mod:`.handlers`) serving a page that draws with three.js
(installed from npm by ``tools/vendor_js.sh``, shipped as package data) and a model whose
numbers all come from the library: the session (:mod:`.session`) with its sources
(:mod:`.source`), uploads (:mod:`.uploads`), file loader (:mod:`.loader`), designs
(:mod:`.design`, the library's edit language), views (:mod:`.views`), and what goes over the
wire (:mod:`.wire`, :mod:`.payloads`). Every page starts through :func:`serve`
(:mod:`.start`). See docs/viewer.md.
"""

import secrets

from .start import serve

__all__ = ["new_token", "serve"]


def new_token() -> str:
    """A random URL-safe token (192 bits): every request to the viewer must carry it."""
    return secrets.token_urlsafe(24)
