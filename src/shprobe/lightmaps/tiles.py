"""The gather on a Dask cluster: the texels' tiles (`shprobe.lightmaps.gather.tile_size`) run as
tasks, each on a worker's own ray caster; since every tile draws from its own seed the result equals
the local bake's exactly."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..progress import Progress, stage
from .atlas import Atlas, Texels
from .gather import Gathered, gather_tile, join, tile_size
from .settings import LightmapSettings

__all__ = ["gather_on_dask"]

#: a worker keeps the ray caster of the scene it traced last (building it takes a while)
_CASTER: dict[str, Any] = {}


def _caster(key: str, atlas: Atlas) -> Any:
    if key not in _CASTER:
        from ..scene.raycast import RayCaster

        faces, base = [], 0
        for p in atlas.primitives:
            faces.append(p.faces + base)
            base += len(p.positions)
        _CASTER.clear()
        _CASTER[key] = RayCaster(np.concatenate([p.positions for p in atlas.primitives]),
                                 np.concatenate(faces))
    return _CASTER[key]


def _task(key: str, atlas: Atlas, tx: Texels, a: int, b: int, sky: NDArray,
          settings: LightmapSettings) -> Gathered:
    return gather_tile(atlas, tx, (a, b), sky, settings, _caster(key, atlas))


def gather_on_dask(atlas: Atlas, tx: Texels, sky: NDArray, settings: LightmapSettings,
                   scheduler: str, progress: Progress | None = None) -> Gathered:
    """`shprobe.lightmaps.gather.gather` with its tiles on the Dask scheduler at
    ``scheduler`` (as ``shprobe batch --scheduler`` runs its chunks).

    Parameters
    ----------
    atlas : Atlas
        The baked primitives.
    tx : Texels
        Covered texels.
    sky : ndarray (9, C)
        World-frame radiance SH.
    settings : LightmapSettings
        Samples, seed, albedo, sun.
    scheduler : str
        The scheduler's address, e.g. tcp://host:8786.
    progress : Progress, optional
        Reporter.

    Returns
    -------
    Gathered
        Equal to the local gather's.
    """
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise ShprobeError("--scheduler needs the optional packages of shprobe[batch] "
                           "(distributed): pip install 'shprobe[batch]'") from None
    import secrets

    try:
        client = Client(scheduler, timeout="30s")
    except OSError as e:
        raise ShprobeError(f"cannot reach the Dask scheduler at {scheduler}: {e}") from None
    key = secrets.token_hex(8)
    t = tile_size(settings)
    ranges = [(a, min(tx.count, a + t)) for a in range(0, tx.count, t)]
    try:
        atlas_f, tx_f = client.scatter([atlas, tx], broadcast=True)
        futures = {client.submit(_task, key, atlas_f, tx_f, a, b, sky, settings,
                                 pure=False): i for i, (a, b) in enumerate(ranges)}
        parts: list[Gathered | None] = [None] * len(ranges)
        with stage(progress, f"tracing texel rays on {scheduler}", total=tx.count) as bar:
            for fut in as_completed(futures):
                i = futures[fut]
                parts[i] = fut.result()
                bar.advance(ranges[i][1] - ranges[i][0])
    finally:
        client.close()
    return join(parts)  # type: ignore[arg-type]
