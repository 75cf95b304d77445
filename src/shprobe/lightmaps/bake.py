"""The lightmap bake: ``bake_lightmap(scene, lighting, settings) -> Lightmap`` (H&W 2010 §4.2–4.3,
directional irradiance at the texels of a second UV set, in the normal map's tangent frame)."""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..limits import Cost, check_memory, cores
from ..progress import Progress, stage
from .atlas import Atlas, build_atlas, texels
from .checks import check_scene, sky_coeffs
from .encode import bounce, denoise_sh, dilate, encodings_from_sh, project_sh
from .format import ENCODINGS, N_COEFFS
from .gather import BYTES_PER_HIT, RAYS_PER_BATCH, gather
from .result import Lightmap
from .scene import LightmapScene, load_scene
from .settings import LightmapSettings

__all__ = ["bake_lightmap", "estimate_lightmap_bake"]

#: rays per second and core the gather reaches (Embree + the NumPy bookkeeping), cautious
RAYS_PER_CORE_SECOND = 1.5e6


def estimate_lightmap_bake(n_texels: int, settings: LightmapSettings) -> Cost:
    """Time and peak memory of a bake of ``n_texels`` covered texels, before any work.

    Parameters
    ----------
    n_texels : int
        Covered texels (the atlas size is a bound: W × H).
    settings : LightmapSettings
        Samples, bounces.

    Returns
    -------
    Cost
        Seconds on this machine and bytes.
    """
    rays = float(n_texels) * settings.samples
    size = (settings.size if settings.texels_per_unit is None else np.sqrt(n_texels)) ** 2
    extra = 10 if settings.transfer else 1  # the transfer's 27 more channels
    nbytes = (rays * (2 * BYTES_PER_HIT + 60 * extra)  # the hits (twice while joined), SH
              + n_texels * (9 * 3 * 8 * 3 + 64 * 3)  # SH, frames, points
              + size * (sum(N_COEFFS.values()) * 3 * 4 + 9 * 3 * 8 * 3) * extra  # images
              + min(rays, RAYS_PER_BATCH) * 400)  # one batch of rays in flight
    # measured (bench/bench_lightmap.py, tracemalloc): 376 MB for 37,498 texels × 64 rays
    seconds = rays * (1 + 0.3 * settings.bounces) / (RAYS_PER_CORE_SECOND * min(cores(), 2))
    return Cost(float(seconds), float(nbytes))


def _rel_rms(a: NDArray, b: NDArray, ref: NDArray) -> float:
    scale = float(np.abs(ref).mean()) or 1.0
    return float(np.sqrt(np.mean((a - b) ** 2)) / scale) if a.size else 0.0


def bake_lightmap(scene: LightmapScene | str | os.PathLike[str], lighting: Any,
                  settings: LightmapSettings | None = None,
                  progress: Progress | None = None, scheduler: str | None = None) -> Lightmap:
    """Bake a scene's directional lightmap (H&W 2010 §4.2–4.3) in all six encodings.

    Parameters
    ----------
    scene : LightmapScene or path
        The scene (a .glb / .gltf / .obj path is read with
        [`load_scene`][shprobe.lightmaps.load_scene]).
    lighting : Lighting or array_like (K ≥ 9, 3)
        The distant environment's radiance SH (cut to lmax 2), e.g. from
        ``shprobe.lighting.resolve_lighting``.
    settings : LightmapSettings, optional
        Basis, size, samples, bounces, sun, denoise.
    progress : Progress, optional
        Reporter.
    scheduler : str, optional
        A Dask scheduler (tcp://host:port) to trace the tiles of texels on; the result equals
        the local bake's.

    Returns
    -------
    Lightmap
        All six encodings' coefficient images, the atlas and the bake's figures.
    """
    settings = settings or LightmapSettings()
    t0 = time.perf_counter()
    if not isinstance(scene, LightmapScene):
        scene = load_scene(scene)
    check_scene(scene)
    sky = sky_coeffs(lighting)
    if settings.texels_per_unit is None:  # the size bounds the texels: refuse before any work
        bound = estimate_lightmap_bake(settings.size**2, settings)
        check_memory(bound.nbytes, f"a {settings.size}x{settings.size} lightmap bake with "
                     f"{settings.samples} samples", scene.path)
    with stage(progress, "lightmap UVs and texels"):
        atlas = build_atlas(scene, settings)
        tx = texels(atlas)
    if tx.count == 0:
        raise ShprobeError("no texel of the lightmap is covered: raise --size", scene.path)
    if tx.count > settings.max_texels:
        raise ShprobeError(f"{tx.count} texels is over the limit of {settings.max_texels}: "
                           "lower --size or --texels-per-unit", scene.path)
    cost = estimate_lightmap_bake(tx.count, settings)
    check_memory(cost.nbytes, f"a {atlas.width}x{atlas.height} lightmap bake with "
                 f"{settings.samples} samples", scene.path)
    from ..scene.raycast import RayCaster

    caster = RayCaster(np.concatenate([p.positions for p in atlas.primitives]),
                       np.concatenate(_global_faces(atlas)))
    if settings.transfer:  # one more set of channels per sky coefficient (PRT, LH §4)
        sky = np.concatenate([sky, np.kron(np.eye(9), np.ones((1, 3)))], axis=1)
    if scheduler:
        from .tiles import gather_on_dask

        g = gather_on_dask(atlas, tx, sky, settings, scheduler, progress)
    else:
        g = gather(atlas, tx, sky, settings, caster, progress)
    shape = (atlas.height, atlas.width)
    with stage(progress, f"{settings.bounces} bounces and the SH projection"):
        plain, prev = bounce(g, tx.rc, shape, settings.bounces)
        lsh = project_sh(g, prev, settings.bounces)
        valid = np.zeros(shape, bool)
        valid[tx.rc[g.valid, 0], tx.rc[g.valid, 1]] = True
        sh_img = _to_image(lsh, tx.rc, g.valid, shape)
        plain_img = _to_image(plain, tx.rc, g.valid, shape)
        transfer = _transfer(sh_img, plain_img) if settings.transfer else None
        sh_img, plain_img = sh_img[..., :3], plain_img[..., :3]
    stats: dict[str, Any] = {
        "texels_baked": int(tx.count), "texels_invalid": int((~g.valid).sum()),
        "samples": settings.samples, "bounces": settings.bounces,
        "rays": tx.count * settings.samples,
        "atlas": "xatlas" if atlas.made else "TEXCOORD_1", "uv_overlap": atlas.overlap,
        "noise_rel_rms": _rel_rms(g.half_e[0][g.valid, :3], g.half_e[1][g.valid, :3],
                                  g.direct_e[g.valid, :3]) / 2,
        "estimate_seconds": cost.seconds, "estimate_bytes": cost.nbytes}
    if settings.transfer:  # the sky the transfer was baked under, for viewers that turn it
        stats["sky"] = sky[:, :3].tolist()
    if settings.denoise:
        with stage(progress, "denoising (Open Image Denoise, RTLightmap)"):
            sh_d, plain_d = denoise_sh(sh_img, plain_img)
            sh_d, plain_d = dilate(sh_d, valid), dilate(plain_d, valid)
        stats["denoise_change_rel_rms"] = _rel_rms(plain_d[valid], plain_img[valid],
                                                   plain_img[valid])
        stats["noisy"] = {k: v.astype(np.float32) for k, v in
                          encodings_from_sh(sh_img, plain_img).items()}
        sh_img, plain_img = sh_d, plain_d
    enc = {k: v.astype(np.float32) for k, v in encodings_from_sh(sh_img, plain_img).items()}
    stats["seconds"] = time.perf_counter() - t0
    noisy = stats.pop("noisy", None)
    return Lightmap(enc, settings.basis, valid, stats, atlas, tx, scene, noisy, transfer)


def _transfer(sh_img: NDArray, plain_img: NDArray) -> dict[str, NDArray[np.float32]]:
    """Per encoding, the (H, W, n, 9, 3) matrices from the sky's SH to the coefficients: the
    channels 3 + 3j + c of the images are colour c of the texel's response to sky SH j."""
    h, w = plain_img.shape[:2]
    t_sh = np.moveaxis(sh_img[..., 3:].reshape(h, w, 9, 9, 3), 3, 2)  # (H, W, j, k, c)
    t_plain = plain_img[..., 3:].reshape(h, w, 9, 3)
    return {k: np.ascontiguousarray(np.moveaxis(v, 2, 3), dtype=np.float32)
            for k, v in encodings_from_sh(t_sh, t_plain).items()}


def _global_faces(atlas: Atlas) -> list[NDArray]:
    out, base = [], 0
    for p in atlas.primitives:
        out.append(p.faces + base)
        base += len(p.positions)
    return out


def _to_image(values: NDArray, rc: NDArray, ok: NDArray, shape: tuple[int, int]) -> NDArray:
    img = np.zeros((*shape, *values.shape[1:]))
    mask = np.zeros(shape, bool)
    img[rc[ok, 0], rc[ok, 1]] = values[ok]
    mask[rc[ok, 0], rc[ok, 1]] = True
    return dilate(img, mask)


assert set(ENCODINGS) == set(N_COEFFS)
