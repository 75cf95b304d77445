"""An independent reference for interreflected PRT: a per-point gather of direct,
1- and 2-bounce exit radiance under band-limited SH lighting, written without the transfer
machinery — its own Embree scene and ray loop, cosine-weighted stratified (Malley) hemisphere
sampling in each point's own frame, exact hit points from the ray distance, smooth normals and
albedo interpolated at every hit, and the lighting evaluated as radiance L(ω) = Σ L_lm y_lm(ω)
(never projected onto a transfer vector).

    B_0(x) = ρ/π ∫ L(ω) V(x, ω) max(0, n·ω) dω              ≈ ρ/N Σ_j L(ω_j) V_j
    B_k(x) = ρ/π ∫ B_{k−1}(hit(x, ω)) max(0, n·ω) dω         ≈ ρ/N Σ_j B_{k−1}(hit_j)

(cosine-weighted ω_j: pdf cos/π). Rays leave from x + ε n, by the one offset rule of the bake
(shprobe.scene.raycast.RayCaster.offset_points: a step that crosses another surface is put back);
back-face hits block and send nothing, as in the bake; a ray that escapes sees L (direct) or
nothing (bounces). Only the origins come from the library's ray caster; the rays are cast here.
"""

from __future__ import annotations

import numpy as np

from shprobe.sh import sh_basis


class Gather:
    def __init__(self, vertices, faces, normals, albedo, coeffs, eps_fraction=1e-4, seed=0):
        from embreex import mesh_construction, rtcore_scene

        self.v = np.asarray(vertices, dtype=np.float64)
        self.f = np.asarray(faces, dtype=np.int64)
        self.n = np.asarray(normals, dtype=np.float64)
        self.rho = np.asarray(albedo, dtype=np.float64)[:, 0]
        self.coeffs = np.asarray(coeffs, dtype=np.float64)  # (K,) grey radiance
        self.lmax = round(np.sqrt(self.coeffs.shape[0])) - 1
        self.scene = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(self.scene, self.v.astype(np.float32),
                                       self.f.astype(np.int32))
        fv = self.v[self.f]
        fn = np.cross(fv[:, 1] - fv[:, 0], fv[:, 2] - fv[:, 0])
        self.fn = fn / np.linalg.norm(fn, axis=1, keepdims=True)
        self.eps = eps_fraction * float(np.linalg.norm(np.ptp(self.v, axis=0)))
        self.rng = np.random.default_rng(seed)
        from shprobe.scene.raycast import RayCaster

        self.caster = RayCaster(self.v, self.f)

    def _vertex_ids(self, points):
        from scipy.spatial import cKDTree

        d, i = cKDTree(self.v).query(points)
        if d.max() > 0:
            raise ValueError("radiance without `on` takes mesh vertices")
        return i

    def _dirs(self, normals, n):
        """Stratified cosine-weighted directions (P, n, 3) about each normal (Malley)."""
        p = normals.shape[0]
        k = int(np.sqrt(n))
        i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
        u1 = (i.ravel()[None] + self.rng.random((p, k * k))) / k
        u2 = (j.ravel()[None] + self.rng.random((p, k * k))) / k
        r, phi = np.sqrt(u1), 2 * np.pi * u2
        x, y, z = r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0.0, 1 - u1))
        a = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        t = np.cross(normals, a)
        t /= np.linalg.norm(t, axis=1, keepdims=True)
        b = np.cross(normals, t)
        return (x[..., None] * t[:, None] + y[..., None] * b[:, None]
                + z[..., None] * normals[:, None])

    def _cast(self, o, d):
        r = self.scene.run(o.astype(np.float32), d.astype(np.float32), output=1)
        return r["primID"].astype(np.int64), r["tfar"].astype(np.float64)

    def radiance(self, points, normals, albedo, bounce, n_dirs, on=None):
        """B_bounce (the bounce-th term alone, not cumulative) at points (P, 3) with normals and
        albedo (P,); ``n_dirs``: directions per level, outermost first (len ≥ bounce + 1); on:
        the face each point lies on (default: the points are vertices; any face using them)."""
        if on is None:
            first = np.full(len(self.v), -1, dtype=np.int64)
            first[self.f.ravel()] = np.repeat(np.arange(len(self.f)), 3)
            on = first[self._vertex_ids(points)]
        p = points.shape[0]
        nd = int(np.sqrt(n_dirs[0])) ** 2
        d = self._dirs(normals, n_dirs[0]).reshape(-1, 3)
        o = np.repeat(self.caster.offset_points(points, normals, self.eps, on)[0], nd, axis=0)
        prim, tfar = self._cast(o, d)
        miss = prim < 0
        if bounce == 0:
            val = np.where(miss, sh_basis(d, self.lmax) @ self.coeffs, 0.0)
            return albedo * val.reshape(p, nd).mean(1)
        hit = np.flatnonzero(~miss)
        front = np.einsum("ij,ij->i", d[hit], self.fn[prim[hit]]) < 0
        hit = hit[front]
        val = np.zeros(p * nd)
        if hit.size:
            x = o[hit] + tfar[hit, None] * d[hit]
            fv = self.f[prim[hit]]
            w = _barycentric(x, self.v[fv])
            nn = np.einsum("ij,ijk->ik", w, self.n[fv])
            nn /= np.linalg.norm(nn, axis=1, keepdims=True)
            rho = np.einsum("ij,ij->i", w, self.rho[fv])
            val[hit] = self.radiance(x, nn, rho, bounce - 1, n_dirs[1:], prim[hit])
        return albedo * val.reshape(p, nd).mean(1)


def _barycentric(x, tri):
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, x - a
    d00 = np.einsum("ij,ij->i", v0, v0)
    d01 = np.einsum("ij,ij->i", v0, v1)
    d11 = np.einsum("ij,ij->i", v1, v1)
    d20 = np.einsum("ij,ij->i", v2, v0)
    d21 = np.einsum("ij,ij->i", v2, v1)
    den = d00 * d11 - d01 * d01
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    return np.stack([1 - v - w, v, w], 1)
