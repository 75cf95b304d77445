"""The baked transfer: per-vertex transfer vectors of every model a bake can give, with the scene
they belong to, saved as .npz.

Radiance scale (one convention everywhere in ``shprobe.prt``): for lighting coefficients L_lm
(radiance), ``transfer[v] · L`` is the exit radiance of vertex v,

    B(v) = ρ_v/π · ( ∫ L(ω) V_v(ω) max(0, n_v·ω) dω  +  Σ bounces ),

so for the unshadowed model it is ρ/π times the irradiance E(n_v) = Σ Â_l L_lm y_lm(n_v)
(R&H eq. 7; LH eq. 9 with π H_l = Â_l).

Run-time model switching (LH §4): one bake serves
every model up to what it traced. The unshadowed transfer is analytic in the stored normals and
albedo (LH eq. 9) and is never stored; a ray-traced bake stores the shadowed transfer (bounce 0)
and, for an interreflected bake, the cumulative transfer after each bounce, so
[`Transfer.select`][shprobe.prt.Transfer.select] picks unshadowed, shadowed or interreflected with
any number of bounces up to the baked one, without re-baking.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..files import load_npz, npz_headers, save_npz
from ..sh import check_lmax, degrees, lmax_of, num_coeffs, sh_basis
from ..sh.zonal import clamped_cosine_factors
from .geometry import BakeScene, load_scene, mesh_hash

FORMAT = "shprobe-prt"
#: 1: one ``transfer`` array of the baked model; 2: ``traced`` layers + ``bounce_counts``.
FORMAT_VERSION = 2
MODES = ("unshadowed", "shadowed", "interreflected")


def unshadowed_transfer(normals: NDArray[np.floating], lmax: int) -> NDArray[np.float64]:
    """Â_l y_lm(n) for each normal, (V, K): the SH of max(0, n·ω) (LH eq. 9, π H_l = Â_l)."""
    a = clamped_cosine_factors(lmax)[degrees(lmax)]
    return sh_basis(np.asarray(normals, dtype=np.float64), lmax) * a


def coloured(albedo: NDArray[np.float64]) -> bool:
    """True when some vertex has a non-grey albedo (the transfer then has 3 channels)."""
    a = np.asarray(albedo)
    return bool(np.any(a[:, 1:] != a[:, :1]))


def times_albedo(t: NDArray[np.float64], albedo: NDArray[np.float64]) -> NDArray[np.float64]:
    """ρ/π · t: (V, K) → (V, K, 1) for grey albedo, (V, K, 3) for coloured albedo."""
    channels = 3 if coloured(albedo) else 1
    return t[:, :, None] * (np.asarray(albedo, dtype=np.float64) / np.pi)[:, None, :channels]


def as_stored(t: NDArray[np.float64]) -> NDArray[np.float32]:
    """(V, K, 1) → (V, K) float32; (V, K, 3) stays three-channel."""
    return np.asarray(t[..., 0] if t.shape[-1] == 1 else t, dtype=np.float32)


def _jsonable(value: Any) -> Any:
    """numpy scalars and arrays as JSON values (as_dict)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


def check_int(value: Any, minimum: int, what: str) -> int:
    """``value`` as an int, refusing bools, non-integers and values below ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ShprobeError(f"{what} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def vertex_hash(rows: ArrayLike, seed: int) -> NDArray[np.uint64]:
    """A 64-bit hash of each vertex index and the seed (Fibonacci hashing): what picks a
    vertex's rotated direction set or its turn of the adaptive grid, so that neighbours differ
    and a bake does not depend on how its vertices are split into blocks."""
    return (np.asarray(rows, dtype=np.uint64) + np.uint64(seed)) * np.uint64(0x9E3779B97F4A7C15)


@dataclass(frozen=True)
class Transfer:
    """Per-vertex transfer vectors of every model a bake gives, and their scene.

    vertices/normals (V, 3), faces (F, 3), albedo (V, 3) as baked; lmax the baked degree.
    traced: (S, V, K) float32, or (S, V, K, 3) when the albedo is coloured — the ray-traced
    transfer, cumulative: ``traced[i]`` is shadowed plus ``bounce_counts[i]`` bounces
    (``bounce_counts`` = (0, 1, …, B) for an interreflected bake with B bounces, (0,) for a
    shadowed bake, () with S = 0 for an unshadowed bake). K = (lmax+1)², flat SH index.
    metadata: mesh_hash, mode (the most complete model baked), lmax, samples, bounces, seed,
    albedo summary, and the scale.
    """

    vertices: NDArray[np.float64]
    normals: NDArray[np.float64]
    faces: NDArray[np.int64]
    albedo: NDArray[np.float64]
    lmax: int
    traced: NDArray[np.float32]
    bounce_counts: tuple[int, ...] = ()
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def mode(self) -> str:
        """The most complete model baked (the default of
        [`select`][shprobe.prt.Transfer.select])."""
        return str(self.metadata.get("mode", ""))

    @property
    def mesh_hash(self) -> str:
        return str(self.metadata.get("mesh_hash", ""))

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def max_bounces(self) -> int | None:
        """Largest number of bounces available (0 for a shadowed bake; None without rays)."""
        return max(self.bounce_counts) if self.bounce_counts else None

    @property
    def modes(self) -> tuple[str, ...]:
        """The models this transfer can give at run time."""
        out = ["unshadowed"]
        if 0 in self.bounce_counts:
            out.append("shadowed")
        if any(b > 0 for b in self.bounce_counts):
            out.append("interreflected")
        return tuple(out)

    @property
    def transfer(self) -> NDArray[np.float32]:
        """The transfer of the baked model, (V, K) or (V, K, 3): ``select()``."""
        return self.select()

    @cached_property
    def _unshadowed(self) -> NDArray[np.float32]:
        return as_stored(times_albedo(unshadowed_transfer(self.normals, self.lmax), self.albedo))

    def as_dict(self) -> dict[str, Any]:
        """A JSON-able summary of the bake (not its arrays): what the CLI prints and the
        viewer and batch serialise.

        Returns
        -------
        dict
            mode, models, lmax, vertices, faces, bounces, mesh hash and the bake's metadata
            (samples, seed, refinement rounds, …).
        """
        return {"mode": self.mode, "models": list(self.modes), "lmax": int(self.lmax),
                "vertices": int(self.n_vertices), "faces": len(self.faces),
                "bounces": self.max_bounces, "mesh_hash": self.mesh_hash,
                "metadata": json.loads(json.dumps(self.metadata, default=_jsonable))}

    def select(self, mode: str | None = None, bounces: int | None = None,
               lmax: int | None = None) -> NDArray[np.float32]:
        """The transfer (V, K) or (V, K, 3) of one model, picked at run time (no re-bake).

        mode: 'unshadowed' (always available: analytic from the normals, LH eq. 9),
        'shadowed' (bakes that cast rays), 'interreflected' (shadowed plus ``bounces`` bounces,
        at most the baked number; default all of them); None: the baked mode (``bounces``
        alone implies 'interreflected'). lmax: the first (lmax+1)² columns (default: all).
        """
        if mode is None:
            mode = "interreflected" if bounces is not None else self.mode
        if mode not in MODES:
            raise ShprobeError(f"unknown PRT mode {mode!r}; choose one of {', '.join(MODES)}")
        if bounces is not None and mode != "interreflected":
            raise ShprobeError(f"bounces apply to the interreflected model, not to {mode}")
        k = num_coeffs(self.lmax if lmax is None else self._check_lmax(lmax))
        if mode == "unshadowed":
            return self._unshadowed[:, :k]
        if not self.bounce_counts:
            raise ShprobeError(f"this transfer was baked unshadowed (no rays): it cannot give "
                               f"the {mode} model; bake with --mode {mode}")
        if mode == "shadowed":
            want = 0
        elif bounces is None:
            if self.mode != "interreflected":
                raise ShprobeError("this transfer was baked shadowed (no bounces): it cannot "
                                   "give the interreflected model; bake with --mode "
                                   "interreflected")
            want = max(self.bounce_counts)
        else:
            want = check_int(bounces, 0, "bounces")
        if want not in self.bounce_counts:
            what = "the shadowed model" if mode == "shadowed" else f"{want} bounces"
            top = max(self.bounce_counts)
            if want < top:  # a gap in the layers: only files of format 1 have them
                raise ShprobeError(f"this transfer (from a format-1 file) holds only its baked "
                                   f"model ({self.mode}, {top} bounces), not {what}; re-bake "
                                   "to switch models")
            raise ShprobeError(f"this transfer was baked with {top} bounces; it cannot give "
                               f"{what}")
        return self.traced[self.bounce_counts.index(want), :, :k]

    def _check_lmax(self, lmax: int) -> int:
        lmax = check_lmax(lmax)
        if lmax > self.lmax:
            raise ShprobeError(f"transfer was baked to lmax={self.lmax}, cannot use lmax={lmax}")
        return lmax

    def truncated(self, lmax: int) -> Transfer:
        """The same transfer at a lower degree: the first (lmax+1)² columns (no re-bake)."""
        lmax = self._check_lmax(lmax)
        return replace(self, lmax=lmax, traced=self.traced[:, :, : num_coeffs(lmax)],
                       metadata={**self.metadata, "lmax": lmax})

    def scene(self) -> BakeScene:
        """The scene this transfer was baked for."""
        return BakeScene(self.vertices, self.normals, self.faces, self.albedo, self.mesh_hash)

    def save(self, path: str | os.PathLike[str], overwrite: bool = False) -> Path:
        """Write an .npz (atomic; an existing file is replaced only with ``overwrite``)."""
        meta = {"format": FORMAT, "version": FORMAT_VERSION, **self.metadata, "lmax": self.lmax}
        return save_npz(path, overwrite=overwrite, traced=self.traced,
                        bounce_counts=np.asarray(self.bounce_counts, dtype=np.int64),
                        vertices=self.vertices, normals=self.normals, faces=self.faces,
                        albedo=self.albedo, metadata=np.array(json.dumps(meta)))


_GEOMETRY = ("vertices", "normals", "faces", "albedo", "metadata")
_ARRAYS = {1: ("transfer",), 2: ("traced", "bounce_counts")}


def load_transfer(path: str | os.PathLike[str], scene: Any = None) -> Transfer:
    """Read a transfer .npz (format 2, or format 1 with only its baked model); with ``scene``
    (anything [`load_scene`][shprobe.prt.load_scene] takes: the mesh path(s) or object(s) given to
    [`bake`][shprobe.prt.bake]; the ground plane is added again when the bake had one) refuse a
    file baked for another mesh (hash mismatch).
    """
    p = Path(path)
    _check_headers(npz_headers(p, "transfer file"), p)
    d = load_npz(p, what="transfer file")
    missing = [k for k in _GEOMETRY if k not in d]
    if missing:
        raise ShprobeError("not a shprobe transfer file (no " + ", ".join(missing) + " array)",
                           p)
    meta = _metadata(d["metadata"], p)
    version = meta.get("version")
    if version not in _ARRAYS:
        raise ShprobeError(f"transfer file format {version!r} is not supported "
                           f"(this shprobe reads formats 1 and 2)", p)
    missing = [k for k in _ARRAYS[version] if k not in d]
    if missing:
        raise ShprobeError("not a shprobe transfer file (no " + ", ".join(missing) + " array)",
                           p)
    arrays = {k: d[k] for k in _GEOMETRY[:-1] + _ARRAYS[version]}
    for k, a in arrays.items():
        if a.dtype.kind not in "biuf":
            raise ShprobeError(f"array {k!r} is not numeric ({a.dtype})", p)
        if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
            raise ShprobeError(f"array {k!r} holds NaN or infinity (corrupt file)", p)
    v, f = arrays["vertices"], arrays["faces"]
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise ShprobeError(f"mesh arrays have shapes {v.shape} and {f.shape}, not (V, 3) and "
                           "(F, 3) (corrupt file)", p)
    if f.size and (f.dtype.kind == "f" or f.min() < 0 or f.max() >= v.shape[0]):
        raise ShprobeError("face indices out of range (corrupt file)", p)
    for k, cols in (("normals", (3,)), ("albedo", (3,))):
        if arrays[k].shape != (v.shape[0], *cols):
            raise ShprobeError(f"array {k!r} has shape {arrays[k].shape}, not "
                               f"({v.shape[0]}, 3) for {v.shape[0]} vertices (corrupt file)", p)
    mode = meta.get("mode")
    if mode not in MODES:
        raise ShprobeError(f"unknown transfer mode {mode!r}", p)
    v = arrays["vertices"]
    if version == 1:
        traced, counts = _from_format_1(arrays["transfer"], mode, meta, v.shape[0], p)
    else:
        traced = arrays["traced"]
        counts = tuple(int(b) for b in np.asarray(arrays["bounce_counts"]).ravel())
    if (traced.ndim not in (3, 4) or traced.shape[0] != len(counts)
            or traced.shape[1] != v.shape[0] or (traced.ndim == 4 and traced.shape[3] != 3)):
        raise ShprobeError(f"transfer array has shape {traced.shape} for {v.shape[0]} vertices "
                           f"and {len(counts)} layers", p)
    try:
        lmax = lmax_of(traced.shape[2])
    except ShprobeError as e:
        raise ShprobeError(e.message, p) from None
    if lmax != meta.get("lmax"):
        raise ShprobeError(f"transfer array is lmax {lmax}, metadata says {meta.get('lmax')}", p)
    # layers: () unshadowed, (0,) shadowed, (0, …, B) interreflected; a file converted from
    # format 1 may hold only (B,)
    top = {"unshadowed": None, "shadowed": 0}.get(mode, meta.get("bounces"))
    if (any(b < 0 for b in counts) or list(counts) != sorted(set(counts))
            or (max(counts) if counts else None) != top):
        raise ShprobeError(f"{mode} transfer with bounce layers {list(counts)} (corrupt file)",
                           p)
    if mesh_hash(v, arrays["faces"]) != meta.get("mesh_hash"):
        raise ShprobeError("stored mesh does not match the file's mesh hash (corrupt file)", p)
    if scene is not None:
        if isinstance(scene, BakeScene):
            want = scene.mesh_hash
        else:  # rebuild the scene as baked: the same meshes, with its ground plane if any
            want = load_scene(scene, ground=bool(meta.get("ground", False))).mesh_hash
        # an adaptively refined bake (shprobe.prt.refine) matches the scene it started from
        if want not in (meta["mesh_hash"], meta.get("refine", {}).get("base_mesh_hash")):
            raise ShprobeError(
                f"baked for mesh {meta['mesh_hash'][:12]}…, not for this mesh ({want[:12]}…); "
                "re-bake it", p)
    meta.pop("format", None)
    meta.pop("version", None)
    return Transfer(vertices=v, normals=arrays["normals"], faces=arrays["faces"],
                    albedo=arrays["albedo"], lmax=lmax, traced=traced, bounce_counts=counts,
                    metadata=meta)


#: The most vertices (and faces) a transfer file may declare before anything is inflated.
MAX_VERTICES = 50_000_000


def _check_headers(heads: dict[str, tuple[tuple[int, ...], np.dtype, bool]], p: Path) -> None:
    """Refuse, from the .npy headers alone (nothing inflated), a transfer whose arrays do not
    fit together (a member declaring more rows than the mesh has, as a zip bomb does) or
    declare more than `MAX_VERTICES` rows; the memory check follows in ``load_npz``."""
    shapes = {k: h[0] for k, h in heads.items()}
    v = shapes.get("vertices")
    if v is None or len(v) != 2:
        return  # the one-line refusals after loading name what is missing
    n = v[0]
    if n > MAX_VERTICES or shapes.get("faces", (0,))[0] > 2 * MAX_VERTICES + 4:
        raise ShprobeError(f"transfer declares {n:,} vertices, over the limit of "
                           f"{MAX_VERTICES:,} (corrupt file or zip bomb)", p)
    for k in ("normals", "albedo", "transfer"):
        if k in shapes and (len(shapes[k]) < 1 or shapes[k][0] != n):
            raise ShprobeError(f"array {k!r} has shape {shapes[k]} for {n:,} vertices "
                               "(corrupt file)", p)
    tr = shapes.get("traced")
    if tr is not None and (len(tr) < 3 or tr[1] != n or tr[0] > 1024):
        raise ShprobeError(f"transfer array has shape {tr} for {n:,} vertices (corrupt file)",
                           p)
    if int(np.prod(shapes.get("metadata", ()), dtype=np.float64)) > 1:
        raise ShprobeError("transfer metadata is not one string (corrupt file)", p)


def _metadata(raw: NDArray, p: Path) -> dict[str, Any]:
    try:
        meta = json.loads(str(raw))
    except ValueError:
        raise ShprobeError("transfer metadata is not valid JSON", p) from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise ShprobeError("not a shprobe transfer file", p)
    return meta


def _from_format_1(t: NDArray, mode: str, meta: dict[str, Any], n_vertices: int,
                   p: Path) -> tuple[NDArray, tuple[int, ...]]:
    """Format 1 stored one array, the baked model: shadowed → layer 0, interreflected → its
    bounce count only; unshadowed is recomputed analytically (an empty layer stack)."""
    if t.ndim not in (2, 3) or t.shape[0] != n_vertices or (t.ndim == 3 and t.shape[2] != 3):
        raise ShprobeError(f"transfer array has shape {t.shape} for {n_vertices} vertices", p)
    try:
        meta.setdefault("lmax", lmax_of(t.shape[1]))
    except ShprobeError as e:
        raise ShprobeError(e.message, p) from None
    if mode == "unshadowed":
        return t[None][:0], ()
    return t[None], (0,) if mode == "shadowed" else (int(meta.get("bounces", 0)),)
