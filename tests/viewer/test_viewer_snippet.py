""""Copy as Python": the page's button beside the equivalent command gives library code
(:func:`shprobe.lighting.snippet.python_snippet`) that runs — executed here, in a fresh
namespace — and yields the page's coefficients for the edit shown, whatever the source (the
command-line probe, a preset, uploaded coefficients, a blended upload, darkness)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.lighting.edits import EditSpec
from shprobe.lighting.snippet import SnippetSource, python_snippet
from tests.conftest import data_file
from tests.viewer import test_viewer as tv

# the browser, the served session (the grace probe, the packaged bunny) and its page
browser, served, page, probe_path = tv.browser, tv.served, tv.page, tv.probe_path
set_state = tv._state


def run_snippet(code: str, cwd: Path) -> np.ndarray:
    """Execute ``code`` in a fresh namespace with ``cwd`` as the working folder; its ``L``."""
    old = os.getcwd()
    os.chdir(cwd)
    try:
        ns: dict = {"__name__": "__snippet__"}
        exec(compile(code, "<snippet>", "exec"), ns)
    finally:
        os.chdir(old)
    return np.asarray(ns["L"])


STATES = [
    {},
    {"lmax": 4, "rotation": {"axis": [0.2, 1.0, 0.1], "degrees": 37.5}, "window": "auto"},
    tv.EDITS,
    {"lmax": 3, "weight": 0.7, "sky": {"sky": [1, 1.2, 1.5], "ground": [0.2, 0.1, 0.05],
                                      "up": [0, 1, 0]},
     "set": {"1,0": [0.1, 0.2, 0.3]}, "negate": ["2,1"], "negate_band": [3],
     "rotation": [{"euler": [10, 20, 30]}, {"quat": [0.9, 0.1, 0.3, 0.2]}],
     "window": "lanczos:0.4"},
]


@pytest.mark.parametrize("state", range(len(STATES)))
@pytest.mark.browser
def test_copy_as_python_runs_and_gives_the_pages_coefficients(page, tmp_path, state):
    set_state(page, STATES[state])
    page.evaluate("() => { window.__shprobe.lastSnippet = null; }")
    page.click("#copy-python")
    page.wait_for_function("() => window.__shprobe.lastSnippet")
    code = page.evaluate("() => window.__shprobe.lastSnippet")
    shown = np.array(page.evaluate("() => window.__shprobe.coeffs"))
    L = run_snippet(code, tmp_path)
    assert L.shape == shown.shape
    np.testing.assert_allclose(L, shown, rtol=1e-12, atol=1e-12 * np.abs(shown).max())
    assert page.locator("#python").inner_text().strip() == code.strip()
    assert page.locator("#python-note").inner_text() in ("copied",
                                                         "select the code below and copy it")
    if state == 2:
        shots = Path(os.environ.get("SHPROBE_VIEWER_SHOTS", "/tmp"))
        page.locator("#exports").locator("xpath=..").screenshot(
            path=str(shots / "viewer_copy_python.png"))
    set_state(page, {})


@pytest.mark.browser
def test_the_shown_code_follows_the_edits(page, tmp_path):
    """Once shown, the code is remade with each new design (no second click)."""
    set_state(page, {"lmax": 2})
    page.click("#copy-python")
    page.wait_for_function("() => window.__shprobe.lastSnippet")
    set_state(page, {"lmax": 3, "scale_band": {"2": 0.25}})
    page.wait_for_function("() => window.__shprobe.lastSnippet.includes('scale_bands=')")
    shown = np.array(page.evaluate("() => window.__shprobe.coeffs"))
    L = run_snippet(page.evaluate("() => window.__shprobe.lastSnippet"), tmp_path)
    np.testing.assert_allclose(L, shown, rtol=1e-12, atol=1e-12 * np.abs(shown).max())
    set_state(page, {})


def _post(served, path: str, body: str | bytes, query: dict | None = None, **kw):
    import httpx

    return httpx.post(served.base + path, params={"token": served.token, **(query or {})},
                      content=body, timeout=60, **kw)


def test_snippet_of_other_sources_equals_the_servers_design(served, tmp_path):
    """Preset and uploaded-coefficient sources, and a blended upload (the snippet names the
    file as uploaded: run beside it)."""
    import json

    from shprobe.lighting.export import export_coeffs
    from shprobe.probes.presets import get_preset

    keep = served.session.source
    state = json.dumps({"lmax": 3, "rotation": {"axis": [1, 0, 0], "degrees": 20.0},
                        "scale_band": {"1": 1.3}})
    try:
        assert _post(served, "/api/upload/preset", b"", {"name": "stpeters"}).status_code == 200
        code = _post(served, "/api/snippet", state).text
        assert "preset='stpeters'" in code
        want = np.array(_post(served, "/api/design", state).json()["coeffs"])
        np.testing.assert_allclose(run_snippet(code, tmp_path), want, rtol=1e-12, atol=1e-13)

        coeffs = tmp_path / "light_sh.txt"
        coeffs.write_text(export_coeffs(get_preset("eucalyptus") * 1.5, "cmgen"))
        r = _post(served, "/api/upload/coeffs", coeffs.read_bytes(),
                  headers={"X-Filename": coeffs.name})
        assert r.status_code == 200
        code = _post(served, "/api/snippet", state).text
        assert "coeffs='light_sh.txt'" in code
        want = np.array(_post(served, "/api/design", state).json()["coeffs"])
        np.testing.assert_allclose(run_snippet(code, tmp_path), want, rtol=1e-12, atol=1e-13)
    finally:
        served.session.source = keep
    other = data_file("probes", "ennis.hdr")
    r = _post(served, "/api/upload/blend", other.read_bytes(),
              headers={"X-Filename": other.name})
    assert r.status_code == 200, r.text
    pid = served.session.probe_list()[-1]["id"]
    state = json.dumps({"lmax": 4, "blends": [{"probe": pid, "weight": 0.4}]})
    code = _post(served, "/api/snippet", state).text
    assert "name='ennis.hdr'" in code
    want = np.array(_post(served, "/api/design", state).json()["coeffs"])
    np.testing.assert_allclose(run_snippet(code, other.parent), want, rtol=1e-12, atol=1e-13)
    bad = _post(served, "/api/snippet", '{"lmax": 99}')
    assert bad.status_code == 400 and "lmax" in bad.json()["error"]


def test_snippet_builder_sources(tmp_path, grace_path):
    """The builder alone: darkness, a probe with its layout, an export written under the
    viewer's download name, and each run giving `shprobe edit`'s file."""
    from shprobe.cli.main import main
    from shprobe.lighting.filenames import export_name

    spec = EditSpec.from_text(["--directional", "0,1,0:3", "--lmax", "2"])
    L = run_snippet(python_snippet(spec, SnippetSource(None)), tmp_path)
    from shprobe.lighting.design import directional_light

    np.testing.assert_allclose(L, directional_light([0, 1, 0], [3.0], 2) * np.ones(3),
                               rtol=1e-15)
    spec = EditSpec.from_text(["--rotate", "0,0,1:45", "--lmax", "3", "--window", "auto"])
    code = python_snippet(spec, SnippetSource(str(grace_path), layout="latlong"), fmt="json")
    assert "layout='latlong'" in code
    run_snippet(code, tmp_path)
    name = export_name(str(grace_path), spec, "json")
    out = tmp_path / "cli"
    out.mkdir()
    assert main(["edit", str(grace_path), *spec.to_text(), "-o", str(out)]) == 0
    assert (tmp_path / name).read_text() == (out / name).read_text()
    with pytest.raises(ShprobeError, match="cube faces"):
        python_snippet(spec, SnippetSource("a.hdr … f.hdr (cube faces)"))


def test_snippet_of_the_procedural_sky_equals_the_sessions_design(tmp_path):
    """No probe: the session's procedural sky, which has no file: the snippet makes it."""
    from shprobe.viewer.app import python_text
    from shprobe.viewer.design import read_state
    from shprobe.viewer.session import Session

    s = Session()
    try:
        for state in ({}, {"lmax": 5, "rotation": {"axis": [0, 0, 1], "degrees": 80.0}}):
            spec = read_state(state)
            code = python_text(s, spec)
            assert "procedural_env" in code
            np.testing.assert_allclose(run_snippet(code, tmp_path), s.design_exact(spec)[0],
                                       rtol=1e-12, atol=1e-13)
    finally:
        s.close()
