"""The figure helper (shprobe.probes.figures): exposure rule, layout, labels, colour bars and
the sign legend, checked on the rendered pixels."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from shprobe.errors import ShprobeError
from shprobe.probes.figures import (
    Panel,
    clipped_fraction,
    exposure_for,
    figure,
    read_panels,
    write_figure,
)


def crop(pixels: np.ndarray, box) -> np.ndarray:
    x0, y0, x1, y1 = box
    return pixels[y0:y1, x0:x1]


def dark_fraction(pixels: np.ndarray, box) -> float:
    """Fraction of clearly non-white pixels in a box (text is dark on the white page)."""
    c = crop(pixels, box).astype(int)
    return float((c.min(axis=-1) < 160).mean()) if c.size else 0.0


def srgb8(v: float) -> int:
    v = min(max(v, 0.0), 1.0)
    s = 12.92 * v if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055
    return round(255 * s)


def test_exposure_maps_the_percentile_to_white():
    # values 1..1000 (each once): the 99th percentile is 990.01 (numpy's linear rule)
    v = np.arange(1, 1001, dtype=np.float64)
    img = np.stack([v, v / 2, v / 4], -1).reshape(10, 100, 3)
    e = exposure_for(img)
    assert e == np.floor(-np.log2(990.01) * 10) / 10
    assert clipped_fraction(img, e) <= 0.01
    assert clipped_fraction(img, e + 0.2) > 0.01  # not needlessly dark either
    # the largest channel counts: blue-only light is exposed like the same red light
    assert exposure_for(img[..., ::-1]) == e
    # a mask picks the pixels that count; no light at all gives 0
    mask = np.zeros((10, 100), bool)
    mask[0, :10] = True  # values 1..10
    assert exposure_for(img, mask=mask) == np.floor(-np.log2(9.91) * 10) / 10
    assert exposure_for(np.zeros((4, 4, 3))) == 0.0


def test_radiance_panel_pixels_are_the_tone_map_at_the_stated_exposure():
    img = np.zeros((40, 80, 3), np.float32)
    img[:, :40] = (0.5, 0.25, 0.125)
    img[:, 40:] = (4.0, 0.0, 0.0)
    fig = figure([Panel(img, "left half", units="W", exposure=-1.0)], display_width=160)
    (box,) = [p.image_box for p in fig.panels]
    assert fig.panels[0].kind == "radiance"
    px = crop(fig.pixels, box)
    assert px.shape[:2] == (80, 160)  # scaled 2x, aspect kept
    left, right = px[40, 20], px[40, 140]
    np.testing.assert_allclose(left, [srgb8(0.25), srgb8(0.125), srgb8(0.0625)], atol=1)
    np.testing.assert_allclose(right, [255, 0, 0], atol=1)


def test_titles_are_drawn_above_each_panel_and_nowhere_else():
    rng = np.random.default_rng(0)
    panels = [Panel(rng.random((32, 64, 3)), f"panel {i}", units="relative radiance")
              for i in range(3)]
    fig = figure(panels, title="three panels", columns=2)
    assert len(fig.panels) == 3
    h, w = fig.pixels.shape[:2]
    for p in fig.panels:
        assert 0 <= p.title_box[0] < p.title_box[2] <= w
        assert p.title_box[3] <= p.image_box[1] <= h
        assert dark_fraction(fig.pixels, p.title_box) > 0.02, p.title
    # the same page with empty titles has a blank first line where the titles were (the
    # second line, units and exposure, stays)
    blank = figure([Panel(p.image, "", exposure=0.0) for p in panels], columns=2)
    for p, q in zip(blank.panels, fig.panels, strict=True):
        x0, y0, x1, _ = p.title_box
        assert dark_fraction(blank.pixels, (x0, y0, x1, y0 + 14)) == 0.0
        qx0, qy0, qx1, _ = q.title_box
        assert dark_fraction(fig.pixels, (qx0, qy0, qx1, qy0 + 14)) > 0.02
        assert dark_fraction(blank.pixels, (x0, y0 + 15, x1, y0 + 30)) > 0.02
    # the empty cell of the 2x2 grid stays white
    x0 = fig.panels[1].image_box[0]
    y0 = fig.panels[2].title_box[1]
    empty = fig.pixels[y0:, x0:]
    assert (empty > 250).all()


def test_signed_panels_are_green_positive_blue_negative_with_a_bar_and_legend():
    ramp = np.linspace(-1.0, 1.0, 64)[None, :].repeat(32, axis=0)
    fig = figure([Panel(ramp, "ramp", "signed", units="a.u.", scale=1.0)])
    (p,) = fig.panels
    assert fig.legend and p.colorbar_box is not None
    px = crop(fig.pixels, p.image_box).astype(int)
    mid = px.shape[0] // 2
    neg, pos = px[mid, 2], px[mid, -3]
    assert neg[2] > 200 and neg[1] < 40 and neg[0] < 40  # blue
    assert pos[1] > 200 and pos[2] < 40 and pos[0] < 40  # green
    bar = crop(fig.pixels, p.colorbar_box).astype(int)
    top, bottom = bar[2, bar.shape[1] // 2], bar[-3, bar.shape[1] // 2]
    assert top[1] > 200 and bottom[2] > 200  # +scale green at the top, −scale blue below
    # the legend band under the panels has text and the three swatches
    legend = fig.pixels[p.image_box[3] + 4:]
    assert ((legend[..., 1] > 150) & (legend[..., 0] < 60)).any()  # green swatch
    assert ((legend[..., 2] > 200) & (legend[..., 1] < 60)).any()  # blue swatch


def test_error_panel_colour_bar_spans_zero_to_scale():
    err = np.linspace(0, 3.0, 50)[None, :].repeat(10, axis=0)
    fig = figure([Panel(err, "err", "error", units="%")])
    (p,) = fig.panels
    assert not fig.legend and p.colorbar_box is not None
    bar = crop(fig.pixels, p.colorbar_box).astype(int)
    assert bar[-3].mean() < bar[2].mean()  # dark at 0, bright at the top (magma)


def test_written_figure_reads_back(tmp_path):
    path = tmp_path / "f.png"
    fig = write_figure(path, [Panel(np.ones((8, 16, 3)), "one"), None,
                              Panel(np.ones((8, 16)), "two", "signed")], columns=3)
    with Image.open(path) as im:
        assert im.size == fig.pixels.shape[1::-1] and im.mode == "RGB"
        np.testing.assert_array_equal(np.asarray(im), fig.pixels)
    meta = read_panels(path)
    assert [p["title"] for p in meta["panels"]] == ["one", "two"]
    assert meta["legend"] is True
    with pytest.raises(ShprobeError, match="exists"):
        fig.save(path)
    assert "2 panels" in repr(fig) and len(repr(fig)) < 120


@pytest.mark.parametrize("panel, match", [
    (Panel(np.ones((4, 4)), "x", "bogus"), "kind"),
    (Panel(np.ones((4, 4, 3)), "x", "signed"), r"\(H, W\)"),
    (Panel(np.full((4, 4, 3), np.nan), "x"), "NaN"),
    (Panel(np.ones((0, 4, 3)), "x"), "empty"),
])
def test_bad_panels_are_one_line_errors(panel, match):
    with pytest.raises(ShprobeError, match=match):
        figure([panel])


def test_long_titles_are_fitted_to_the_panel():
    long = "a title far longer than the panel it belongs to, " * 3
    fig = figure([Panel(np.ones((8, 16, 3)), long), Panel(np.ones((8, 16, 3)), "next")],
                 display_width=160)
    a, b = fig.panels
    # no ink in the gap between the two cells: the first title stopped at its panel
    gap = fig.pixels[a.title_box[1]:a.title_box[3], a.image_box[2] + 3:b.image_box[0] - 1]
    assert (gap > 200).all()
