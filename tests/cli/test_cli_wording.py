"""What the terminal and the pictures say: a turntable's closing line counts its frames, a
table piped to a file or another program keeps each row on one line, and the H-basis figure
says why its H6 and H4 panels look alike."""

from __future__ import annotations

import re

import numpy as np
import pytest
import trimesh

from shprobe.cli.main import main
from shprobe.hbasis.rendering import save_panel
from shprobe.probes.figures import read_panels
from shprobe.scene import Camera, RenderResult


def test_turntable_closing_line_counts_the_frames(tmp_path, capsys):
    mesh = tmp_path / "sphere.obj"
    trimesh.creation.icosphere(subdivisions=1).export(mesh)
    t = tmp_path / "t.npz"
    assert main(["prt", "bake", str(mesh), "--mode", "unshadowed", "--lmax", "2",
                 "-o", str(t)]) == 0
    capsys.readouterr()
    frames = tmp_path / "frames"
    assert main(["prt", "render", str(t), "--cone", "0,1,0:30", "--size", "16x16",
                 "--turntable", "5", "-o", str(frames / "f.png")]) == 0
    last = capsys.readouterr().err.strip().splitlines()[-1]
    # one line naming how many frames and the first and last, not a list of two files
    assert re.match(r"wrote 5 files in .*frames/: f_000\.png … f_004\.png \(turntable frames, ",
                    last), last
    assert sorted(p.name for p in frames.iterdir()) == [f"f_{i:03d}.png" for i in range(5)]


def test_piped_table_rows_stay_on_one_line(capsys, monkeypatch, grace_path):
    # captured stdout is not a terminal, as when piped; without COLUMNS rich would use 80
    monkeypatch.delenv("COLUMNS", raising=False)
    assert main(["error", str(grace_path), "--lmax-max", "3"]) == 0
    out = capsys.readouterr().out
    rows = [ln for ln in out.splitlines() if ln.startswith("│")]
    assert [ln.split("│")[1].strip() for ln in rows] == ["1", "2", "3"]  # one line per row
    assert max(len(ln) for ln in out.splitlines()) > 80
    assert any("= lmax 2 (Â_3 = 0)" in ln for ln in rows)


@pytest.mark.parametrize("keys, says", [(("H6", "H4", "SH9"), True), (("H4", "SH9"), False)])
def test_hbasis_figure_says_why_h6_matches_h4(tmp_path, keys, says):
    h = w = 24
    ref = np.full((h, w, 3), 2.0, np.float32)
    layers = {k: ref * (1 + 0.01 * i) for i, k in enumerate(keys)}
    res = RenderResult(image=ref, radiance=ref, mask=np.ones((h, w), bool),
                       normals=np.zeros((h, w, 3), np.float32), irradiance=ref,
                       face=np.zeros((h, w), np.int64), bary=np.zeros((h, w, 3), np.float32),
                       camera=Camera(w, h), mode="pixel", layers=layers,
                       info={"rel_rms": {k: 0.01 for k in keys}})
    title = read_panels(save_panel(tmp_path / "nm.png", res))["title"]
    assert ("H6 ≈ H4" in title and "H⁵ and H⁶ vanish" in title) is says, title
