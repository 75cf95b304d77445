"""What a fit writes: the coefficient document with the fit's quality, the per-pixel images
(fitted irradiance, fitted radiance, residual, rejected mask) and one labelled PNG panel."""

from __future__ import annotations

import os

import numpy as np
from numpy.typing import NDArray

from ..lighting.coeffs import RH_LABELS
from ..lighting.irradiance import irradiance
from .ball import BallFit
from .document import fit_document
from .objects import ObjectFit
from .solve import POOR_CONDITION

__all__ = ["fit_document", "fit_images", "fit_table_rows", "save_fit_figure"]

Result = BallFit | ObjectFit


def fit_table_rows(result: Result) -> list[tuple[str, list[float], list[float], float, bool]]:
    """(label, L_lm RGB, standard error RGB, conditioning, poorly determined) per coefficient."""
    f = result.fit
    return [(RH_LABELS[k], f.coeffs[k].tolist(), f.stderr[k].tolist(),
             float(f.conditioning[k]), bool(f.conditioning[k] > POOR_CONDITION))
            for k in range(9)]


def fit_images(result: Result, view: int = 0) -> dict[str, NDArray[np.float32]]:
    """Full-size (H, W, 3) images: ``fitted`` (the model's radiance, the photo's units),
    ``residual`` (photo − fitted), ``rejected`` (1 where clipped or rejected, grey), and for
    diffuse fits ``irradiance`` (E(n) of the fitted coefficients, W m⁻² sr⁰ units of L)."""
    f = result.fit
    out = {"fitted": result.image(f.fitted, view) if isinstance(result, ObjectFit)
           else result.image(f.fitted),
           "residual": result.image(f.residual, view) if isinstance(result, ObjectFit)
           else result.image(f.residual)}
    rej = np.repeat(f.rejected.astype(np.float32)[:, None], 3, axis=1)
    out["rejected"] = result.image(rej, view) if isinstance(result, ObjectFit) \
        else result.image(rej)
    if f.model == "diffuse":
        n = result.pixels.normals if isinstance(result, BallFit) else result.normals
        e = irradiance(f.coeffs, n).astype(np.float32)
        out["irradiance"] = result.image(e, view) if isinstance(result, ObjectFit) \
            else result.image(e)
    return out


def _crop(result: Result, view: int) -> tuple[slice, slice]:
    if isinstance(result, BallFit):
        c, (H, W) = result.circle, result.pixels.shape
        m = 0.08 * c.r
        return (slice(max(int(c.cy - c.r - m), 0), min(int(c.cy + c.r + m) + 1, H)),
                slice(max(int(c.cx - c.r - m), 0), min(int(c.cx + c.r + m) + 1, W)))
    rows, cols = result.views[view]
    H, W = result.shapes[view]
    m = 4
    return (slice(max(int(rows.min()) - m, 0), min(int(rows.max()) + m + 1, H)),
            slice(max(int(cols.min()) - m, 0), min(int(cols.max()) + m + 1, W)))


def save_fit_figure(path: str | os.PathLike[str], photo: NDArray, result: Result,
                    title: str, overwrite: bool = False, view: int = 0) -> None:
    """A labelled PNG, cropped to the object: the photo and the fitted radiance (same
    exposure: the photo's 99.5th percentile at 0.8), for diffuse fits the fitted irradiance
    E(n) (luminance, colour bar), the residual (signed, colour bar in the photo's units) and
    the rejected / clipped mask; the summary line below."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..files import atomic_output
    from ..probes.tonemap import tonemap

    if getattr(result, "photo", None) is not None:  # a block-averaged fit: its own photo
        photo = result.photo
    ims = fit_images(result, view)
    sy, sx = _crop(result, view)
    ph = np.asarray(photo, np.float32)[sy, sx, :3]
    fitted = ims["fitted"][sy, sx]
    peak = float(np.percentile(ph, 99.5)) / 0.8 if ph.size else 1.0
    exposure = -np.log2(peak) if peak > 0 else 0.0  # the 99.5th percentile at 0.8
    res = ims["residual"][sy, sx].mean(axis=-1)
    lim = float(np.percentile(np.abs(res), 99.5)) or 1e-12
    rej = ims["rejected"][sy, sx, 0]
    obj = np.zeros_like(rej)
    if isinstance(result, BallFit):
        obj[result.pixels.rows - sy.start, result.pixels.cols - sx.start] = 1
    else:
        rows, cols = result.views[view]
        obj[rows - sy.start, cols - sx.start] = 1
    mask_rgb = np.stack([np.where(rej > 0, 0.9, 0.15 * obj),
                         np.where(rej > 0, 0.15, 0.55 * obj),
                         np.where(rej > 0, 0.1, 0.25 * obj)], -1)
    ext = (sx.start, sx.stop, sy.stop, sy.start)  # image pixel coordinates
    diffuse = "irradiance" in ims
    fig, axs = plt.subplots(1, 5 if diffuse else 4, figsize=(19 if diffuse else 15, 4.6),
                            constrained_layout=True)
    axs = list(axs)
    axs[0].imshow(tonemap(ph, exposure), extent=ext)
    axs[0].set_title(f"photo (exposure {exposure:+.2f} stops)")
    axs[1].imshow(tonemap(fitted, exposure), extent=ext)
    axs[1].set_title("fitted radiance (same exposure)")
    if diffuse:
        e = ims["irradiance"][sy, sx] @ np.array([0.2126, 0.7152, 0.0722], np.float32)
        e = np.ma.masked_where(obj == 0, e)
        im = axs[2].imshow(e, cmap="magma", extent=ext)
        axs[2].set_title("fitted irradiance E(n), luminance")
        fig.colorbar(im, ax=axs[2], shrink=0.8, label="E (units of L_lm)")
        axs.pop(2)
    im = axs[2].imshow(res, cmap="RdBu_r", vmin=-lim, vmax=lim, extent=ext)
    axs[2].set_title("residual photo − fit (RGB mean)")
    fig.colorbar(im, ax=axs[2], shrink=0.8, label="radiance (photo units)")
    axs[3].imshow(mask_rgb, extent=ext)
    axs[3].set_title(f"rejected {100 * result.fit.rejected_fraction:.2f} % (red) / used")
    for a in fig.axes:
        if a.get_label() != "<colorbar>":
            a.set_xlabel("x (px)")
            a.set_ylabel("y (px)")
    fig.suptitle(title)
    fig.text(0.5, 0.01, result.summary(), ha="center", fontsize=8, wrap=True)
    with atomic_output(path, overwrite) as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)
