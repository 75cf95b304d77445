"""Layer: the viewer (``shprobe view``), a local web application over the library: a Starlette
app (:mod:`.app`) serving a page that draws with three.js (installed from npm by
``tools/vendor_js.sh``, shipped as package data) and a model (:mod:`.session`) whose numbers all
come from the library. See docs/viewer.md.
"""

__all__: list[str] = []
