"""Layer: the viewer (``shprobe view``), a local web application over the library: a Starlette
app (`shprobe.viewer.app`, its routes `shprobe.viewer.handlers`) serving a page that draws with
three.js (installed from npm by ``tools/vendor_js.sh``, shipped as package data) and a model whose
numbers all come from the library: the session (`shprobe.viewer.session`) with its sources
(`shprobe.viewer.source`), uploads (`shprobe.viewer.uploads`), file loader
(`shprobe.viewer.loader`), designs (`shprobe.viewer.design`, the library's edit language), views
(`shprobe.viewer.views`), and what goes over the wire (`shprobe.viewer.wire`,
`shprobe.viewer.payloads`). Every page starts through [`serve`][shprobe.viewer.serve]
(`shprobe.viewer.start`). See docs/viewer.md.
"""

import secrets

from .start import serve

__all__ = ["new_token", "serve"]


def new_token() -> str:
    """A random URL-safe token (192 bits): every request to the viewer must carry it."""
    return secrets.token_urlsafe(24)
