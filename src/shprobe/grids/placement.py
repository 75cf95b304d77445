"""Probes inside geometry: found, moved to free space within their cell, or marked invalid
and filled from their neighbours (the validity / virtual offset / dilation of Unity's probe
volumes and DDGI's probe relocation, done once at bake time).

A probe is inside geometry when more than ``inside_fraction`` of its test rays meet the back
of a face (from inside a closed solid, every ray does). It is moved to the nearest point of a
lattice in its cell (offsets up to ±0.4 of the cell per axis) that sees no back face within
its test rays and no surface closer than a twentieth of the smallest cell side (a probe whose
nearest surface lies beyond every lattice point is buried and not searched); where no
lattice point is free, its validity is 0 and its coefficients are the mean of its valid
neighbours', grown outwards until every invalid probe has a value (dilation).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..prt.directions import sample_directions
from .rays import ProbeTracer

__all__ = ["TEST_RAYS", "dilate", "place_probes"]

#: Rays per probe (and per candidate position) of the inside-geometry test.
TEST_RAYS = 256
#: Offsets tried within the cell, as fractions of the cell side per axis.
_OFFSETS = np.array([-0.4, -0.2, 0.0, 0.2, 0.4])
#: Candidate positions tested per probe in one round (nearest first).
_ROUND = 8


def place_probes(tracer: ProbeTracer, centres: NDArray[np.float64],
                 spacing: NDArray[np.float64], inside_fraction: float, seed: int = 0
                 ) -> tuple[NDArray[np.float64], NDArray[np.float32], NDArray[np.bool_]]:
    """Bake positions (P, 3), validity (P,) and moved (P,) flags for probes at ``centres``
    (P, 3) (module doc)."""
    dirs = sample_directions(TEST_RAYS, seed + 1)
    pos = np.array(centres, dtype=np.float64).reshape(-1, 3)
    valid = np.ones(len(pos), np.float32)
    moved = np.zeros(len(pos), bool)
    back, near = _back_fraction(tracer, pos, dirs)
    inside = back > inside_fraction
    g = np.stack(np.meshgrid(_OFFSETS, _OFFSETS, _OFFSETS, indexing="ij"), -1).reshape(-1, 3)
    offsets = g * spacing
    offsets = offsets[np.argsort(np.linalg.norm(offsets, axis=1), kind="stable")][1:]
    reach = float(np.linalg.norm(offsets, axis=1).max())
    # a probe whose nearest surface is beyond every lattice point is buried: invalid at once
    buried = inside & (near > reach)
    valid[buried] = 0.0
    todo = np.flatnonzero(inside & ~buried)
    clearance = 0.05 * float(spacing.min())
    for a in range(0, len(offsets), _ROUND):  # nearest offsets first, all probes at once
        if not len(todo):
            break
        cand = pos[todo, None, :] + offsets[None, a:a + _ROUND]  # (T, R, 3)
        b, n = _back_fraction(tracer, cand.reshape(-1, 3), dirs)
        ok = ((b == 0) & (n >= clearance)).reshape(len(todo), -1)
        found = ok.any(axis=1)
        first = ok.argmax(axis=1)
        pos[todo[found]] = cand[found, first[found]]
        moved[todo[found]] = True
        todo = todo[~found]
    valid[todo] = 0.0
    return pos, valid, moved


def _back_fraction(tracer: ProbeTracer, points: NDArray[np.float64], dirs: NDArray[np.float64]
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Fraction of rays meeting a back face and the nearest hit distance, per point (a block
    of points at a time: the hits of all rays at once held ~100 bytes a ray)."""
    back, near = np.empty(len(points)), np.empty(len(points))
    step = max(1, (1 << 18) // len(dirs))
    for a in range(0, len(points), step):
        h = tracer.trace(points[a:a + step], dirs)
        back[a:a + step], near[a:a + step] = h.back.mean(axis=1), h.dist.min(axis=1)
    return back, near


def dilate(coeffs: NDArray, validity: NDArray) -> NDArray:
    """Coefficients (NX, NY, NZ, K, 3) with each invalid probe (validity 0) set to the mean of
    its valid or already filled 26-neighbours, ring after ring; unchanged where all are
    valid or none is."""
    c = np.array(coeffs, copy=True)
    have = np.asarray(validity) > 0
    if have.all() or not have.any():
        return c
    shape = have.shape
    while not have.all():
        acc = np.zeros_like(c)
        cnt = np.zeros(shape)
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    if dx == dy == dz == 0:
                        continue
                    src, dst = _shifted(shape, (dx, dy, dz))
                    m = have[src]
                    acc[dst] += np.where(m[..., None, None], c[src], 0.0)
                    cnt[dst] += m
        grow = ~have & (cnt > 0)
        c[grow] = acc[grow] / cnt[grow][:, None, None]
        have = have | grow
    return c


def _shifted(shape: tuple[int, ...], step: tuple[int, int, int]):
    """Slices (src, dst) with dst = src + step, inside ``shape``."""
    src, dst = [], []
    for n, s in zip(shape, step, strict=True):
        src.append(slice(max(0, -s), n - max(0, s)))
        dst.append(slice(max(0, s), n - max(0, -s)))
    return tuple(src), tuple(dst)
