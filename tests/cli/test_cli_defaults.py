"""One defaults table: each workflow's CLI options take their defaults from the workflow's
settings type, so ``shprobe X`` and the library's entry do the same thing unasked. Checked by
introspecting the click commands (their parameters' defaults) against the dataclasses'."""

from __future__ import annotations

import dataclasses

import click
import pytest

from shprobe.batch.rows import BatchOptions
from shprobe.cli.grid import grid
from shprobe.cli.hbasis import hbasis_group
from shprobe.cli.prt import prt_group
from shprobe.fitting import FitSettings
from shprobe.grids import GridSettings
from shprobe.hbasis import HBasisSettings
from shprobe.lighting.design_settings import EditSettings, ExportSettings, WindowSettings
from shprobe.lighting.workflow import IrradianceSettings, PrefilterSettings
from shprobe.prt import DEFAULT_LMAX, PrtSettings
from shprobe.prt.view import PrtRenderSettings
from shprobe.report.probe import ReportSettings
from shprobe.scene.workflow import BasisImagesSettings, RenderSettings


def _command(path: str) -> click.Command:
    """A command by its words ('prt bake'), loaded as the top-level group loads it."""
    from shprobe.cli.main import cli

    ctx = click.Context(cli)
    cmd: click.Command = cli
    for word in path.split():
        cmd = cmd.get_command(ctx, word)  # type: ignore[attr-defined]
        assert cmd is not None, path
    return cmd


def _field_default(settings_type: type, name: str):
    f = settings_type.__dataclass_fields__[name]
    if f.default is not dataclasses.MISSING:
        return f.default
    return f.default_factory()  # type: ignore[misc]


def _parse_size(text: str):
    w, h = text.split("x")
    return int(w), int(h)


#: (command, settings type, {option name: (settings field, option value → field value)}):
#: every option that sets a field of the workflow's settings.
WORKFLOWS = [
    ("prt bake", PrtSettings, {
        "mode": ("mode", None), "lmax": ("lmax", None), "samples": ("samples", None),
        "bounces": ("bounces", None), "seed": ("seed", None), "threads": ("threads", None),
        "refine": ("refine", None)}),
    ("prt render", PrtRenderSettings, {
        "lmax": ("lmax", None), "mode": ("mode", None), "bounces": ("bounces", None),
        "size": ("size", _parse_size), "azimuth": ("azimuth", None),
        "elevation": ("elevation", None),
        "exposure": ("exposure", lambda v: None if v == "auto" else float(v)),
        "turntable": ("turntable", None)}),
    ("grid bake", GridSettings, {
        "bounces": ("bounces", None), "lmax": ("lmax", int), "samples": ("samples", None),
        "gather": ("gather", None)}),
    ("hbasis bake", HBasisSettings, {"basis": ("basis", None), "bands": ("bands", None)}),
    ("prefilter", PrefilterSettings, {"lmax": ("lmax", None)}),
    ("irradiance", IrradianceSettings, {"method": ("method", None),
                                        "out_layout": ("out_layout", None),
                                        "exposure": ("exposure",
                                                     lambda v: None if v == "auto" else v)}),
    ("render", RenderSettings, {
        "mode": ("mode", None), "size": ("size", _parse_size), "azimuth": ("azimuth", None),
        "elevation": ("elevation", None), "fov": ("fov", None), "ortho": ("ortho", None),
        "exposure": ("exposure", lambda v: None if v == "auto" else float(v))}),
    ("fit grey-ball", FitSettings, {"no_robust": ("robust", lambda v: not v),
                                    "saturation": ("saturation", None)}),
    ("report", ReportSettings, {"map_size": ("map_height", None),
                                "render_size": ("render_size", None)}),
    ("basis-images", BasisImagesSettings, {
        "lmax": ("lmax", None), "mode": ("mode", None), "size": ("size", _parse_size),
        "azimuth": ("azimuth", None), "elevation": ("elevation", None), "fov": ("fov", None),
        "ortho": ("ortho", None)}),
    ("edit", EditSettings, {"lmax": ("lmax", None), "weight": ("weight", None),
                            "window": ("window", None), "fmt": ("format", None)}),
    ("window", WindowSettings, {"lmax": ("lmax", None), "window": ("window", None)}),
    ("export", ExportSettings, {"lmax": ("lmax", None), "window": ("window", None)}),
    ("batch", BatchOptions, {
        "lmax": ("lmax", None), "thumbnail": ("thumbnail", None), "window": ("window", None),
        "clamp": ("clamp", None), "reference": ("reference", None)}),
]


@pytest.mark.parametrize(("path", "settings_type", "options"), WORKFLOWS,
                         ids=[w[0] for w in WORKFLOWS])
def test_cli_option_defaults_are_the_settings_defaults(path, settings_type, options):
    cmd = _command(path)
    ctx = click.Context(cmd)
    params = {p.name: p for p in cmd.params}
    for name, (field, convert) in options.items():
        assert name in params, f"{path}: no option for {name}"
        value = params[name].get_default(ctx)
        if convert is not None and value is not None:
            value = convert(value)
        want = _field_default(settings_type, field)
        assert value == want, f"{path} --{name}: CLI default {value!r}, library {want!r}"


def test_one_default_lmax_for_the_prt_bake():
    """The CLI's and the library's PRT degree are the one documented value."""
    cmd = _command("prt bake")
    lmax = next(p for p in cmd.params if p.name == "lmax")
    assert PrtSettings().lmax == DEFAULT_LMAX == lmax.get_default(click.Context(cmd))


def test_the_groups_are_module_level_objects():
    """The commands are importable module attributes (not made inside register())."""
    for group in (prt_group, grid, hbasis_group):
        assert isinstance(group, click.Group) and group.commands


def test_a_changed_default_would_be_seen():
    """The comparison can fail: a settings type whose default differs from the option's."""
    @dataclasses.dataclass(frozen=True)
    class Other:
        lmax: int = DEFAULT_LMAX + 1

    cmd = _command("prt bake")
    lmax = next(p for p in cmd.params if p.name == "lmax")
    assert lmax.get_default(click.Context(cmd)) != _field_default(Other, "lmax")
