"""Per-vertex tangent frames: MikkTSpace-style tangents of TEXCOORD_0 and the texel frames.

glTF requires normal maps' tangents to be MikkTSpace's (Mikkelsen 2008) when a primitive
brings none. `vertex_tangents` computes the same construction per vertex: each face's
tangent and bitangent from its position and UV differences, accumulated with the face's
corner angle as weight, made orthogonal to the vertex normal (Gram–Schmidt), the handedness w
the sign of (N × T)·B. MikkTSpace additionally splits vertices where the handedness or a
tangent flips sharply; on a mesh without such seams (every scene here) the two agree to the
precision of the interpolation. The UVs are taken as (u, 1 − v), so that B = (N × T)·w points
to decreasing glTF v, the image's "up" that glTF normal maps use for +Y.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["arbitrary_tangents", "face_normals", "frames_from", "vertex_normals",
           "vertex_tangents"]


def _unit(v: NDArray, fallback: NDArray | None = None) -> NDArray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    out = v / np.where(n > 1e-30, n, 1.0)
    if fallback is not None:
        out = np.where(n > 1e-30, out, fallback)
    return out


def face_normals(positions: NDArray, faces: NDArray) -> NDArray[np.float64]:
    """Unit geometric normals (F, 3), counter-clockwise = front; zero for degenerate faces.

    Parameters
    ----------
    positions : ndarray (V, 3)
        Vertex positions.
    faces : ndarray (F, 3)
        Vertex indices.

    Returns
    -------
    ndarray (F, 3)
        The normals.
    """
    p = positions[faces]
    return _unit(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))


def _corner_angles(p: NDArray) -> NDArray:
    out = np.empty(p.shape[:2])
    for k in range(3):
        a = _unit(p[:, (k + 1) % 3] - p[:, k])
        b = _unit(p[:, (k + 2) % 3] - p[:, k])
        out[:, k] = np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0))
    return out


def vertex_normals(positions: NDArray, faces: NDArray) -> NDArray[np.float64]:
    """Angle-weighted unit vertex normals (V, 3) for primitives without NORMAL.

    Parameters
    ----------
    positions : ndarray (V, 3)
        Vertex positions.
    faces : ndarray (F, 3)
        Vertex indices.

    Returns
    -------
    ndarray (V, 3)
        The normals (+z where a vertex has no face).
    """
    fn = face_normals(positions, faces)
    w = _corner_angles(positions[faces])
    acc = np.zeros_like(positions, dtype=np.float64)
    for k in range(3):
        np.add.at(acc, faces[:, k], fn * w[:, k:k + 1])
    return _unit(acc, np.array([0.0, 0.0, 1.0]))


def arbitrary_tangents(normals: NDArray) -> NDArray[np.float64]:
    """The documented frame without TEXCOORD_0: x = normalize(a × N), a = (0, 1, 0), or
    (1, 0, 0) where |N_y| > 0.9; w = 1.

    Parameters
    ----------
    normals : ndarray (..., 3)
        Unit normals.

    Returns
    -------
    ndarray (..., 4)
        Tangents with handedness.
    """
    n = np.asarray(normals, dtype=np.float64)
    a = np.where(np.abs(n[..., 1:2]) > 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    t = _unit(np.cross(a, n))
    return np.concatenate([t, np.ones((*t.shape[:-1], 1))], axis=-1)


def vertex_tangents(positions: NDArray, normals: NDArray, uv: NDArray,
                    faces: NDArray) -> NDArray[np.float64]:
    """MikkTSpace-style per-vertex tangents (V, 4) of the UV set ``uv`` (module docstring).

    Parameters
    ----------
    positions : ndarray (V, 3)
        Vertex positions.
    normals : ndarray (V, 3)
        Unit vertex normals.
    uv : ndarray (V, 2)
        The normal map's UVs (glTF convention, v down).
    faces : ndarray (F, 3)
        Vertex indices.

    Returns
    -------
    ndarray (V, 4)
        Unit tangent xyz orthogonal to the normal, and the handedness w = ±1.
    """
    p = positions[faces]
    t = np.asarray(uv, dtype=np.float64)[faces] * [1.0, -1.0] + [0.0, 1.0]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(det) > 1e-20
    r = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
    ft = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * r
    fb = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * r
    ft, fb = _unit(ft), _unit(fb)
    w = _corner_angles(p)
    tan = np.zeros_like(positions, dtype=np.float64)
    bit = np.zeros_like(tan)
    for k in range(3):
        np.add.at(tan, faces[:, k], ft * w[:, k:k + 1])
        np.add.at(bit, faces[:, k], fb * w[:, k:k + 1])
    n = np.asarray(normals, dtype=np.float64)
    tan = tan - n * np.einsum("ij,ij->i", tan, n)[:, None]
    fallback = arbitrary_tangents(n)[:, :3]
    tan = _unit(tan, fallback)
    hand = np.where(np.einsum("ij,ij->i", np.cross(n, tan), bit) < 0, -1.0, 1.0)
    return np.concatenate([tan, hand[:, None]], axis=1)


def frames_from(normals: NDArray, tangents: NDArray) -> NDArray[np.float64]:
    """Orthonormal frames (..., 3, 3), rows x = T, y = (N × T)·w, z = N, from interpolated
    (not necessarily unit) normals and tangents (H&W §4.3: the normal map's tangent space).

    Parameters
    ----------
    normals : ndarray (..., 3)
        Normals.
    tangents : ndarray (..., 4)
        Tangents with handedness.

    Returns
    -------
    ndarray (..., 3, 3)
        Rows are the frame's axes in world space; ``frame @ world_dir`` is the tangent-space
        direction.
    """
    n = _unit(np.asarray(normals, dtype=np.float64), np.array([0.0, 0.0, 1.0]))
    t = np.asarray(tangents, dtype=np.float64)
    x = t[..., :3] - n * np.einsum("...i,...i->...", t[..., :3], n)[..., None]
    x = _unit(x, arbitrary_tangents(n)[..., :3])
    w = np.where(t[..., 3] < 0, -1.0, 1.0)
    y = np.cross(n, x) * w[..., None]
    return np.stack([x, y, n], axis=-2)
