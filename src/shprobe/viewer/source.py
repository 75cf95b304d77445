"""A lighting source of the viewer: its coefficients at the degrees the page asks for, and its
probe image, which may still be on its way from the loader process (`Source`); the
sources a session makes (`load_probe` and the others)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError

__all__ = ["MAX_LMAX", "Source", "coeffs_source", "env_source", "load_probe", "preset_source"]

#: highest degree the compare view projects to (and the per-pixel view draws)
MAX_LMAX = 4


class Source:
    """A lighting source: its name (as ``shprobe`` commands give it), the probe (None for
    presets) and its coefficients: ``coeffs2`` at lmax 2, the base ``shprobe edit`` starts
    from, and `coeffs` at `MAX_LMAX`, projected on first use (projecting to a
    higher degree changes the low coefficients in the last bits, so both are kept).

    ``pending=True``: a probe whose [`Env`][shprobe.probes.env.Env] is still on its way from the
    loader process (the lmax-2 coefficients came first, for the first frame); `env` waits for it."""

    def __init__(self, name: str, coeffs2: NDArray[np.float64], env: Any = None,
                 pending: bool = False) -> None:
        self.name, self.coeffs2 = name, coeffs2
        self._env = env
        self.has_env = env is not None or pending
        self.layout_name = None if env is None else env.layout.name
        self._coeffs: NDArray[np.float64] | None = None if self.has_env else coeffs2
        self._by_lmax: dict[int, NDArray[np.float64]] = {}
        #: why a pending probe never arrived (one line), raised by :attr:`env`
        self.error: str | None = None
        self._arrived = threading.Event()
        if not pending:
            self._arrived.set()
        #: called before waiting for a pending probe (asks the loader to send it now)
        self.request: Callable[[], None] | None = None
        self._lock = threading.Lock()
        #: the page's background texture (:func:`~shprobe.viewer.payloads.background_payload`)
        self.background: bytes | None = None

    @property
    def env(self) -> Any:
        """The probe (None for presets); waits for one still being loaded; a one-line
        [`ShprobeError`][shprobe.errors.ShprobeError] when its loading failed."""
        if not self._arrived.is_set() and self.request is not None:
            self.request()
        self._arrived.wait()
        if self.error is not None:
            raise ShprobeError(self.error)
        return self._env

    def arrive(self, env: Any, coeffs: NDArray[np.float64] | None = None,
               background: bytes | None = None, error: str | None = None) -> None:
        """The pending probe (None: its loading failed, ``error`` saying why), its
        lmax-`MAX_LMAX` coefficients and background texture, from the loader process."""
        with self._lock:
            self._env = env
            self.error = error
            if coeffs is not None:
                self._coeffs = coeffs
            if background is not None:
                self.background = background
            self.has_env = env is not None
        self._arrived.set()

    @property
    def coeffs(self) -> NDArray[np.float64]:
        """The coefficients at `MAX_LMAX` (the compare view's)."""
        env = self.env
        with self._lock:
            if self._coeffs is None:
                from ..lighting.projection import project

                if env is None:
                    raise ShprobeError(f"{self.name}: the probe could not be loaded")
                self._coeffs = np.asarray(project(env, MAX_LMAX), np.float64)
            return self._coeffs

    def coeffs_at(self, lmax: int) -> NDArray[np.float64]:
        """The probe projected to exactly ``lmax`` (R&H eq. 10; cached): `coeffs2` at 2,
        `coeffs` at `MAX_LMAX` — as ``shprobe edit --blend FILE:W`` projects a
        blended probe to the edit's degree."""
        if lmax == 2:
            return self.coeffs2
        if lmax == MAX_LMAX:
            return self.coeffs
        with self._lock:
            c = self._by_lmax.get(lmax)
        if c is None:
            from ..lighting.projection import project

            env = self.env
            if env is None:
                with self._lock:  # keep_coeffs_only may have cached it and let the image go
                    c = self._by_lmax.get(lmax)
                if c is not None:
                    return c
                raise ShprobeError(f"{self.name}: the probe could not be loaded")
            c = np.asarray(project(env, lmax), np.float64)
            with self._lock:
                self._by_lmax[lmax] = c
        return c

    def keep_coeffs_only(self, lmax: int) -> None:
        """Project to every degree 0…``lmax`` (cached, `coeffs_at`), then drop the
        probe image and background: what a blend source needs, without its memory."""
        try:
            for l in range(lmax + 1):
                self.coeffs_at(l)
        except ShprobeError:  # a probe that failed to load has nothing to keep
            return
        with self._lock:
            self._env, self.background = None, None

    def __repr__(self) -> str:
        return f"Source({self.name!r}, env={self.has_env})"


def load_probe(path: str | list[str], layout: str = "auto", name: str | None = None,
               mark: Callable[[str], None] | None = None) -> Source:
    """A probe — one file, or six cube-face files +X −X +Y −Y +Z −Z — as a `Source`,
    read by the library's one resolver (`shprobe.lighting.source.resolve_lighting`:
    decoded, projected to lmax 2) and checked; one-line
    [`ShprobeError`][shprobe.errors.ShprobeError] naming the file when it is bad. ``mark`` (a timing
    hook) is called with 'decoded' once the file is read."""
    from ..lighting.source import resolve_lighting

    lit = resolve_lighting(path, layout=None if layout == "auto" else layout, lmax=2,
                           need_env=True)
    if mark is not None:
        mark("decoded")
    env = lit.env
    where = name or lit.source
    rad = env.radiance
    if not np.all(np.isfinite(rad)):
        raise ShprobeError("probe has non-finite (NaN or Inf) pixels", where)
    if float(rad.min()) < 0:
        raise ShprobeError("probe has negative pixels", where)
    src = Source(where, np.asarray(lit.coeffs, np.float64), env)
    if not np.all(np.isfinite(src.coeffs2)):
        raise ShprobeError("probe projects to non-finite coefficients", where)
    return src


def coeffs_source(path: str, name: str) -> Source:
    """Coefficients in any format the library reads
    (`shprobe.lighting.source.resolve_lighting`) as a `Source` named ``name``."""
    from ..lighting.source import resolve_lighting

    return Source(name, resolve_lighting(coeffs=path, lmax=None).coeffs)


def preset_source(name: str) -> Source:
    from ..lighting.source import resolve_lighting

    return Source(f"preset:{name}", resolve_lighting(preset=name, lmax=None).coeffs)


def env_source(env: Any, name: str) -> Source:
    """A probe already in memory (the procedural sky) as a `Source`."""
    from ..lighting.projection import project

    return Source(name, np.asarray(project(env, 2), np.float64), env)
