"""What `shprobe view` says when its server is ready, for both of its pages: the warning of a
non-local address, the URL with its token, the browser opened on it (or, where none opens, a
line saying so)."""

from __future__ import annotations

import threading
import webbrowser

import click

#: addresses only this machine can reach (the server then also checks the Host header)
LOCAL_HOSTS = ("127.0.0.1", "localhost", "::1")


def announce(url: str, host: str, no_browser: bool) -> None:
    """Print the page's ``url`` (after a warning when ``host`` is reachable from elsewhere)
    and, unless ``no_browser``, open it in the browser.

    Parameters
    ----------
    url : str
        The page's URL with its token.
    host : str
        The address the server listens on.
    no_browser : bool
        Only print the URL.
    """
    if host not in LOCAL_HOSTS:
        click.echo(f"warning: --host {host} makes the viewer reachable from other "
                   "machines; anyone with the URL's token can read what it serves", err=True)
    click.echo(f"shprobe view: {url}", nl=True)
    if not no_browser:
        threading.Timer(0.3, _open_browser, args=(url,)).start()


def _open_browser(url: str) -> None:
    """Open ``url`` in the user's browser; say so in one line where none can be opened (a
    machine without a desktop, an ssh session)."""
    try:
        opened = webbrowser.open(url)
    except webbrowser.Error:
        opened = False
    if not opened:
        click.echo("shprobe view: no web browser could be opened here: open the URL above in "
                   "one (on another machine: ssh -L PORT:127.0.0.1:PORT, then the same URL)",
                   err=True)
