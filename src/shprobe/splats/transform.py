"""Similarity transforms of splat scenes: positions, covariances, opacities and every SH band.

A similarity x ↦ s·Q·x + t (Q orthogonal, det ±1, s > 0) maps a splat at p with covariance
Σ = R S² Rᵀ (R from its quaternion, S = diag(exp log_scales)) to s·Q·p + t with covariance
s² Q Σ Qᵀ. The colour it shows from direction d afterwards must be the colour it showed from
Q⁻¹d before (translation and uniform scale do not change directions), so its SH function f
becomes f∘Q⁻¹: for a rotation that is the Wigner rotation of each band (Lisle & Huang 2007
eq. 5); for a reflection Q = −R' (R' = −Q a rotation) it is the rotation R' after the parity
(−1)^l of each band, since f(−u) has coefficients (−1)^l a_lm.

A reflection cannot be put into a quaternion as is: Q R has det −1. It is folded into the
splat's own axes instead: Q R = R' R diag(−1, −1, −1) = (R' R diag(1, −1, −1)) diag(−1, 1, 1),
and the last factor flips one axis of the ellipsoid, which leaves S² — and so Σ — unchanged.
The new quaternion is q_R' ⊗ q ⊗ (0, 1, 0, 0): a valid right-handed rotation, the scales as
they were.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from .cloud import Splats

#: Largest deviation of AᵀA/s² from I accepted for a "similarity" 4×4.
SIMILARITY_TOL = 1e-5
#: Largest magnitude of a matrix entry: the scale of float32 positions (3.4e38) less room
#: for the scene's own extent.
MAX_ENTRY = 1e30

#: Axis letters of the named frames: where the +x, +y, +z axes point (Right/Left, Up/Down,
#: Back/Front; "back" is toward the viewer of a y-up scene).
FRAMES = {
    "opencv": "RDF", "colmap": "RDF", "ply": "RDF",          # 3DGS training captures
    "opengl": "RUB", "usd": "RUB", "three": "RUB", "spz": "RUB",
    "gltf": "LUF",                                             # glTF 2.0: +Y up, +Z forward
    "blender": "RFU",
    "unity": "RUF",                                            # left-handed
}
_LETTERS = {"R": (1, 0, 0), "L": (-1, 0, 0), "U": (0, 1, 0), "D": (0, -1, 0),
            "B": (0, 0, 1), "F": (0, 0, -1)}


@dataclass(frozen=True)
class Similarity:
    """x ↦ scale · linear · x + translation; ``linear`` orthogonal (det ±1), ``scale`` > 0.

    Parameters
    ----------
    linear
        (3, 3) orthogonal (det ±1).
    scale
        Uniform scale, > 0.
    translation
        (3,) offset.
    """

    linear: NDArray[np.float64]
    scale: float = 1.0
    translation: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))

    def __repr__(self) -> str:
        kind = "mirror" if self.is_mirror else "rotation"
        return (f"Similarity({kind}, scale={self.scale:g}, "
                f"translation={np.round(self.translation, 6).tolist()})")

    @property
    def is_mirror(self) -> bool:
        return bool(np.linalg.det(self.linear) < 0)

    @property
    def matrix(self) -> NDArray[np.float64]:
        """The 4×4 matrix acting on column vectors (x, y, z, 1)."""
        m = np.eye(4)
        m[:3, :3] = self.scale * self.linear
        m[:3, 3] = self.translation
        return m

    def then(self, other: Similarity) -> Similarity:
        """This transform followed by ``other``.

        Parameters
        ----------
        other
            The transform applied after this one.

        Returns
        -------
        Similarity
            The composition.
        """
        return Similarity(other.linear @ self.linear, other.scale * self.scale,
                          other.scale * other.linear @ self.translation + other.translation)

    @classmethod
    def identity(cls) -> Similarity:
        return cls(np.eye(3))

    @classmethod
    def from_matrix(cls, matrix: ArrayLike) -> Similarity:
        """A 4×4 (or 3×4) matrix that must be a similarity: shear and non-uniform scale are
        refused in one line (they would turn the SH lobes into no SH of the same degree).

        Parameters
        ----------
        matrix
            A 4×4 or 3×4 similarity matrix.

        Returns
        -------
        Similarity
            The similarity (shear and non-uniform scale refused).
        """
        try:
            m = np.asarray(matrix, dtype=np.float64)
        except (TypeError, ValueError):
            raise ShprobeError("matrix must be 12 or 16 numbers") from None
        if m.size in (12, 16) and m.ndim == 1:
            m = m.reshape(-1, 4)
        if m.shape not in ((3, 4), (4, 4)) or not np.all(np.isfinite(m)):
            raise ShprobeError(f"matrix must be a finite 4×4 (or 3×4), got shape {m.shape}")
        if np.abs(m).max() > MAX_ENTRY:  # its determinant and the positions would overflow
            raise ShprobeError(f"matrix entries must be within ±{MAX_ENTRY:g}, got "
                               f"{float(np.abs(m).max()):.3g}")
        if m.shape == (4, 4) and not np.allclose(m[3], [0, 0, 0, 1], atol=1e-9):
            raise ShprobeError(f"matrix is projective (last row {m[3].tolist()}, expected "
                               "0,0,0,1): not a similarity")
        a = m[:3, :3]
        det = float(np.linalg.det(a))
        if det == 0.0:
            raise ShprobeError("matrix is singular: not a similarity")
        s = abs(det) ** (1.0 / 3.0)
        err = float(np.abs(a.T @ a / s**2 - np.eye(3)).max())
        if not err <= SIMILARITY_TOL:
            raise ShprobeError(f"matrix is not a similarity (shear or non-uniform scale: AᵀA "
                               f"differs from s²I by {err:.3g} relative): splats and their SH "
                               "only transform exactly under rotation, mirror, uniform scale "
                               "and translation")
        q = a / s
        u, _, vt = np.linalg.svd(q)  # the nearest orthogonal matrix
        return cls(u @ vt, s, m[:3, 3].copy())


def rotation(matrix: ArrayLike) -> Similarity:
    """A rotation (checked by
    [`shprobe.sh.rotation.one_rotation`][shprobe.sh.rotation.one_rotation]).

    Parameters
    ----------
    matrix
        A 3×3 rotation, (w, x, y, z) quaternion or scipy ``Rotation``.

    Returns
    -------
    Similarity
        The rotation.
    """
    from ..sh.rotation import one_rotation

    return Similarity(one_rotation(matrix))


def translation(offset: ArrayLike) -> Similarity:
    """A translation by ``offset``: positions move, SH (directions) do not.

    Parameters
    ----------
    offset
        (3,) the displacement, finite.

    Returns
    -------
    Similarity
        x ↦ x + offset.
    """
    t = np.asarray(offset, dtype=np.float64).reshape(3)
    if not np.all(np.abs(t) <= MAX_ENTRY):
        raise ShprobeError(f"translation must be finite and within ±{MAX_ENTRY:g}")
    return Similarity(np.eye(3), 1.0, t)


def uniform_scale(factor: float) -> Similarity:
    """A uniform scale about the origin: positions and splat scales grow, SH do not change.

    Parameters
    ----------
    factor
        The scale, finite and positive.

    Returns
    -------
    Similarity
        x ↦ factor · x.
    """
    s = float(factor)
    if not (1.0 / MAX_ENTRY <= s <= MAX_ENTRY):
        raise ShprobeError(f"scale must be a positive number from {1.0 / MAX_ENTRY:g} to "
                           f"{MAX_ENTRY:g}, got {factor!r}")
    return Similarity(np.eye(3), s)


def mirror(axis: str) -> Similarity:
    """The reflection x ↦ −x (or y, z) through the plane of the other two axes.

    Parameters
    ----------
    axis
        "x", "y" or "z".

    Returns
    -------
    Similarity
        The reflection.
    """
    i = "xyz".find(str(axis).strip().lower())
    if i < 0 or len(str(axis).strip()) != 1:
        raise ShprobeError(f"mirror axis must be x, y or z, got {axis!r}")
    m = np.eye(3)
    m[i, i] = -1.0
    return Similarity(m)


def _frame_axes(name: str) -> NDArray[np.float64]:
    code = FRAMES.get(name.strip().lower(), name.strip().upper())
    if len(code) != 3 or any(c not in _LETTERS for c in code):
        raise ShprobeError(f"unknown frame {name!r}: use one of {', '.join(sorted(FRAMES))} "
                           "or three axis letters such as RDF (x Right, y Down, z Front)")
    c = np.array([_LETTERS[ch] for ch in code], dtype=np.float64).T
    if abs(abs(np.linalg.det(c)) - 1.0) > 1e-9:
        raise ShprobeError(f"frame {name!r} names an axis twice")
    return c


def frame(source: str, target: str) -> Similarity:
    """Re-express a scene given in frame ``source`` in frame ``target`` (names of
    [`FRAMES`][shprobe.splats.FRAMES] or axis letters), e.g. ``frame("colmap", "gltf")`` = 180°
    about z.

    Parameters
    ----------
    source, target
        Frame names of ``FRAMES`` or axis letters.

    Returns
    -------
    Similarity
        The change of frame.
    """
    return Similarity(_frame_axes(target).T @ _frame_axes(source))


# ----------------------------------------------------------------------------- the SH matrix

def _fibonacci(n: int) -> NDArray[np.float64]:
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = i * np.pi * (3.0 - np.sqrt(5.0))
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


@lru_cache(maxsize=64)
def _sh_matrix_cached(key: bytes, degree: int) -> NDArray[np.float64]:
    from ..sh.basis import sh_basis_numpy
    from ..sh.conventions import cs_signs

    q = np.frombuffer(key, dtype=np.float64).reshape(3, 3)
    u = _fibonacci(64)
    # Coefficients a' of f∘Q⁻¹ satisfy Y(u) a' = Y(Qᵀu) a at every u: solved on 64 points,
    # exact to rounding (Y(u) has full column rank). This is the band-by-band Wigner matrix
    # of shprobe.sh.rotation for a rotation, and parity × Wigner for a reflection (both
    # checked in the tests); it stays in numpy so that a streamed transform loads no numba.
    d = np.linalg.lstsq(sh_basis_numpy(u, degree), sh_basis_numpy(u @ q, degree), rcond=None)[0]
    s = cs_signs(degree)
    out = s[:, None] * d * s[None, :]  # into the renderer's CS-phase basis
    out[np.abs(out) < 1e-14] = 0.0
    out.flags.writeable = False
    return out


def sh_matrix(linear: ArrayLike, degree: int) -> NDArray[np.float64]:
    """(K, K) matrix M mapping a splat's SH (renderer's CS-phase convention, K = (degree+1)²)
    under the orthogonal map ``linear``: sh' = M @ sh, so that the colour seen from Q·d after
    equals the colour seen from d before.

    Parameters
    ----------
    linear
        (3, 3) orthogonal map (a rotation or a reflection).
    degree
        The SH degree, K = (degree + 1)².

    Returns
    -------
    ndarray of shape (K, K)
        M with sh' = M @ sh.
    """
    q = np.ascontiguousarray(linear, dtype=np.float64)
    if q.shape != (3, 3) or not np.allclose(q @ q.T, np.eye(3), atol=1e-6):
        raise ShprobeError("the SH of splats transform only under an orthogonal 3×3 map")
    return _sh_matrix_cached(q.tobytes(), int(degree))


# ----------------------------------------------------------------------------- quaternions

def quat_multiply(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Hamilton products a ⊗ b of (..., 4) quaternions (w, x, y, z), broadcast."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def quat_from_matrix(r: ArrayLike) -> NDArray[np.float64]:
    """Unit quaternion (w, x, y, z), w ≥ 0, of one proper rotation matrix (Shepperd 1978)."""
    m = np.asarray(r, dtype=np.float64)
    tr = np.trace(m)
    cands = [tr, m[0, 0], m[1, 1], m[2, 2]]
    i = int(np.argmax(cands))
    if i == 0:
        w = np.sqrt(1.0 + tr) / 2
        q = [w, (m[2, 1] - m[1, 2]) / (4 * w), (m[0, 2] - m[2, 0]) / (4 * w),
             (m[1, 0] - m[0, 1]) / (4 * w)]
    elif i == 1:
        x = np.sqrt(1.0 + 2 * m[0, 0] - tr) / 2
        q = [(m[2, 1] - m[1, 2]) / (4 * x), x, (m[0, 1] + m[1, 0]) / (4 * x),
             (m[0, 2] + m[2, 0]) / (4 * x)]
    elif i == 2:
        y = np.sqrt(1.0 + 2 * m[1, 1] - tr) / 2
        q = [(m[0, 2] - m[2, 0]) / (4 * y), (m[0, 1] + m[1, 0]) / (4 * y), y,
             (m[1, 2] + m[2, 1]) / (4 * y)]
    else:
        z = np.sqrt(1.0 + 2 * m[2, 2] - tr) / 2
        q = [(m[1, 0] - m[0, 1]) / (4 * z), (m[0, 2] + m[2, 0]) / (4 * z),
             (m[1, 2] + m[2, 1]) / (4 * z), z]
    q = np.array(q)
    return q * (1.0 if q[0] >= 0 else -1.0) / np.linalg.norm(q)


#: The quaternion of the 180° turn about the splat's own x axis (folds a reflection in).
X180 = np.array([0.0, 1.0, 0.0, 0.0])


def apply(splats: Splats, sim: Similarity) -> Splats:
    """The splats moved by ``sim`` (see the module docstring), every SH band included; values
    beyond float32 become inf, which every writer refuses (no numpy warning on the way).

    Parameters
    ----------
    splats : Splats
        The splats, in the PLY's frame.
    sim : Similarity
        The transform.

    Returns
    -------
    Splats
        The moved splats.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        return _apply(splats, sim)


def _apply(splats: Splats, sim: Similarity) -> Splats:
    q = np.asarray(sim.linear, dtype=np.float64)
    mirror_ = np.linalg.det(q) < 0
    proper = -q if mirror_ else q
    pos = (splats.positions.astype(np.float64) @ (sim.scale * q).T) + sim.translation
    scales = splats.log_scales + np.float32(np.log(sim.scale))
    rot = quat_multiply(quat_from_matrix(proper), splats.rotations)
    if mirror_:
        rot = quat_multiply(rot, X180)
    m = sh_matrix(q, splats.degree).astype(np.float32)
    sh = np.matmul(m, splats.sh)
    normals = None if splats.normals is None else splats.normals @ q.T.astype(np.float32)
    return Splats(pos, scales, rot, splats.opacity, sh, normals)
