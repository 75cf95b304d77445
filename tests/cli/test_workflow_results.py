"""Every workflow's library entry returns a result whose ``as_dict()`` is JSON (what the CLI,
the viewer and batch serialise through): each entry run on a tiny input, its document
through ``json.dumps`` (NaN and infinity refused), and a figure of it checked against the
result it came from."""

from __future__ import annotations

import json

import numpy as np
import pytest


def _json(result) -> dict:
    doc = result.as_dict()
    assert isinstance(doc, dict) and doc
    return json.loads(json.dumps(doc, allow_nan=False))


@pytest.fixture(scope="module")
def grace():
    from shprobe.probes.presets import get_preset

    return get_preset("grace")


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    import trimesh

    p = tmp_path_factory.mktemp("mesh") / "sphere.obj"
    trimesh.creation.icosphere(subdivisions=1).export(p)
    return p


@pytest.fixture(scope="module")
def mesh(sphere):
    from shprobe.scene.mesh import load_mesh

    return load_mesh(sphere)


def test_prefilter():
    from shprobe.lighting.workflow import PrefilterSettings, prefilter

    lit = prefilter(settings=PrefilterSettings(lmax=2), preset="grace")
    doc = _json(lit)
    assert np.allclose(np.asarray(doc["coefficients"], float).reshape(9, 3), lit.coeffs)


def test_irradiance_map(grace, tmp_path):
    from shprobe.lighting.source import Lighting
    from shprobe.lighting.workflow import IrradianceSettings, write_irradiance_map

    res = write_irradiance_map(Lighting(grace, "grace"), tmp_path / "e.exr",
                               IrradianceSettings(size=(16, 8)))
    doc = _json(res)
    assert (tmp_path / "e.exr").exists() and "e.exr" in json.dumps(doc)


def test_render(grace, mesh, tmp_path):
    from shprobe.scene.workflow import RenderSettings, render_image

    res = render_image(mesh, grace, tmp_path / "r.png", RenderSettings(size=(24, 24)))
    assert (tmp_path / "r.png").exists() and "r.png" in json.dumps(_json(res))


@pytest.fixture(scope="module")
def transfer(sphere):
    from shprobe.prt import PrtSettings, bake

    return bake(str(sphere), PrtSettings(mode="unshadowed", lmax=2, samples=64, bounces=0))


def test_prt_bake(transfer):
    doc = _json(transfer)
    assert str(transfer.vertices.shape[0]) in json.dumps(doc)


def test_prt_render(transfer, grace, tmp_path):
    from shprobe.prt.view import PrtRenderSettings, render

    res = render(transfer, grace, tmp_path / "p.png", PrtRenderSettings(size=(24, 24)))
    assert (tmp_path / "p.png").exists() and "p.png" in json.dumps(_json(res))


def test_hbasis_bake(grace, mesh):
    from shprobe.hbasis import HBasisSettings, bake_hbasis

    res = bake_hbasis(mesh, grace, HBasisSettings())
    assert str(len(mesh.vertices)) in json.dumps(_json(res))


def test_grid_bake(grace):
    import trimesh

    from shprobe.grids import GridSettings, bake_grid

    speck = trimesh.Trimesh([[0, 0, 0], [1e-3, 0, 0], [0, 0, 1e-3]], [[0, 2, 1]],
                            process=False)
    g = bake_grid(speck, grace, GridSettings((2, 1, 2), bounds=[[-2, -1, -2], [2, 1, 2]],
                                             bounces=0, samples=64))
    doc = _json(g)
    assert "2" in json.dumps(doc)


def test_splat_transform(tmp_path):
    from shprobe import splats as sp
    from tests.splats import splat_reference as ref

    path = tmp_path / "s.ply"
    ref.write_trainer_ply(path, ref.random_splats(50, 1, seed=3))
    res = sp.transform_file(path, tmp_path / "o.ply", sp.TransformSettings())
    doc = _json(res)
    assert (doc["count"], doc["sh_degree_out"]) == (50, 1) and doc["path"].endswith("o.ply")


def test_fit(grey):
    from shprobe.fitting import fit_grey_ball, read_photo

    photo = read_photo(grey)
    res = fit_grey_ball(photo.image)
    doc = _json(res)
    assert np.allclose(np.asarray(doc["coefficients"], float).reshape(9, 3), res.coeffs)
    assert doc["fit"]["kind"] == "grey" and doc["fit"]["pixels"] == res.fit.weights.size
    # the CLI's document is the same one, with the photo's name and exposure
    from shprobe.fitting.report import fit_document

    assert res.as_dict(str(grey), photo) == fit_document(res, str(grey), photo)


def test_report():
    from shprobe.probes.env import Env
    from shprobe.report.probe import ReportSettings, probe_report

    rad = np.random.default_rng(0).uniform(0.1, 1.0, (16, 32, 3)).astype(np.float32)
    rep = probe_report(Env(rad, "latlong"), settings=ReportSettings(map_height=4,
                                                                    render_size=16))
    _json(rep)


def test_batch(tmp_path):
    from shprobe.batch import Engine, run_batch
    from shprobe.probes.images import write_image

    write_image(tmp_path / "a.hdr", np.full((8, 16, 3), 0.5, np.float32))
    (tmp_path / "bad.hdr").write_bytes(b"not a probe")
    res = run_batch([tmp_path], tmp_path / "t.parquet", engine=Engine(scheduler="inline"))
    doc = _json(res)
    assert (doc["rows"], doc["failed"], doc["computed"]) == (2, 1, 2)
    assert doc["rows"] == res.table.num_rows and doc["output"].endswith("t.parquet")
    again = run_batch([tmp_path], tmp_path / "t.parquet", engine=Engine(scheduler="inline"))
    assert (again.computed, again.as_dict()["kept"]) == (1, 1)  # the failed row is retried


def test_lightmap_bake(grace):
    pytest.importorskip("xatlas")
    from shprobe.lightmaps import LightmapSettings, bake_lightmap
    from tests.lightmaps.test_lightmaps_bake import _room

    lm = bake_lightmap(_room(), grace[:9], LightmapSettings(size=16, samples=16, bounces=0))
    _json(lm)
