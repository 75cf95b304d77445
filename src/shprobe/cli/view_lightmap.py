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
    from ..viewer import new_token
    from ..viewer.lightmap import load_lightmap_view

    view = load_lightmap_view(path)
    from ..viewer.app import create_app, listen, make_server
    from .serve import LOCAL_HOSTS, announce

    sock = listen(host, port)
    port = sock.getsockname()[1]
    token = new_token()
    # create_app serves any page object with routes() in place of the designer's: its
    # ``grid`` argument
    server = make_server(create_app(None, token, host, port, check_host=host in LOCAL_HOSTS,
                                    grid=view))
    announce(host, port, token, "/lightmap", no_browser)
    server.run(sockets=[sock])
