"""What `shprobe view` says when its server is ready, for both of its pages: the warning of a
non-local address, the URL with its token, the browser opened on it."""

from __future__ import annotations

import threading
import webbrowser

import click

#: addresses only this machine can reach (the server then also checks the Host header)
LOCAL_HOSTS = ("127.0.0.1", "localhost", "::1")


def announce(host: str, port: int, token: str, page: str, no_browser: bool) -> str:
    """Print the page's URL (after a warning when ``host`` is reachable from elsewhere) and,
    unless ``no_browser``, open it in the browser; returns the URL."""
    if host not in LOCAL_HOSTS:
        click.echo(f"warning: --host {host} makes the viewer reachable from other "
                   "machines; anyone with the URL's token can read what it serves", err=True)
    shown = "127.0.0.1" if host in ("0.0.0.0", "::") else host
    url = f"http://{shown}:{port}{page}?token={token}"
    click.echo(f"shprobe view: {url}", nl=True)
    if not no_browser:
        threading.Timer(0.3, lambda: webbrowser.open(url)).start()
    return url
