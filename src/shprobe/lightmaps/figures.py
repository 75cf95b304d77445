"""Pictures of a baked lightmap, as Habel & Wimmer 2010 show theirs: Fig. 1 (plain lightmap ·
H6 without albedo · H6 with albedo), Fig. 5 (H4 beside H6) and an error-per-encoding heat map.

The scene of the .glb is ray-cast (Embree primary rays,
[`shprobe.scene.raycast.RayCaster`][shprobe.scene.RayCaster]) from one pinhole camera; at every
pixel the surface point's TEXCOORD_0 gives the normal map's tangent-space normal n and the base
colour, its TEXCOORD_1 the lightmap's coefficients (read bilinearly, as a GPU samples them), and
E(n) = Σ cᵢ Bᵢ(n) (H&W eq. 15) is what a shader computes (`shprobe.lightmaps.shaders`). Every panel
of a figure has one exposure, chosen so that none clips: pixel = (albedo or 1) · E / π · 2^exposure,
sRGB.

The encodings shown are those the stored one implies (`shprobe.lightmaps.derive`; bake with
``--basis sh9`` to have all six). The error map compares each with the richest of them (L2 SH
where stored, else the stored encoding): |E − E_ref| / mean E_ref per pixel, mean and 95th
percentile in each panel's title (H&W §5's study on the scene's own pixels).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from . import format as fmt
from .derive import implied_encodings

__all__ = ["FigureSettings", "LightmapFigures", "Shading", "lightmap_figures", "shade_view"]

#: the reference order of the error map: the first the file implies is the reference
REFERENCE_ORDER = ("sh9", "h6", "h4", "sh4", "hl2", "plain")
LABELS = {"plain": "plain lightmap", "hl2": "HL2", "sh4": "L1 SH (4)", "sh9": "L2 SH (9)",
          "h4": "H4", "h6": "H6"}
_BACKGROUND = 0.12


@dataclass(frozen=True)
class FigureSettings:
    """Settings of `lightmap_figures`.

    Parameters
    ----------
    width, height : int
        Pixels of one panel.
    eye, target : tuple of 3 floats, optional
        The camera (world frame); default a view across the scene's bounds.
    fov : float
        Vertical field of view, degrees.
    dpi : int
        Resolution of the PNGs.
    """

    width: int = 480
    height: int = 320
    eye: tuple[float, float, float] | None = None
    target: tuple[float, float, float] | None = None
    fov: float = 60.0
    dpi: int = 100

    def __post_init__(self) -> None:
        if not (16 <= int(self.width) <= 4096 and 16 <= int(self.height) <= 4096):
            raise ShprobeError(f"figure panels must be 16..4096 pixels, got "
                               f"{self.width}x{self.height}")
        if not 1.0 <= float(self.fov) <= 150.0:
            raise ShprobeError(f"field of view must be in [1, 150] degrees, got {self.fov}")
        for name in ("eye", "target"):
            v = getattr(self, name)
            if v is not None and (len(v) != 3 or not np.all(np.isfinite(np.asarray(v, float)))):
                raise ShprobeError(f"camera {name} must be three finite numbers, got {v}")


@dataclass(eq=False)
class Shading:
    """What the camera sees, per pixel (flat, row-major, ``height × width``).

    Parameters
    ----------
    hit : ndarray (P,) bool
        The ray hit a lightmapped surface.
    normal : ndarray (P, 3)
        Tangent-space normal-map normal (0, 0, 1 where there is no normal map).
    albedo : ndarray (P, 3)
        Linear base colour (factor × texture).
    irradiance : dict
        Encoding → E (P, 3) at the normal (plain: at 0, 0, 1).
    width, height : int
        Image size.
    """

    hit: NDArray[np.bool_]
    normal: NDArray[np.float64] = field(repr=False)
    albedo: NDArray[np.float64] = field(repr=False)
    irradiance: dict[str, NDArray[np.float64]] = field(repr=False)
    width: int
    height: int

    def image(self, values: NDArray) -> NDArray[np.float64]:
        """Per-pixel ``values`` (P, C) as an (H, W, C) image, background where nothing hit."""
        out = np.full((self.width * self.height, values.shape[-1]), _BACKGROUND)
        out[self.hit] = values[self.hit]
        return out.reshape(self.height, self.width, -1)


@dataclass
class LightmapFigures:
    """The pictures written and what they show.

    Parameters
    ----------
    paths : dict
        Figure name → PNG path.
    encoding : str
        The stored encoding.
    reference : str
        The error map's reference encoding.
    exposure : float
        Stops, the one exposure of Fig. 1 and Fig. 5.
    errors : dict
        Encoding → {"mean": ..., "p95": ...} relative error against the reference.
    """

    paths: dict[str, str]
    encoding: str
    reference: str
    exposure: float
    errors: dict[str, dict[str, float]]

    def as_dict(self) -> dict[str, Any]:
        """A JSON-able summary.

        Returns
        -------
        dict
            The fields.
        """
        return {"paths": dict(self.paths), "encoding": self.encoding,
                "reference": self.reference, "exposure": self.exposure,
                "errors": {k: dict(v) for k, v in self.errors.items()}}


def _repeat(tex: NDArray, uv: NDArray) -> NDArray:
    from .gather import _srgb_free  # the bake's REPEAT-wrapped bilinear lookup

    return _srgb_free(tex, uv)


def _camera_rays(settings: FigureSettings, lo: NDArray, hi: NDArray
                 ) -> tuple[NDArray, NDArray]:
    size, diag = hi - lo, float(np.linalg.norm(hi - lo))
    eye = (np.asarray(settings.eye, float) if settings.eye is not None else
           lo + np.array([0.15 * size[0], 0.3 * size[1] + 0.08 * diag, 0.1 * size[2]]))
    target = (np.asarray(settings.target, float) if settings.target is not None else
              lo + np.array([0.55 * size[0], 0.25 * size[1], 0.6 * size[2]]))
    fwd = target - eye
    if np.linalg.norm(fwd) == 0:
        raise ShprobeError("camera eye and target are the same point")
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 1.0, 0.0])
    if np.linalg.norm(right) < 1e-6:
        right = np.array([1.0, 0.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    w, h = int(settings.width), int(settings.height)
    t = math.tan(math.radians(settings.fov) / 2)
    xs = ((np.arange(w) + 0.5) / w * 2 - 1) * t * w / h
    ys = (1 - (np.arange(h) + 0.5) / h * 2) * t
    d = fwd + xs[None, :, None] * right + ys[:, None, None] * up
    d = d.reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.broadcast_to(eye, d.shape), d


def shade_view(path: str | os.PathLike[str], settings: FigureSettings | None = None
               ) -> tuple[Shading, fmt.StoredLightmap]:
    """Ray-cast a lightmap .glb from the settings' camera and evaluate every implied
    encoding at every pixel.

    Parameters
    ----------
    path : str or PathLike
        A ``shprobe lightmap bake`` output.
    settings : FigureSettings, optional
        Camera and size.

    Returns
    -------
    tuple of (Shading, StoredLightmap)
        Per-pixel normals, albedo and E per encoding; the file's lightmap.
    """
    from ..scene.raycast import RayCaster
    from .atlas import Atlas
    from .gather import bilinear, sample_albedo
    from .scene import load_scene

    s = settings or FigureSettings()
    p = os.fspath(path)
    doc, binary = fmt.read_glb(p)
    stored = fmt.read_lightmap(doc, binary, p)
    scene = load_scene(p)
    prims = [q for q in scene.primitives if q.uv1 is not None]
    if not prims:
        raise ShprobeError("no primitive has TEXCOORD_1: not a baked lightmap", p)
    offs = np.cumsum([0] + [len(q.positions) for q in prims])
    v = np.concatenate([q.positions for q in prims])
    f = np.concatenate([q.faces + o for q, o in zip(prims, offs[:-1], strict=True)])
    fprim = np.concatenate([np.full(len(q.faces), i) for i, q in enumerate(prims)])
    fbase = np.concatenate([[0], np.cumsum([len(q.faces) for q in prims])])
    origins, dirs = _camera_rays(s, v.min(0), v.max(0))
    face, bu, bv = RayCaster(v, f).first_hit(origins, dirs)
    hit = face >= 0
    n_px = len(face)
    fi = face[hit].astype(np.int64)
    bary = np.stack([1 - bu[hit] - bv[hit], bu[hit], bv[hit]], 1).astype(np.float64)
    pi = fprim[fi]
    local = fi - fbase[pi]
    uv1 = np.zeros((len(fi), 2))
    nrm = np.tile([0.0, 0.0, 1.0], (len(fi), 1))
    for i, q in enumerate(prims):
        sel = np.flatnonzero(pi == i)
        tri = q.faces[local[sel]]
        uv1[sel] = (q.uv1[tri] * bary[sel][:, :, None]).sum(1)
        if q.normal_texture is not None and q.uv0 is not None:
            uv0 = (q.uv0[tri] * bary[sel][:, :, None]).sum(1)
            t = _repeat(q.normal_texture, uv0) * 2 - 1
            t[:, :2] *= q.normal_scale
            nrm[sel] = t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
    atlas = Atlas(prims, [None] * len(prims), stored.coeffs.shape[1], stored.coeffs.shape[0],
                  False)
    alb = sample_albedo(atlas, pi, local, bary, None)
    encs = implied_encodings(stored.encoding, stored.coeffs)
    irr = {}
    for e, c in encs.items():
        k = bilinear(c.reshape(*c.shape[:2], -1), uv1).reshape(len(fi), -1, 3)
        n = nrm if e != "plain" else np.array([0.0, 0.0, 1.0])
        out = np.zeros((n_px, 3))
        out[hit] = fmt.evaluate(e, k, n)
        irr[e] = out
    full = np.zeros((n_px, 3))
    full_n, full_a = full.copy(), full.copy()
    full_n[hit], full_a[hit] = nrm, alb
    return Shading(hit, full_n, full_a, irr, int(s.width), int(s.height)), stored


def _srgb(v: NDArray) -> NDArray:
    v = np.clip(v, 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)


def _exposure(values: list[NDArray]) -> float:
    """Stops that put the largest displayed value of all panels at 0.98 (nothing clips)."""
    peak = max(float(np.max(v, initial=0.0)) for v in values)
    return math.log2(0.98 / peak) if peak > 0 else 0.0


def _save(fig: Any, path: Path) -> str:
    from ..files import atomic_output

    with atomic_output(path, True) as tmp:
        fig.savefig(tmp, format="png", dpi=fig.dpi)
    return str(path)


def _panels(sh: Shading, panels: list[tuple[str, NDArray]], title: str, path: Path,
            dpi: int) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(panels)
    w, h = sh.width / dpi, sh.height / dpi
    fig, axes = plt.subplots(1, n, figsize=(w * n, h + 0.75), dpi=dpi, squeeze=False)
    for ax, (label, img) in zip(axes[0], panels, strict=True):
        ax.imshow(img, interpolation="nearest")
        ax.set_title(label, fontsize=10)
        ax.set_axis_off()
    fig.suptitle(title, fontsize=9)
    fig.subplots_adjust(left=0.005, right=0.995, bottom=0.01, top=1 - 0.7 / (h + 0.75),
                        wspace=0.02)
    out = _save(fig, path)
    plt.close(fig)
    return out


def lightmap_figures(path: str | os.PathLike[str], out_dir: str | os.PathLike[str],
                     settings: FigureSettings | None = None,
                     progress: Any = None) -> LightmapFigures:
    """Write Fig. 1, Fig. 5 and the error heat map of a lightmap .glb into ``out_dir``.

    Parameters
    ----------
    path : str or PathLike
        A ``shprobe lightmap bake`` output.
    out_dir : str or PathLike
        Folder for ``fig1.png``, ``fig5.png`` and ``errors.png`` (created if missing; the
        files are replaced).
    settings : FigureSettings, optional
        Camera and panel size.
    progress : Progress, optional
        Reporter of the four stages (shprobe.progress).

    Returns
    -------
    LightmapFigures
        The paths, the exposure and the error table.
    """
    from ..progress import Steps

    s = settings or FigureSettings()
    d = Path(out_dir)
    with Steps(progress, 4) as step:
        step("ray casting and shading")
        sh, stored = shade_view(path, s)
        d.mkdir(parents=True, exist_ok=True)
        return _figures(sh, stored, os.path.basename(os.fspath(path)), d, s, step)


def _figures(sh: Shading, stored: fmt.StoredLightmap, name: str, d: Path, s: FigureSettings,
             step: Any) -> LightmapFigures:
    E = sh.irradiance
    paths: dict[str, str] = {}
    plain, h6 = E["plain"], E.get("h6", E[stored.encoding])
    h6_name = "h6" if "h6" in E else stored.encoding
    shown = [plain / math.pi, h6 / math.pi, sh.albedo * h6 / math.pi]
    if "h4" in E:
        shown += [E["h4"] / math.pi]
    stops = _exposure([v[sh.hit] for v in shown])
    k = 2.0 ** stops

    def img(v: NDArray) -> NDArray:
        return _srgb(sh.image(v * k))

    foot = (f"{name}: stored {LABELS[stored.encoding]}; pixel = (albedo or 1) · E / π · "
            f"2^{stops:.2f}, sRGB, one exposure for all panels (none clips)")
    step("Fig. 1")
    paths["fig1"] = _panels(sh, [("plain lightmap (normal map ignored)", img(shown[0])),
                                 (f"{LABELS[h6_name]}, without albedo", img(shown[1])),
                                 (f"{LABELS[h6_name]}, with albedo", img(shown[2]))],
                            "Fig. 1 (Habel & Wimmer 2010): " + foot, d / "fig1.png", s.dpi)
    if "h4" in E and "h6" in E:
        step("Fig. 5")
        diff = np.abs(E["h6"] - E["h4"]) / math.pi * k
        gain = 2.0 ** math.floor(math.log2(0.98 / max(float(diff[sh.hit].max(initial=0)),
                                                      1e-30)))
        gain = min(gain, 2.0 ** 10)
        paths["fig5"] = _panels(
            sh, [("H4, without albedo", img(E["h4"] / math.pi)),
                 ("H6, without albedo", img(E["h6"] / math.pi)),
                 (f"|H6 − H4| × {gain:g}", _srgb(sh.image(diff * gain)))],
            "Fig. 5 (Habel & Wimmer 2010): " + foot, d / "fig5.png", s.dpi)
    step("error map")
    ref = next(e for e in REFERENCE_ORDER if e in E)
    errors, maps = _errors(sh, ref)
    paths["errors"] = _error_figure(sh, ref, errors, maps, name, d / "errors.png", s.dpi)
    return LightmapFigures(paths, stored.encoding, ref, stops, errors)


def _errors(sh: Shading, ref: str) -> tuple[dict[str, dict[str, float]], dict[str, NDArray]]:
    """Per encoding: relative error |E − E_ref| (luminance) / mean E_ref, per pixel."""
    lum = np.array([0.2126, 0.7152, 0.0722])
    r = sh.irradiance[ref][sh.hit] @ lum
    scale = max(float(np.mean(np.abs(r))), 1e-30)
    errors, maps = {}, {}
    for e in fmt.ENCODINGS:
        if e == ref or e not in sh.irradiance:
            continue
        err = np.abs(sh.irradiance[e][sh.hit] @ lum - r) / scale
        full = np.full(sh.width * sh.height, np.nan)
        full[sh.hit] = err
        maps[e] = full.reshape(sh.height, sh.width)
        errors[e] = {"mean": float(err.mean()), "p95": float(np.percentile(err, 95))}
    return errors, maps


def _error_figure(sh: Shading, ref: str, errors: dict, maps: dict, name: str, path: Path,
                  dpi: int) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = max(len(maps), 1)
    cols = min(n, 3)
    rows = -(-n // cols)
    w, h = sh.width / dpi, sh.height / dpi
    fig, axes = plt.subplots(rows, cols, figsize=(w * cols + 1.0, (h + 0.35) * rows + 0.6),
                             dpi=dpi, squeeze=False, layout="constrained")
    vals = [m[np.isfinite(m)] for m in maps.values()]
    vmax = max([float(np.percentile(v, 99)) for v in vals if v.size] + [1e-6])
    cmap = plt.get_cmap("inferno").with_extremes(bad=(0.25, 0.25, 0.25))
    im = None
    for ax in axes.ravel():
        ax.set_axis_off()
    for ax, (e, m) in zip(axes.ravel(), maps.items(), strict=False):
        im = ax.imshow(100 * m, cmap=cmap, vmin=0, vmax=100 * vmax, interpolation="nearest")
        ax.set_title(f"{LABELS[e]}: mean {100 * errors[e]['mean']:.2f} %, "
                     f"p95 {100 * errors[e]['p95']:.2f} %", fontsize=9)
    if im is not None:
        cb = fig.colorbar(im, ax=axes.ravel().tolist(), fraction=0.03, pad=0.01, shrink=0.9)
        cb.set_label("|E − E_ref| / mean E_ref (luminance), %")
    fig.suptitle(f"{name}: error per encoding against {LABELS[ref]} (the richest encoding "
                 "the file implies), at the normal-map normals; grey = background",
                 fontsize=9)
    out = _save(fig, path)
    plt.close(fig)
    return out
