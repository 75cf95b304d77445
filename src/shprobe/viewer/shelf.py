"""The probes a viewer session keeps for blending (`ProbeShelf`, a part of
`Session`): every probe loaded — the command line's, the uploads —
by the id the page names it with, its coefficients at every degree a design asks for, and the
decoded images of those that are only blend sources let go."""

from __future__ import annotations

import os
import threading

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..lighting.edits import Blend
from .design import DESIGN_LMAX
from .source import Source

__all__ = ["ProbeShelf"]


class ProbeShelf:
    """The session's probes for blending. Needs, from the session: ``lock``, ``probes`` (id →
    (file name as the user gave it, Source)), ``_probe_tag`` (this server's id prefix) and
    ``_source`` (the current lighting source)."""

    lock: threading.Lock
    probes: dict[str, tuple[str, Source]]
    _probe_tag: str
    _source: Source | None

    def register_probe(self, src: Source, name: str) -> str:
        """Keep a loaded probe for blending; → its id (what the page names it by)."""
        with self.lock:
            pid = f"{self._probe_tag}.{len(self.probes)}"
            self.probes[pid] = (name, src)
        self._trim_probes(keep=src)  # it may become the source next
        return pid

    def _trim_probes(self, keep: Source | None = None) -> None:
        """A probe that is only a blend source now (not `source`, not ``keep``) keeps
        its coefficients at every degree a design can ask for and lets its decoded image go
        (in a thread: up to `DESIGN_LMAX` + 1 projections), so that uploads do not pile
        up images in memory: at most the source's and the latest upload's are held."""
        current = self._source
        old = [src for _, (_, src) in self._probe_items()
               if src is not current and src is not keep and src._arrived.is_set()
               and src._env is not None]
        if old:
            threading.Thread(target=lambda: [o.keep_coeffs_only(DESIGN_LMAX) for o in old],
                             daemon=True).start()

    def _probe_items(self) -> list[tuple[str, tuple[str, Source]]]:
        with self.lock:  # register_probe adds from a worker thread
            return list(self.probes.items())

    def probe_names(self) -> dict[str, str]:
        return {k: v[0] for k, v in self._probe_items()}

    def probe_list(self) -> list[dict[str, str]]:
        return [{"id": k, "name": os.path.basename(v[0]) or v[0]}
                for k, v in self._probe_items()]

    def blend_coeffs(self, blend: Blend, lmax: int) -> NDArray[np.float64]:
        """A blend of the page's design: a preset, or a probe this session loaded (by id);
        never a file named by the page."""
        from ..lighting.source import blend_lighting

        if blend.kind == "probe":
            return self.probe_coeffs(blend.name, lmax)
        if blend.kind != "preset":
            raise ShprobeError("the page blends presets and the probes this server loaded")
        return blend_lighting(blend, lmax)

    def probe_coeffs(self, pid: str, lmax: int) -> NDArray[np.float64]:
        """A registered probe projected to ``lmax`` (`Source.coeffs_at`)."""
        with self.lock:
            hit = self.probes.get(pid)
        if hit is None:
            raise ShprobeError(f"blend probe {pid} is not loaded in this server (load it "
                               "again)")
        return hit[1].coeffs_at(lmax)
