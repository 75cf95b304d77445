"""The viewer's computed views, all from the library: the compare view (brute-force and SH
irradiance, R&H's error per degree: `compare_data`) and the H-basis normal-mapping panel
(`hbasis_panel`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..lighting.edits import EditSpec
from ..progress import Progress
from .source import MAX_LMAX, Source

__all__ = ["HBASIS_LABELS", "NORMAL_GRID", "compare_data", "hbasis_panel", "is_rotation_only"]

#: lat-long size (H) of the irradiance lookup textures (the normals of ``error_report``)
NORMAL_GRID = 32


def compare_data(src: Source, progress: Progress | None = None) -> dict[str, Any]:
    """The compare view's numbers and lookup textures, all from the library: the brute-force
    irradiance (``reference_irradiance``) and the SH irradiance of every lmax 1..N
    (``irradiance``) on the normals of ``error_report`` (a (2N)×N lat-long grid, N =
    `NORMAL_GRID`), and R&H's error metric per lmax (``error_report``, §3.1)."""
    from ..lighting.irradiance import irradiance
    from ..lighting.projection import total_intensity
    from ..lighting.reference import error_report, reference_irradiance
    from ..probes.layouts import LatLong
    from ..sh import num_coeffs

    env = src.env
    if env is None:
        raise ShprobeError(f"{src.name} has no probe image: the exact irradiance needs one")
    h = NORMAL_GRID
    nrm = LatLong().pixel_directions((h, 2 * h)).reshape(-1, 3)
    ref = reference_irradiance(env, nrm, progress=progress)
    lmaxes = tuple(range(1, MAX_LMAX + 1))
    rep = error_report(env, lmaxes, reference=ref, normal_grid=h)
    maps = {lm: irradiance(src.coeffs[: num_coeffs(lm)], nrm).reshape(h, 2 * h, 3)
            for lm in lmaxes}
    from ..lighting.glsl import glsl_uniform_values

    return {"grid": [h, 2 * h], "reference": ref.reshape(h, 2 * h, 3),
            # E_lm of the probe at lmax N: the page's per-pixel SH at each lmax 1..N
            "irradiance": glsl_uniform_values(src.coeffs, MAX_LMAX).tolist(),
            "maps": maps, "total_intensity": total_intensity(env).tolist(),
            "rows": rep.as_dict()["rows"]}


#: the H-basis view's panels, in order, with their captions (the page shows them as given)
HBASIS_LABELS = {"reference": "reference E(n′)", "H6": "H6: 6 per-vertex coefficients",
                 "H4": "H4: 4 per-vertex coefficients", "SH9": "SH9: 9 per-vertex coefficients"}


def is_rotation_only(spec: EditSpec) -> bool:
    """Whether ``spec`` leaves its source as it is but for a rotation (no scale, set, light,
    blend, weight or window): then the design is the probe turned, and the H-basis view can
    bake from the probe's own pixels and compare with the brute force over them.

    Parameters
    ----------
    spec : EditSpec
        The page's edit state.

    Returns
    -------
    bool
        True when only rotations (or nothing) are edited.
    """
    from dataclasses import replace

    def moved(vals: tuple) -> tuple:  # a slider left at 1 is no edit
        return tuple(x for x in vals if any(v != 1.0 for v in x[1]))

    core = replace(spec.unrotated(), scales=moved(spec.scales),
                   scale_bands=moved(spec.scale_bands))
    return spec.window is None and core == EditSpec(lmax=spec.lmax)


def hbasis_panel(L: NDArray[np.float64], env: Any, rotation: NDArray[np.float64], mesh: Any,
                 size: int = 160, baked: Any = None) -> tuple[bytes, dict[str, float]]:
    """Irradiance normal mapping (Habel & Wimmer 2010) as ``shprobe hbasis render`` draws it.

    ``mesh`` (None: a sphere) with a procedural bump, shaded by per-vertex H6, H4 and
    tangent-space SH9, against the reference E(n′). The per-vertex coefficients are baked
    from the probe ``env`` box-filtered to 64×128 and turned by ``rotation`` (the page's
    design when it only rotates the probe, `is_rotation_only`), the reference the brute
    force over those pixels; without ``env``, from ``L`` (the page's design at lmax 4, every
    edit applied), the reference the lighting's own SH expansion — the panels and errors are
    then those of ``render_normal_mapped(mesh, L)``; with ``baked`` (a ``shprobe hbasis
    bake`` file's coefficients; ``L`` its radiance SH, ``env`` None), those coefficients.

    Parameters
    ----------
    L : ndarray (K, 3)
        Radiance SH of the lighting (used when ``env`` is None).
    env : Env or None
        The probe, when the design is the probe turned by ``rotation``.
    rotation : ndarray (3, 3)
        The design's rotation, applied to ``env``.
    mesh : trimesh.Trimesh or None
        The mesh shown (None: a sphere).
    size : int
        Panel size in pixels.
    baked : NormalMapBake or None
        Per-vertex coefficients of a bake file, drawn instead of baking.

    Returns
    -------
    tuple of (bytes, dict)
        One ``pack_binary`` message and the relative RMS error per basis. The message
        holds each panel as linear E/π (H, W, 3) float32 (``reference``, ``H6``, ``H4``,
        ``SH9``), the exposure that shows them (``auto_exposure`` of the reference), and each
        basis's error map ``err_<basis>`` (H, W): |E_basis − E_ref| as a fraction of ∫L dω,
        the largest over R, G, B — the compare view's metric (R&H §3.1, the unit of
        ``shprobe error``) — with its maximum and the mask of hit pixels.
    """
    from ..hbasis.rendering import render_normal_mapped
    from ..lighting.projection import total_intensity
    from ..probes.env import Env
    from ..probes.layouts import LatLong
    from ..probes.tonemap import auto_exposure
    from ..scene import sphere_mesh
    from .wire import pack_binary

    lighting: Any = L
    if env is not None:  # the probe turned by the page's rotation: L'(p) = L(Rᵀp)
        h = 64
        dirs = LatLong().pixel_directions((h, 2 * h))
        lighting = Env(np.asarray(env.sample(dirs @ rotation), np.float32), LatLong())
        tot = total_intensity(lighting)
    else:  # ∫ L dω = L_00 ∫ Y_00 dω = √(4π) L_00
        tot = np.sqrt(4.0 * np.pi) * np.asarray(L, np.float64)[0]
    tot = np.where(np.abs(tot) > 0, np.abs(tot), 1.0)
    res = render_normal_mapped(mesh if mesh is not None else sphere_mesh(4), lighting,
                               size=size, baked=baked)
    ref = res.irradiance
    keys = [k for k in ("H6", "H4", "SH9") if k in res.layers]
    errs = {k: (np.abs(res.layers[k] - ref) / tot).max(axis=-1) for k in keys}
    rms = res.info["rel_rms"]
    head = {"size": [int(ref.shape[0]), int(ref.shape[1])], "keys": ["reference", *keys],
            "labels": {k: HBASIS_LABELS[k] for k in ("reference", *keys)},
            "reference": "brute force over the probe" if env is not None
            else "the lighting's SH expansion",
            "baked": baked is not None,
            "stops": auto_exposure(ref[res.mask] / np.pi, target=1.0),
            "total_intensity": tot.tolist(), "rel_rms": rms,
            "max_frac": {k: float(e.max()) for k, e in errs.items()},
            "mean_frac": {k: float(e[res.mask].mean()) if res.mask.any() else 0.0
                          for k, e in errs.items()}}
    arrays = {"reference": (ref / np.pi).astype(np.float32),
              **{k: (res.layers[k] / np.pi).astype(np.float32) for k in keys},
              **{f"err_{k}": e.astype(np.float32) for k, e in errs.items()},
              "mask": res.mask.astype(np.uint32)}
    return pack_binary(head, arrays), rms
