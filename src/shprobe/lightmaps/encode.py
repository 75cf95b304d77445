"""From the gathered radiance to the six encodings: bounces, the one SH projection, the
encodings derived from it, dilation over empty texels and the optional denoiser.

Irradiance SH (R&H 2001 eq. 7): Ê_lm = Â_l L_lm with Â = (π, 2π/3, π/4); sh9 and sh4 are
Ê (l ≤ 2, l ≤ 1), h6 = T_h Ê (H&W 2010 §4.1), h4 its first four rows, hl2 the least-squares
projection of Ê on the upper hemisphere onto the Half-Life 2 basis (H&W eq. 1–2), and plain
the cosine-weighted estimate E(N) from the same rays (no band limit).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..hbasis import get_basis, sh_to_h_matrix
from .format import ENCODINGS
from .gather import Gathered, bilinear

__all__ = ["A_HAT", "bounce", "denoise_sh", "dilate", "encodings_from_sh", "project_sh"]

#: R&H 2001 eq. 8–9 for l = 0, 1, 2, per flat SH index
A_HAT = np.array([np.pi] + [2 * np.pi / 3] * 3 + [np.pi / 4] * 5)


def dilate(image: NDArray, valid: NDArray[np.bool_]) -> NDArray:
    """Every invalid texel takes the value of its nearest valid texel (so bilinear filtering
    never reads an empty texel; charts are ≥ 2 texels apart, so a chart's ring of border
    texels is nearest to the chart itself).

    Parameters
    ----------
    image : ndarray (H, W, ...)
        Texel values.
    valid : ndarray (H, W) bool
        Texels holding a value.

    Returns
    -------
    ndarray (H, W, ...)
        The filled image (unchanged if nothing is valid).
    """
    from scipy.ndimage import distance_transform_edt

    if valid.all() or not valid.any():
        return image
    _, (ri, ci) = distance_transform_edt(~valid, return_indices=True)
    return image[ri, ci]


def _tint(weight: NDArray, values: NDArray) -> NDArray:
    """Colour weights (M, 3) times values (M, 3k): channel 3j + c is colour c of set j."""
    m, c = values.shape
    return (values.reshape(m, c // 3, 3) * weight[:, None, :]).reshape(m, c)


def hit_sums_numpy(g: Gathered, image: NDArray, factor: NDArray) -> NDArray:
    """Per texel, Σ over its hits of factor[k] · hit weight (colour) · bilinear(image) at the
    hit's UV: the reference of the numba kernel ``_kernels.hit_sums``.

    Parameters
    ----------
    g : Gathered
        The hits.
    image : ndarray (H, W, C)
        The previous bounce's lightmap (C = 3·k channels).
    factor : ndarray (M, K)
        Per hit, the K direction factors (cos θ, or the 9 SH values).

    Returns
    -------
    ndarray (P, K, C)
        The sums.
    """
    lr = _tint(g.hit_weight, bilinear(image, g.hit_uv))
    out = np.zeros((len(g.direct_e), factor.shape[1], image.shape[2]))
    for k in range(factor.shape[1]):
        out[:, k] = _segment_sum(g.hit_texel, lr * factor[:, k:k + 1], len(out))
    return out


def hit_sums(g: Gathered, image: NDArray, factor: NDArray) -> NDArray:
    """`hit_sums_numpy` by the numba kernel (one pass over the hits).

    Parameters
    ----------
    g : Gathered
        The hits.
    image : ndarray (H, W, C)
        The previous bounce's lightmap.
    factor : ndarray (M, K)
        Per hit, the direction factors.

    Returns
    -------
    ndarray (P, K, C)
        The sums.
    """
    from ._kernels import hit_sums as kernel

    out = np.zeros((len(g.direct_e), factor.shape[1], image.shape[2]))
    if len(g.hit_texel):
        kernel(g.hit_texel, g.hit_uv, g.hit_weight, np.ascontiguousarray(factor),
               np.ascontiguousarray(image, dtype=np.float64), out)
    return out


def _segment_sum(index: NDArray, values: NDArray, n: int) -> NDArray:
    """Σ of the rows of ``values`` (M, C) per ``index`` (M,) → (n, C)."""
    return np.stack([np.bincount(index, values[:, c], minlength=n)
                     for c in range(values.shape[1])], 1)


def _image(values: NDArray, rc: NDArray, valid: NDArray, shape: tuple[int, int]) -> NDArray:
    img = np.zeros((*shape, *values.shape[1:]))
    mask = np.zeros(shape, bool)
    img[rc[valid, 0], rc[valid, 1]] = values[valid]
    mask[rc[valid, 0], rc[valid, 1]] = True
    return dilate(img, mask)


def bounce(g: Gathered, rc: NDArray, shape: tuple[int, int], bounces: int
           ) -> tuple[NDArray, NDArray]:
    """Plain irradiance with ``bounces`` diffuse bounces, and the map the final gather reads.

    Parameters
    ----------
    g : Gathered
        The gather pass.
    rc : ndarray (P, 2)
        Texel rows and columns.
    shape : (int, int)
        Lightmap (H, W).
    bounces : int
        Diffuse bounces.

    Returns
    -------
    tuple of ndarray
        E_B (P, 3) and the dilated map E_{B−1} (H, W, 3) (None-like zeros for 0 bounces).
    """
    e = g.direct_e.copy()
    prev = np.zeros((*shape, e.shape[1]))
    for _ in range(bounces):
        prev = _image(e, rc, g.valid, shape)
        e = g.direct_e + hit_sums(g, prev, g.hit_dir[:, 2:3])[:, 0]
    return e, prev


def project_sh(g: Gathered, prev: NDArray, bounces: int) -> NDArray[np.float64]:
    """Radiance SH (P, 9, 3) in the tangent frames: direct terms plus the last bounce.

    Parameters
    ----------
    g : Gathered
        The gather pass.
    prev : ndarray (H, W, 3)
        The plain lightmap of the bounce before the last.
    bounces : int
        Diffuse bounces (0: no light from the scene).

    Returns
    -------
    ndarray (P, 9, 3)
        L_lm.
    """
    out = g.direct_sh.copy()
    if bounces > 0 and len(g.hit_texel):
        # hit_sums(g, prev, sh_basis(g.hit_dir, 2)) with the SH made per hit in the kernel
        from ._kernels import hit_sums_sh

        hit_sums_sh(g.hit_texel, g.hit_uv, g.hit_weight, g.hit_dir,
                    np.ascontiguousarray(prev, dtype=np.float64), out)
    return out


def encodings_from_sh(radiance_sh: NDArray, plain: NDArray) -> dict[str, NDArray]:
    """All six encodings (..., n, 3) from radiance SH (..., 9, 3) and plain E (..., 3).

    Parameters
    ----------
    radiance_sh : ndarray (..., 9, 3)
        Tangent-frame radiance SH.
    plain : ndarray (..., 3)
        Cosine-weighted irradiance at the normal.

    Returns
    -------
    dict
        Encoding name → coefficients.
    """
    e_sh = radiance_sh * A_HAT[:, None]
    h6 = np.matmul(sh_to_h_matrix(2, 6), e_sh)  # (6, 9) @ (..., 9, 3)
    hl2 = np.matmul(get_basis("HL2").sh_matrix(2), e_sh)
    out = {"plain": plain[..., None, :], "hl2": hl2, "sh4": e_sh[..., :4, :], "sh9": e_sh,
           "h4": h6[..., :4, :], "h6": h6}
    return {k: np.ascontiguousarray(out[k]) for k in ENCODINGS}


def denoise_sh(sh_img: NDArray, plain_img: NDArray) -> tuple[NDArray, NDArray]:
    """Intel Open Image Denoise (RTLightmap) over irradiance-SH and plain maps.

    The l = 0 band and the plain map are HDR images; the higher bands are divided by the l = 0
    band and denoised in the filter's directional mode (values in [−1, 1]), as OIDN documents
    for directional lightmaps, then multiplied back.

    Parameters
    ----------
    sh_img : ndarray (H, W, 9, 3)
        Radiance SH images.
    plain_img : ndarray (H, W, 3)
        Plain irradiance image.

    Returns
    -------
    tuple of ndarray
        The denoised SH and plain images.
    """
    import pyoidn

    def run(img: NDArray, directional: bool) -> NDArray:
        dev = pyoidn.Device(pyoidn.OIDN_DEVICE_TYPE_CPU)
        dev.commit()
        src = np.ascontiguousarray(img, dtype=np.float32)
        out = np.empty_like(src)
        flt = pyoidn.Filter(dev, pyoidn.OIDN_FILTER_TYPE_RT_LIGHTMAP)
        flt.set_image(pyoidn.OIDN_IMAGE_COLOR, src, pyoidn.OIDN_FORMAT_FLOAT3)
        flt.set_image(pyoidn.OIDN_IMAGE_OUTPUT, out, pyoidn.OIDN_FORMAT_FLOAT3)
        if directional:
            flt.set_bool("directional", True)
        flt.commit()
        flt.execute()
        flt.release()
        dev.release()
        return out.astype(np.float64)

    dc = np.maximum(sh_img[:, :, 0], 0.0)
    dc_d = np.maximum(run(dc, False), 0.0)
    out = np.empty_like(sh_img)
    out[:, :, 0] = dc_d
    safe = np.where(dc > 1e-12, dc, 1.0)
    # |L_1m| ≤ √3 L_00 and |L_2m| ≤ √5 L_00 for a non-negative signal: normalise into [−1, 1]
    for k in range(1, 9):
        bound = np.sqrt(3.0) if k < 4 else np.sqrt(5.0)
        ratio = np.clip(sh_img[:, :, k] / safe / bound, -1.0, 1.0)
        out[:, :, k] = run(ratio, True) * bound * dc_d
    plain = np.maximum(run(np.maximum(plain_img, 0.0), False), 0.0)
    return out, plain
