"""The Unity and Godot grid exports checked against each engine's own evaluation, written here
from the engines' sources as oracles (docs/grid-exports.md cites them), and the
``shprobe grid export`` command.

Unity: a ``SphericalHarmonicsL2`` (27 floats, ``sh[rgb, k]``) is packed into the shader
constants as HDRP's ``SphericalHarmonicMath.PackCoefficients`` / the built-in pipeline do
(SHA = (sh[3], sh[1], sh[2], sh[0] − sh[6]), SHB = (sh[4], sh[5], 3 sh[6], sh[7]),
SHC = sh[8]) and ``ShadeSH9`` (UnityCG.cginc) sums SHA·(n, 1) + SHB·(xy, yz, z², xz) +
SHC (x² − y²): the outgoing radiance E/π of a white Lambertian surface, at a normal in Unity's
left-handed frame. Godot: the forward shaders' lightmap-capture polynomial (c1 … c5 =
0.429043, 0.511664, 0.743125, 0.886227, 0.247708) on the probe SH gives E/π too.

Between probes each oracle blends the exported probes trilinearly on the axes it reads from the
exported positions (scipy's RegularGridInterpolator, in the engine's frame), at the sample
point three.js uses (half a cell along the normal, clamped to the outer probes): equal to
``ProbeGrid.irradiance(..., leak_control=False) / π``.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from shprobe.cli.main import main
from shprobe.grids.exports import FORMATS, SUFFIX, export_grid, export_text
from shprobe.grids.grid import ProbeGrid
from shprobe.grids.io import save_grid
from shprobe.lighting import irradiance

TOL = 1e-5


def random_grid(lmax: int = 2, seed: int = 3) -> ProbeGrid:
    rng = np.random.default_rng(seed)
    K = (lmax + 1) ** 2
    c = rng.normal(size=(4, 3, 5, K, 3)) * 0.3
    c[..., 0, :] += 2.0
    return ProbeGrid(c.astype(np.float32), np.array([[-3.0, 0.0, -2.0], [1.0, 2.5, 3.0]]))


def samples(grid: ProbeGrid, n: int = 300, seed: int = 4):
    rng = np.random.default_rng(seed)
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    lo, hi = grid.bounds
    return lo - 0.3 + rng.random((n, 3)) * (hi - lo + 0.6), nrm  # some beyond the faces


def blend(points: np.ndarray, values: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Trilinear blend of per-probe ``values`` (P, ...) at q (N, 3), the axes read from the
    probe ``points`` (P, 3) in whatever order they come; q clamped to the outer probes."""
    axes = [np.unique(points[:, a]) for a in range(3)]
    index = [np.searchsorted(axes[a], points[:, a]) for a in range(3)]
    table = np.zeros((*(len(x) for x in axes), *values.shape[1:]))
    table[index[0], index[1], index[2]] = values
    qc = np.clip(q, [x[0] for x in axes], [x[-1] for x in axes])
    return RegularGridInterpolator(axes, table)(qc)


def sample_points(points: np.ndarray, p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """p + n·spacing/2, the spacing read from the probe positions."""
    spacing = np.array([np.diff(np.unique(points[:, a]))[0] for a in range(3)])
    return p + n * spacing * 0.5


def shade_sh9(sh: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Unity: SphericalHarmonicsL2 (N, 3 rgb, 9) at normals (N, 3), packed and summed as the
    built-in / HDRP shaders do."""
    sha = np.stack([sh[..., 3], sh[..., 1], sh[..., 2], sh[..., 0] - sh[..., 6]], -1)
    shb = np.stack([sh[..., 4], sh[..., 5], 3.0 * sh[..., 6], sh[..., 7]], -1)
    shc = sh[..., 8]
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    n4 = np.stack([x, y, z, np.ones_like(x)], -1)
    vb = np.stack([x * y, y * z, z * z, z * x], -1)
    return (np.einsum("nci,ni->nc", sha, n4) + np.einsum("nci,ni->nc", shb, vb)
            + shc * (x * x - y * y)[:, None])


def godot_capture(sh: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Godot: the forward shader's lightmap-capture polynomial on sh (N, 9, 3)."""
    c1, c2, c3, c4, c5 = 0.429043, 0.511664, 0.743125, 0.886227, 0.247708
    x, y, z = (n[:, i][:, None] for i in range(3))
    return (c1 * sh[:, 8] * (x * x - y * y) + c3 * sh[:, 6] * z * z + c4 * sh[:, 0]
            - c5 * sh[:, 6] + 2 * c1 * sh[:, 4] * x * y + 2 * c1 * sh[:, 7] * x * z
            + 2 * c1 * sh[:, 5] * y * z + 2 * c2 * sh[:, 3] * x + 2 * c2 * sh[:, 1] * y
            + 2 * c2 * sh[:, 2] * z)


def rel(a, b) -> float:
    return float(np.abs(np.asarray(a) - b).max() / np.abs(b).max())


@pytest.mark.parametrize("lmax", [1, 2])
def test_unity_shade_sh9_of_the_export(tmp_path, lmax):
    grid = random_grid(lmax)
    doc = json.loads(export_grid(grid, "unity", tmp_path / "g.unity.json").read_text())
    assert doc["format"] == "shprobe-grid-unity" and doc["resolution"] == [4, 3, 5]
    pos = np.reshape(doc["positions"], (-1, 3))
    sh = np.reshape(doc["coefficients"], (-1, 3, 9))
    mirror = np.array([1.0, 1.0, -1.0])
    # at each probe: ShadeSH9 at the Unity normal = E/π of that probe's own coefficients
    n = samples(grid, 60)[1]
    for i, (ix, iy, iz) in enumerate(np.ndindex(*grid.resolution)):
        if i % 7:
            continue
        np.testing.assert_allclose(pos[i], grid.centres()[ix, iy, iz] * mirror, atol=1e-6)
        ref = irradiance(grid.coeffs[ix, iy, iz].astype(np.float64), n) / np.pi
        assert rel(shade_sh9(np.repeat(sh[i][None], len(n), 0), n * mirror), ref) < TOL
    # between probes: Unity-frame trilinear blend at the sample point, ShadeSH9
    p, n = samples(grid)
    pu, nu = p * mirror, n * mirror
    got = shade_sh9(blend(pos, sh, sample_points(pos, pu, nu)), nu)
    ref = grid.irradiance(p, n, leak_control=False) / np.pi
    print(f"Unity ShadeSH9 of the export vs ProbeGrid.irradiance/pi: max rel {rel(got, ref):.3g}")
    assert rel(got, ref) < TOL
    # the frame matters: the same coefficients read at the unmirrored normal disagree
    assert rel(shade_sh9(blend(pos, sh, sample_points(pos, pu, nu)), n), ref) > 1e-2
    lo, hi = np.reshape(doc["bounds"], (2, 3))
    np.testing.assert_allclose([lo, hi], [[-3, 0, -3], [1, 2.5, 2]])


def parse_tres(text: str) -> dict:
    """The metadata of a Godot text resource: AABB, Vector3i, packed arrays, ints, strings."""
    assert text.startswith('[gd_resource type="Resource" format=3]\n\n[resource]\n')
    out = {}
    for key, value in re.findall(r"^metadata/(\w+) = (.*)$", text, re.M):
        m = re.fullmatch(r"(AABB|Vector3i|PackedVector3Array|PackedColorArray)\((.*)\)", value)
        if m:
            out[key] = np.array([float(v) for v in m.group(2).split(",")])
        elif value.startswith('"'):
            out[key] = json.loads(value)
        else:
            out[key] = int(value)
    return out


@pytest.mark.parametrize("lmax", [1, 2])
def test_godot_capture_of_the_export(tmp_path, lmax):
    grid = random_grid(lmax)
    res = parse_tres(export_grid(grid, "godot", tmp_path / "g.tres", source='a "b"').read_text())
    assert res["format"] == "shprobe-grid-godot" and res["version"] == 1
    assert res["resolution"].tolist() == [4, 3, 5]
    np.testing.assert_allclose(res["bounds"], [-3, 0, -2, 4, 2.5, 5])
    pts = res["points"].reshape(-1, 3)
    np.testing.assert_allclose(pts, grid.centres().reshape(-1, 3), atol=1e-6)
    sh = res["sh"].reshape(-1, 9, 4)
    assert np.all(sh[..., 3] == 1.0)
    p, n = samples(grid)
    got = godot_capture(blend(pts, sh[..., :3], sample_points(pts, p, n)), n)
    ref = grid.irradiance(p, n, leak_control=False) / np.pi
    print(f"Godot capture polynomial of the export vs ProbeGrid.irradiance/pi: "
          f"max rel {rel(got, ref):.3g}")
    assert rel(got, ref) < TOL
    assert rel(godot_capture(blend(pts, sh[..., :3], sample_points(pts, p, n)),
                             n * [1, 1, -1]), ref) > 1e-2


def test_relocated_probes_export_at_their_cell_centres():
    """A probe baked at a moved point is still looked up at its cell centre (the plain
    interpolation's lattice): that is where the exports place it."""
    grid = random_grid()
    moved = grid.centres() + 0.1
    g = ProbeGrid(grid.coeffs, grid.bounds, positions=moved)
    pos = np.reshape(json.loads(export_text(g, "unity"))["positions"], (-1, 3))
    np.testing.assert_allclose(pos, (grid.centres() * [1, 1, -1]).reshape(-1, 3), atol=1e-6)
    pts = parse_tres(export_text(g, "godot"))["points"].reshape(-1, 3)
    np.testing.assert_allclose(pts, grid.centres().reshape(-1, 3), atol=1e-6)


def test_three_export_layout():
    """The three document: texture order (X fastest), R&H L_lm unchanged, bounds as given."""
    grid = random_grid()
    doc = json.loads(export_text(grid, "three"))
    c = np.reshape(doc["coefficients"], (5, 3, 4, 9, 3))  # (nz, ny, nx, k, rgb)
    np.testing.assert_allclose(c[4, 2, 1], grid.coeffs[1, 2, 4], rtol=1e-7)
    assert doc["bounds"] == [-3.0, 0.0, -2.0, 1.0, 2.5, 3.0] and doc["resolution"] == [4, 3, 5]
    l1 = random_grid(lmax=1)  # padded: three.js's shader reads 9 coefficients
    c = np.reshape(json.loads(export_text(l1, "three"))["coefficients"], (5, 3, 4, 9, 3))
    np.testing.assert_allclose(c[..., :4, :], np.transpose(l1.coeffs, (2, 1, 0, 3, 4)))
    assert not c[..., 4:, :].any()


def test_non_finite_grid_is_refused(tmp_path):
    c = np.ones((2, 2, 2, 9, 3), np.float32)
    c[1, 1, 1, 4, 2] = np.nan
    grid = ProbeGrid(c, np.array([[0.0, 0, 0], [1, 1, 1]]))
    for fmt in FORMATS:
        with pytest.raises(Exception, match="non-finite"):
            export_grid(grid, fmt, tmp_path / f"g{SUFFIX[fmt]}")
        assert not (tmp_path / f"g{SUFFIX[fmt]}").exists()


def test_cli_grid_export(tmp_path, capsys):
    from shprobe.cli import grid_export

    assert grid_export.FORMATS == FORMATS and grid_export.SUFFIX == SUFFIX
    grid = random_grid()
    src = save_grid(tmp_path / "room.npz", grid)
    for fmt in FORMATS:
        out = tmp_path / f"room{SUFFIX[fmt]}"
        assert main(["grid", "export", str(src), "--format", fmt, "-o", str(out)]) == 0
        assert out.read_text() == export_text(grid, fmt, source="room.npz")
        err = capsys.readouterr().err
        assert err.startswith(f"wrote {out} (") and "4x3x5 probes" in err
        # an existing output is refused before any work, and replaced with --force
        assert main(["grid", "export", str(src), "--format", fmt, "-o", str(out)]) == 1
        assert "already exists" in capsys.readouterr().err
        assert main(["grid", "export", str(src), "--format", fmt, "-o", str(out), "-f"]) == 0
        assert capsys.readouterr().err.startswith(f"wrote {out} (")
    # over the memory limit: one line before any work, nothing written
    assert main(["--max-memory", "1K", "grid", "export", str(src), "--format", "godot", "-o",
                 str(tmp_path / "big.tres")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "would need about" in err
    assert not (tmp_path / "big.tres").exists()
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    for args in ([str(bad)], [str(tmp_path / "none.npz")]):
        assert main(["grid", "export", *args, "--format", "three", "-o",
                     str(tmp_path / "x.json")]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("shprobe: error: ")
        assert not (tmp_path / "x.json").exists()
