"""The viewer's computed views, all from the library: the compare view (brute-force and SH
irradiance, R&H's error per degree: :func:`compare_data`) and the H-basis normal-mapping panel
(:func:`hbasis_panel`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..progress import Progress
from .source import MAX_LMAX, Source

__all__ = ["NORMAL_GRID", "compare_data", "hbasis_panel"]

#: lat-long size (H) of the irradiance lookup textures (the normals of ``error_report``)
NORMAL_GRID = 32


def compare_data(src: Source, progress: Progress | None = None) -> dict[str, Any]:
    """The compare view's numbers and lookup textures, all from the library: the brute-force
    irradiance (``reference_irradiance``) and the SH irradiance of every lmax 1..N
    (``irradiance``) on the normals of ``error_report`` (a (2N)×N lat-long grid, N =
    :data:`NORMAL_GRID`), and R&H's error metric per lmax (``error_report``, §3.1)."""
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
            "rows": [{"lmax": r.lmax, "mean_frac": r.mean_frac, "max_frac": r.max_frac,
                      "mean_rel": r.mean_rel} for r in rep.rows]}




def hbasis_panel(L: NDArray[np.float64], env: Any, rotation: NDArray[np.float64], mesh: Any,
                 size: int = 160) -> tuple[bytes, dict[str, float]]:
    """Irradiance normal mapping (Habel & Wimmer 2010) as ``shprobe hbasis render`` draws it,
    for the page's lighting ``L`` (its design at lmax 4, edits and rotation applied): ``mesh``
    (None: a sphere) with a procedural bump, shaded by per-vertex H6, H4 and tangent-space
    SH9 baked from ``L``, against the reference E(n′) — brute force over the probe ``env``
    (box-filtered to 64×128 and turned by ``rotation``; the other edits are not applied to
    it) or, without a probe, the lighting's own SH expansion.
    → (PNG of ``panel_image``, relative RMS per basis)."""
    import io

    from PIL import Image

    from ..hbasis.rendering import panel_image, render_normal_mapped
    from ..probes.env import Env
    from ..probes.layouts import LatLong
    from ..probes.tonemap import auto_exposure, tonemap
    from ..scene import sphere_mesh

    lighting: Any = L
    if env is not None:  # the probe turned by the page's rotation: L'(p) = L(Rᵀp)
        h = 64
        dirs = LatLong().pixel_directions((h, 2 * h))
        lighting = Env(np.asarray(env.sample(dirs @ rotation), np.float32), LatLong())
    res = render_normal_mapped(mesh if mesh is not None else sphere_mesh(4), lighting,
                               size=size)
    stops = auto_exposure(res.irradiance[res.mask], target=1.0)
    buf = io.BytesIO()
    Image.fromarray(tonemap(panel_image(res), stops)).save(buf, format="PNG")
    return buf.getvalue(), res.info["rel_rms"]
