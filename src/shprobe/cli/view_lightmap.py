"""CLI: ``shprobe view --lightmap OUT.glb``, the lightmap page of the viewer
(`shprobe.viewer.lightmap`): the file is read before the URL is printed, so a bad one is
one line and a non-zero exit, with no server started."""

from __future__ import annotations

from ..errors import ShprobeError


def view_lightmap(path: str, others: tuple[str | None, ...], host: str, port: int,
                  no_browser: bool) -> None:
    """Serve the lightmap page for ``path`` until Ctrl-C.

    Parameters
    ----------
    path : str
        The lightmap .glb.
    others : tuple
        PROBE, --preset, --mesh, --transfer, --grid, --scene and --hbasis: a lightmap
        carries its own scene and lighting, so none may be given.
    host, port : str, int
        Where to listen.
    no_browser : bool
        Print the URL only.
    """
    if any(others):
        raise ShprobeError("--lightmap shows the file's own scene and lighting: give no PROBE, "
                           "--preset, --mesh, --transfer, --grid, --scene or --hbasis with it")
    from ..viewer import serve
    from ..viewer.lightmap import load_lightmap_view
    from .serve import LOCAL_HOSTS, announce

    view = load_lightmap_view(path)  # a bad file is one line, before any URL
    serve(view, host, port, lambda url: announce(url, host, no_browser),
          check_host=host in LOCAL_HOSTS)
