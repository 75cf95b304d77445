"""An independent Monte-Carlo path tracer of diffuse irradiance, for checking grid bakes.

It shares no code with shprobe's bake: Embree through embreex directly, its own lat-long
lookup and its own SH evaluation (R&H 2001 constants), cosine-weighted sampling. Irradiance
at a point with normal n, up to ``bounces`` diffuse reflections:

    E(p, n) = π · E_ω~cos[L(p, ω)],  L = sky(ω) on a miss, ρ · E(hit)/π · π = ρ · L' at the
    front of a surface (the next vertex of the path, cosine-sampled about the face normal),
    0 at a back face or past the last bounce.
"""

from __future__ import annotations

import numpy as np

EPS = 1e-4


def sh9(d: np.ndarray) -> np.ndarray:
    """Real SH y_lm, l ≤ 2, R&H 2001 constants and signs, flat index l(l+1)+m."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack([np.full_like(x, 0.282095), 0.488603 * y, 0.488603 * z, 0.488603 * x,
                     1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3 * z * z - 1),
                     1.092548 * x * z, 0.546274 * (x * x - y * y)], axis=-1)


def sh_sky(coeffs: np.ndarray):
    """Radiance function of SH coefficients (≤ 9, 3)."""
    c = np.asarray(coeffs, dtype=np.float64)

    def sky(d):
        return sh9(d)[..., : len(c)] @ c

    return sky


def latlong_sky(image: np.ndarray):
    """Nearest-pixel radiance of a lat-long image (H, 2H, 3): row 0 = +Y, azimuth ψ = 2πu
    with ω = (−sin ψ sin θ, cos θ, cos ψ sin θ)."""
    img = np.asarray(image, dtype=np.float64)
    h, w = img.shape[:2]

    def sky(d):
        theta = np.arccos(np.clip(d[..., 1], -1, 1))
        psi = np.arctan2(-d[..., 0], d[..., 2]) % (2 * np.pi)
        i = np.minimum((theta / np.pi * h).astype(int), h - 1)
        j = np.minimum((psi / (2 * np.pi) * w).astype(int), w - 1)
        return img[i, j]

    return sky


class PathTracer:
    """Diffuse path tracing over a triangle mesh (vertices (V, 3), faces (F, 3)) of albedo
    ``albedo`` (a number, or (F, 3) per face) under ``sky(dirs) -> radiance``."""

    def __init__(self, vertices, faces, albedo, sky) -> None:
        from embreex import mesh_construction, rtcore_scene

        self.v = np.asarray(vertices, dtype=np.float64)
        self.f = np.asarray(faces, dtype=np.int64)
        fv = self.v[self.f]
        n = np.cross(fv[:, 1] - fv[:, 0], fv[:, 2] - fv[:, 0])
        self.fn = n / np.linalg.norm(n, axis=1, keepdims=True)
        a = np.asarray(albedo, dtype=np.float64)
        self.albedo = np.broadcast_to(a if a.ndim == 2 else np.full(3, a), (len(self.f), 3))
        self.sky = sky
        self.scene = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(self.scene, self.v.astype(np.float32),
                                       self.f.astype(np.int32))

    def _cosine(self, n: np.ndarray, rng) -> np.ndarray:
        """Cosine-distributed directions about unit normals (N, 3) (Malley's method)."""
        u1, u2 = rng.random(len(n)), rng.random(len(n))
        r, phi = np.sqrt(u1), 2 * np.pi * u2
        local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u1)], axis=-1)
        a = np.where(np.abs(n[:, :1]) > 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
        t = np.cross(n, a)
        t /= np.linalg.norm(t, axis=1, keepdims=True)
        b = np.cross(n, t)
        return local[:, :1] * t + local[:, 1:2] * b + local[:, 2:] * n

    def irradiance(self, points, normals, bounces: int, paths: int = 20000,
                   seed: int = 0) -> np.ndarray:
        """Irradiance (N, 3) at points (N, 3) facing unit normals (N, 3)."""
        rng = np.random.default_rng(seed)
        p = np.repeat(np.asarray(points, dtype=np.float64), paths, axis=0)
        n = np.repeat(np.asarray(normals, dtype=np.float64), paths, axis=0)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        o = p + EPS * n
        through = np.ones((len(p), 3))
        total = np.zeros((len(p), 3))
        alive = np.arange(len(p))
        for depth in range(bounces + 1):
            d = self._cosine(n, rng)
            r = self.scene.run(o.astype(np.float32), d.astype(np.float32), output=1)
            prim, tfar = r["primID"], r["tfar"].astype(np.float64)
            miss = prim < 0
            total[alive[miss]] += through[miss] * self.sky(d[miss])
            hit = ~miss
            fn = self.fn[np.maximum(prim, 0)]
            front = hit & (np.einsum("ij,ij->i", d, fn) < 0)
            if depth == bounces:
                break
            keep = np.flatnonzero(front)
            x = o[keep] + tfar[keep, None] * d[keep]
            n = fn[keep]
            o = x + EPS * n
            through = through[keep] * self.albedo[prim[keep]]
            alive = alive[keep]
            if len(alive) == 0:
                break
        return np.pi * total.reshape(-1, paths, 3).mean(axis=1)
