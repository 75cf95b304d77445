"""The page's own maths is the library's: rotation.js — the in-page band 1–2 rotation the page
draws while dragging, the drag's rotation matrices and the state's axis-angle — run by Node
(the page's ES module as it is served, no browser) against shprobe's Wigner rotation
(``lighting.design.rotate_lighting``) and ``sh.rotation``, at random rotations and lightings."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from shprobe.lighting.design import rotate_lighting
from shprobe.sh.rotation import from_axis_angle, from_quaternion

ROTATION_JS = (Path(__file__).resolve().parents[2] / "src/shprobe/viewer/static/rotation.js")

SCRIPT = """import * as R from %s;
const job = JSON.parse(process.argv[2]);
const out = {
  rotated: job.cases.map(([L, M]) => R.rotateLow(L, M)),
  drags: job.drags.map(([dx, dy, w, h]) => R.dragRotation(dx, dy, w, h)),
  axisAngles: job.cases.map(([, M]) => R.toAxisAngle(M)),
  fromAxis: job.cases.map(([, M]) => {
    const a = R.toAxisAngle(M); return R.rotAxis(a.axis, a.degrees); }),
};
console.log(JSON.stringify(out));
"""


@pytest.fixture(scope="module")
def node() -> str:
    exe = shutil.which("node")
    if exe is None:
        pytest.skip("node not installed")
    return exe


def _run(node: str, tmp_path: Path, job: dict) -> dict:
    script = tmp_path / "maths.mjs"
    script.write_text(SCRIPT % json.dumps(ROTATION_JS.as_uri()))
    r = subprocess.run([node, str(script), json.dumps(job)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout)


@pytest.mark.node
def test_rotation_js_is_the_librarys_rotation(node, tmp_path):
    rng = np.random.default_rng(7)
    cases = []
    for k in (1, 4, 9, 9, 9, 9):  # lmax 0, 1, 2
        q = rng.normal(size=4)
        cases.append((rng.normal(size=(k, 3)), from_quaternion(q / np.linalg.norm(q))))
    cases.append((rng.normal(size=(9, 3)), from_axis_angle([0, 0, 1], 179.9)))  # near 180°
    drags = [(48, 0, 512, 256), (0, 32, 512, 256), (-30, 17, 400, 200)]
    out = _run(node, tmp_path, {"cases": [[L.tolist(), R.tolist()] for L, R in cases],
                                "drags": drags})
    for (L, R), got, back in zip(cases, out["rotated"], out["fromAxis"], strict=True):
        np.testing.assert_allclose(np.array(got), rotate_lighting(L, R),
                                   atol=1e-12 * np.abs(L).max())
        np.testing.assert_allclose(np.array(back), R, atol=1e-9)  # axis-angle round trip
    for (dx, dy, w, h), got in zip(drags, out["drags"], strict=True):
        want = from_axis_angle([1, 0, 0], -180.0 * dy / h) @ from_axis_angle(
            [0, 1, 0], -360.0 * dx / w)
        np.testing.assert_allclose(np.array(got), want, atol=1e-12)
    # the test can fail: a wrong sign in the page's band 2 is seen
    L, R = cases[3]
    bad = np.array(out["rotated"][3])
    bad[4] *= -1
    assert np.abs(bad - rotate_lighting(L, R)).max() > 1e-3
