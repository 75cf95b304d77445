"""Labelled figures: panels of images laid out on a white page, each with a title and units, a
colour bar on signed and error panels and a legend where colours encode sign — the one helper
every command uses for its pictures (matplotlib, Agg, no pyplot state).

Three kinds of panel ([`Panel`][shprobe.probes.figures.Panel]):

``radiance``
    linear RGB (H, W, 3), tone-mapped as every shprobe PNG is (`shprobe.probes.images.tonemap`: ×
    2^exposure, clamp, sRGB); the title line gives the units and the exposure.
``signed``
    a scalar image (H, W) in R&H 2001 Fig. 4 colours: positive green, negative blue, black at
    0, linear in the value over ±``scale``; a colour bar shows the scale and the figure gets a
    green = positive / blue = negative legend.
``error``
    a non-negative scalar image (H, W) with a sequential colour map from 0 to ``scale`` and a
    colour bar in the panel's units.

Exposure rule ([`exposure_for`][shprobe.probes.figures.exposure_for]): the exposure in stops that
maps the ``percentile``-th percentile of the per-pixel largest channel to display white, rounded
down to 1/10 stop and lowered further while more than (100 − percentile) % of the pixels would show
as 255. (To be unified with the tone map in `shprobe.probes.images`.)

A written figure is an 8-bit RGB PNG whose ``shprobe:panels`` text chunk lists each panel's
title and its image and title boxes in pixels (x0, y0, x1, y1), so tests and tools can find
the panels without guessing.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from .tonemap import auto_exposure

KINDS = ("radiance", "signed", "error")

#: Pixels: title band above each panel, gap between cells, colour-bar block, page margin.
_TITLE_H = 34
_GAP = 14
_CBAR_W = 74
_MARGIN = 10
_HEADER_H = 26
_LEGEND_H = 28
_DPI = 100
_FONT = 8.5
#: The smallest linear value an 8-bit sRGB PNG shows as 255 (sRGB 254.5 / 255).
_WHITE = ((254.5 / 255 + 0.055) / 1.055) ** 2.4


def exposure_for(values: ArrayLike, percentile: float = 99.0,
                 mask: ArrayLike | None = None) -> float:
    """Automatic exposure (stops) for a linear RGB image ``(..., 3)``: the ``percentile``-th
    percentile p of each pixel's largest channel is mapped to display white (2^e · p = 1),
    rounded down to 0.1 stop, then lowered by 0.1 stop while more than (100 − percentile) %
    of the pixels would reach 8-bit 255 (ties in flat regions). ``mask``
    (boolean, the image's leading shape) picks the pixels that count (e.g. an object's). An
    all-zero image gives 0.

    Parameters
    ----------
    values
        (..., 3) linear RGB.
    percentile
        The percentile mapped to display white.
    mask
        The pixels that count.

    Returns
    -------
    float
        The exposure, stops.
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim >= 1 and v.shape[-1] in (3, 4):
        v = v[..., :3].max(axis=-1)
    if mask is not None:
        v = v[np.asarray(mask, dtype=bool)]
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 0.0
    if not float(np.percentile(v, percentile)) > 0:  # mostly black: key on the brightest
        v = v[v >= v.max()]
    if not v.size or not float(v.max()) > 0:
        return 0.0
    # the one percentile-to-white rule (probes.tonemap.auto_exposure), in steps of 0.1 stop
    e = float(np.floor(auto_exposure(v[:, None], 1.0, percentile) * 10.0) / 10.0)
    allowed = (100.0 - percentile) / 100.0
    for _ in range(200):  # ties at the percentile (flat regions): step down until it holds
        if float((v * 2.0 ** e >= _WHITE).mean()) <= allowed:
            break
        e = round(e - 0.1, 1)
    return e


def clipped_fraction(values: ArrayLike, exposure: float) -> float:
    """Fraction of pixels of a linear RGB image ``(..., 3)`` with a channel that reaches
    display white (8-bit 255) at ``exposure`` (stops).

    Parameters
    ----------
    values
        (..., 3) linear RGB.
    exposure
        Stops.

    Returns
    -------
    float
        The fraction of pixels with a channel at display white.
    """
    v = np.asarray(values, dtype=np.float64)
    m = v[..., :3].max(axis=-1) * 2.0 ** exposure
    return float((m >= _WHITE).mean()) if m.size else 0.0


@dataclass
class Panel:
    """One labelled panel: ``image`` (H, W, 3) linear RGB for ``kind='radiance'``, (H, W) for
    'signed' / 'error'; ``title`` (one line); ``units`` (shown under the title and on the
    colour bar); ``exposure`` in stops for radiance panels (None:
    [`exposure_for`][shprobe.probes.figures.exposure_for] of this panel); ``scale``: the value at
    the ends of the colour bar (None: the panel's max |value|).

    Parameters
    ----------
    image
        (H, W, 3) linear RGB for "radiance", (H, W) for "signed" / "error".
    title
        One line.
    kind
        "radiance", "signed" or "error".
    units
        Shown under the title and on the colour bar.
    exposure
        Stops, for a radiance panel (None: automatic).
    scale
        The value at the ends of the colour bar (None: the panel's max |value|).
    """

    image: ArrayLike
    title: str
    kind: str = "radiance"
    units: str = ""
    exposure: float | None = None
    scale: float | None = None

    def __repr__(self) -> str:
        shape = "x".join(map(str, np.shape(self.image)))
        return f"Panel({self.title!r}, {self.kind}, {shape})"


@dataclass
class PanelBox:
    """Where a panel landed on the page, in pixels (x0, y0, x1, y1; y down).

    Attributes
    ----------
    title, kind
        The panel's title and kind.
    image_box, title_box
        (x0, y0, x1, y1) of its image and its title, pixels, y down.
    colorbar_box
        Its colour bar's box, or None.
    """

    title: str
    kind: str
    image_box: tuple[int, int, int, int]
    title_box: tuple[int, int, int, int]
    colorbar_box: tuple[int, int, int, int] | None = None


@dataclass
class Figure:
    """A rendered figure: ``pixels`` (H, W, 3) uint8 and the panel boxes.

    Attributes
    ----------
    pixels
        (H, W, 3) uint8 page.
    panels
        Each panel's title, kind and boxes.
    title
        The page's title.
    legend
        Whether the sign legend is shown.
    path
        The file once saved.
    """

    pixels: NDArray[np.uint8]
    panels: list[PanelBox]
    title: str = ""
    legend: bool = False
    path: Path | None = field(default=None)

    def __repr__(self) -> str:
        h, w = self.pixels.shape[:2]
        return (f"Figure({w}x{h}, {len(self.panels)} panels"
                + (f", {self.title!r}" if self.title else "")
                + (f", {self.path}" if self.path else "") + ")")

    def metadata(self) -> str:
        """The ``shprobe:panels`` JSON of a written PNG.

        Returns
        -------
        str
            The JSON.
        """
        return json.dumps({"title": self.title, "legend": self.legend,
                           "panels": [p.__dict__ for p in self.panels]})

    def save(self, path: str | os.PathLike[str], overwrite: bool = False) -> Path:
        """Write the PNG (atomically; refuses to replace without ``overwrite``).

        Parameters
        ----------
        path
            The PNG file.
        overwrite
            Replace an existing file.

        Returns
        -------
        Path
            The file written.
        """
        from PIL import Image
        from PIL.PngImagePlugin import PngInfo

        from ..files import atomic_output

        p = Path(path)
        if p.suffix.lower() != ".png":
            raise ShprobeError("a figure is written as .png", p)
        info = PngInfo()
        info.add_text("shprobe:panels", self.metadata())
        with atomic_output(p, overwrite) as tmp:
            Image.fromarray(self.pixels, "RGB").save(tmp, format="PNG", pnginfo=info)
        self.path = p
        return p

    def png_bytes(self) -> bytes:
        """The PNG as bytes (for inlining, e.g. in an HTML report).

        Returns
        -------
        bytes
            The PNG.
        """
        import io

        from PIL import Image

        buf = io.BytesIO()
        Image.fromarray(self.pixels, "RGB").save(buf, format="PNG")
        return buf.getvalue()


def read_panels(path: str | os.PathLike[str]) -> dict:
    """The ``shprobe:panels`` metadata of a figure written by
    [`Figure.save`][shprobe.probes.figures.Figure.save].

    Parameters
    ----------
    path
        A figure's PNG.

    Returns
    -------
    dict
        Its title, legend and panels (titles, kinds, boxes, exposures).
    """
    from PIL import Image

    with Image.open(path) as im:
        text = im.text.get("shprobe:panels") if hasattr(im, "text") else None
    if text is None:
        raise ShprobeError("not a shprobe figure (no shprobe:panels metadata)", path)
    return json.loads(text)


def _fit(text, width: float) -> None:
    """Shrink a text artist's font (down to 5.5 pt), then shorten it with '…', until it fits
    in ``width`` pixels."""
    fig = text.get_figure()
    renderer = fig.canvas.get_renderer()
    while text.get_window_extent(renderer).width > width and text.get_fontsize() > 5.5:
        text.set_fontsize(text.get_fontsize() - 0.5)
    s = text.get_text()
    while text.get_window_extent(renderer).width > width and len(s) > 2:
        s = s[:-1]
        text.set_text(s.rstrip() + "…")


def _sign_cmap():
    from matplotlib.colors import LinearSegmentedColormap

    return LinearSegmentedColormap.from_list("shprobe_sign", [(0, 0, 1), (0, 0, 0), (0, 1, 0)])


def _checked(panel: Panel) -> tuple[NDArray, str]:
    if panel.kind not in KINDS:
        raise ShprobeError(f"panel kind {panel.kind!r}: expected one of {', '.join(KINDS)}")
    a = np.asarray(panel.image, dtype=np.float32)
    if panel.kind == "radiance":
        if a.ndim == 2:
            a = np.repeat(a[..., None], 3, axis=2)
        if a.ndim != 3 or a.shape[2] not in (3, 4):
            raise ShprobeError(f"panel {panel.title!r}: a radiance image is (H, W, 3), got "
                               f"{a.shape}")
        a = a[..., :3]
    elif a.ndim != 2:
        raise ShprobeError(f"panel {panel.title!r}: a {panel.kind} image is (H, W), got "
                           f"{a.shape}")
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise ShprobeError(f"panel {panel.title!r} is empty")
    if not np.all(np.isfinite(a)):
        raise ShprobeError(f"panel {panel.title!r} has NaN or Inf values")
    return a, panel.kind


def figure(panels: Sequence[Panel | None] | Sequence[Sequence[Panel | None]],
           title: str = "", columns: int | None = None, legend: bool | None = None,
           display_width: int | None = None, shared_colorbar: bool = False) -> Figure:
    """Lay out ``panels`` on a grid and render the page.

    ``panels``: a flat list (``columns`` per row, default all in one row) or a list of rows;
    ``None`` leaves a cell empty (e.g. the basis pyramid). ``title``: a line over the page.
    ``legend``: the green = positive / blue = negative legend (default: when a signed panel
    is present). ``display_width``: pixels per panel image (default: the widest image, at
    least 160 and at most 512); images are scaled to it, nearest-neighbour when enlarged.
    ``shared_colorbar``: the scalar panels share one scale (give each the same ``scale``) and
    one colour bar at the right of the page instead of one each.

    Parameters
    ----------
    panels
        A flat list of panels, or a list of rows; None leaves a cell empty.
    title
        A line over the page.
    columns
        Panels per row of a flat list.
    legend
        Show the green = positive / blue = negative legend (default: when a panel is signed).
    display_width
        Pixels per panel image.
    shared_colorbar
        One colour bar for all scalar panels.

    Returns
    -------
    Figure
        The rendered page with its panels' boxes.
    """
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure as MplFigure
    from matplotlib.patches import Patch

    from .tonemap import tonemap

    if panels and not isinstance(panels[0], Panel | type(None)):
        rows = [list(r) for r in panels]  # type: ignore[arg-type]
    else:
        flat = list(panels)  # type: ignore[arg-type]
        n = max(1, columns or len(flat))
        rows = [flat[i:i + n] for i in range(0, len(flat), n)]
    ncol = max(len(r) for r in rows) if rows else 0
    cells = [(i, j, p) for i, r in enumerate(rows) for j, p in enumerate(r) if p is not None]
    if not cells:
        raise ShprobeError("a figure needs at least one panel")
    data = {id(p): _checked(p) for _, _, p in cells}
    widest = max(data[id(p)][0].shape[1] for _, _, p in cells)
    dw = int(display_width or min(512, max(160, widest)))
    aspect = max(data[id(p)][0].shape[0] / data[id(p)][0].shape[1] for _, _, p in cells)
    dh = max(1, round(dw * aspect))
    has_bar = any(p.kind != "radiance" for _, _, p in cells)
    cell_w = dw + (_CBAR_W if has_bar and not shared_colorbar else 0)
    cell_h = _TITLE_H + dh
    has_legend = any(p.kind == "signed" for _, _, p in cells) if legend is None else legend
    top = _MARGIN + (_HEADER_H if title else 0)
    W = 2 * _MARGIN + ncol * cell_w + (ncol - 1) * _GAP
    W += _CBAR_W if has_bar and shared_colorbar else 0
    H = top + len(rows) * cell_h + (len(rows) - 1) * _GAP + _MARGIN
    H += _LEGEND_H if has_legend else 0
    fig = MplFigure(figsize=(W / _DPI, H / _DPI), dpi=_DPI, facecolor="white")
    FigureCanvasAgg(fig)

    def axes(x0: float, y0: float, w: float, h: float):  # pixel box, y down
        return fig.add_axes((x0 / W, 1 - (y0 + h) / H, w / W, h / H))

    if title:  # on the page: a long title is set smaller rather than cut by the edge
        _fit(fig.text(_MARGIN / W, 1 - (_MARGIN + 2) / H, title, ha="left", va="top",
                      fontsize=_FONT + 1.5, weight="bold"), W - 2 * _MARGIN)
    boxes = []
    shared_drawn = False
    for i, j, p in cells:
        img, kind = data[id(p)]
        x0 = _MARGIN + j * (cell_w + _GAP)
        y0 = top + i * (cell_h + _GAP)
        iy0 = y0 + _TITLE_H
        h_img = round(dw * img.shape[0] / img.shape[1])
        ax = axes(x0, iy0, dw, h_img)
        ax.set_axis_off()
        interp = "nearest" if dw >= img.shape[1] else "antialiased"
        sub = p.units
        bar = None
        if kind == "radiance":
            e = exposure_for(img) if p.exposure is None else float(p.exposure)
            ax.imshow(tonemap(img, e), interpolation=interp, aspect="auto")
            sub = f"{p.units}, " if p.units else ""
            sub += f"exposure {e:+.1f} EV"
        else:
            s = float(np.abs(img).max()) if p.scale is None else float(p.scale)
            s = s if s > 0 else 1.0
            if kind == "signed":
                norm, cmap = Normalize(-s, s), _sign_cmap()
            else:
                norm, cmap = Normalize(0.0, s), matplotlib.colormaps["magma"]
            im = ax.imshow(img, cmap=cmap, norm=norm, interpolation=interp, aspect="auto")
            if shared_colorbar:
                bx, by = W - _MARGIN - _CBAR_W + 8, top + _TITLE_H
                bh = len(rows) * cell_h + (len(rows) - 1) * _GAP - _TITLE_H
            else:
                bx, by, bh = x0 + dw + 8, iy0, h_img
            bar = (bx, by, bx + 10, by + bh)
            if not shared_colorbar or not shared_drawn:
                cax = axes(bx, by, 10, bh)
                cb = fig.colorbar(im, cax=cax)
                cb.ax.tick_params(labelsize=_FONT - 1.5, length=2, pad=1)
                cb.ax.yaxis.get_offset_text().set_fontsize(_FONT - 2)
                if p.units:
                    cb.set_label(p.units, fontsize=_FONT - 1.5, labelpad=2)
                shared_drawn = True
        room = dw + (_CBAR_W - 6 if bar is not None and not shared_colorbar else 0)
        _fit(fig.text((x0 + 1) / W, 1 - (y0 + 2) / H, p.title, ha="left", va="top",
                      fontsize=_FONT + 0.5, weight="bold"), room)
        if sub:
            _fit(fig.text((x0 + 1) / W, 1 - (y0 + 17) / H, sub, ha="left", va="top",
                          fontsize=_FONT - 0.5, color="#333333"), room)
        boxes.append(PanelBox(p.title, kind, (x0, iy0, x0 + dw, iy0 + h_img),
                              (x0, y0, x0 + dw, iy0 - 2), bar))
    if has_legend:
        handles = [Patch(facecolor=(0, 0.8, 0), label="green: positive"),
                   Patch(facecolor=(0, 0, 1), label="blue: negative"),
                   Patch(facecolor=(0, 0, 0), label="black: 0")]
        fig.legend(handles=handles, loc="lower left", ncol=3, frameon=False,
                   fontsize=_FONT, bbox_to_anchor=(_MARGIN / W, 2 / H), borderaxespad=0.2)
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    return Figure(np.ascontiguousarray(rgba[..., :3]), boxes, title, has_legend)


def write_figure(path: str | os.PathLike[str], panels, overwrite: bool = False,
                 **kwargs) -> Figure:
    """[`figure`][shprobe.probes.figures.figure] then
    [`Figure.save`][shprobe.probes.figures.Figure.save]; returns the Figure (``path`` set).

    Parameters
    ----------
    path
        The output PNG.
    panels
        As for [`figure`][shprobe.probes.figures.figure].
    overwrite
        Replace an existing file.
    **kwargs
        The other arguments of [`figure`][shprobe.probes.figures.figure].

    Returns
    -------
    Figure
        The figure, ``path`` set.
    """
    fig = figure(panels, **kwargs)
    fig.save(path, overwrite)
    return fig


__all__ = ["KINDS", "Figure", "Panel", "PanelBox", "clipped_fraction", "exposure_for",
           "figure", "read_panels", "write_figure"]
