"""One start-up for every page (``shprobe.viewer.serve``): the designer page (a Session)
and the grid page (a GridView) start through the same call, a port in use is one line and no
URL, and where no browser can be opened `shprobe view` says so in one line."""

from __future__ import annotations

import threading
import time
import webbrowser

import httpx
import pytest

from shprobe.errors import ShprobeError
from shprobe.viewer import serve
from shprobe.viewer.grid import GridView
from shprobe.viewer.session import Session
from shprobe.viewer.start import listen, page_path
from tests.viewer.test_viewer_grid import make_grid


def _serve_in_thread(page):
    urls = []
    th = threading.Thread(target=serve, args=(page,), kwargs={"on_ready": urls.append},
                          daemon=True)
    th.start()
    t0 = time.time()
    while not urls and time.time() - t0 < 60:
        time.sleep(0.05)
    assert urls, "no URL"
    return urls[0]


@pytest.mark.parametrize("kind", ["designer", "grid"])
def test_every_page_starts_through_serve(kind):
    page = (Session(preset="grace", mesh=None, transfer=None, load=False) if kind == "designer"
            else GridView(make_grid(), "g.npz"))
    url = _serve_in_thread(page)
    assert url.split("?")[0].endswith(page_path(page))
    with httpx.Client(timeout=30) as c:
        r = c.get(url)
        assert r.status_code == 200 and "<html" in r.text
        api = "/api/init" if kind == "designer" else "/api/grid"
        r = c.get(url.split("?")[0].rsplit("/", 1)[0] + api, params={"token":
                                                                   url.split("token=")[1]})
        assert r.status_code == 200


def test_port_in_use_is_one_line_and_no_url():
    sock = listen("127.0.0.1", 0)
    try:
        urls = []
        with pytest.raises(ShprobeError) as e:
            serve(GridView(make_grid(), "g.npz"), port=sock.getsockname()[1],
                  on_ready=urls.append)
        assert "cannot listen" in str(e.value) and "\n" not in str(e.value) and not urls
    finally:
        sock.close()


@pytest.mark.parametrize("how", ["false", "raises"])
def test_no_browser_is_said_in_one_line(monkeypatch, capsys, how):
    from shprobe.cli import serve as cli_serve

    def fake_open(url):
        if how == "raises":
            raise webbrowser.Error("could not locate runnable browser")
        return False

    monkeypatch.setattr(webbrowser, "open", fake_open)
    cli_serve._open_browser("http://127.0.0.1:1/?token=x")
    err = capsys.readouterr().err.strip()
    print(err)
    assert len(err.splitlines()) == 1 and "no web browser" in err and "URL" in err
