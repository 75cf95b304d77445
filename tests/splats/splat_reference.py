"""The 3DGS reference renderer's colour, written here from its published constants.

``computeColorFromSH`` of graphdeco-inria/diff-gaussian-rasterization (forward.cu): the SH
constants below (with their signs) and the view direction dir = normalize(splat − camera);
the result + 0.5, clamped at 0. Independent of shprobe: no shprobe import.
"""

from __future__ import annotations

import numpy as np

SH_C0 = 0.28209479177387814
SH_C1 = 0.4886025119029199
SH_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005,
         -1.0925484305920792, 0.5462742152960396)
SH_C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
         -0.4570457994644658, 1.445305721320277, -0.5900435899266435)


def colour(sh: np.ndarray, position: np.ndarray, camera: np.ndarray) -> np.ndarray:
    """sh (N, K, 3), position (N, 3), camera (N, 3) or (3,) → RGB (N, 3), as the renderer."""
    sh = np.asarray(sh, dtype=np.float64)
    d = np.asarray(position, dtype=np.float64) - np.asarray(camera, dtype=np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    x, y, z = (d[:, i : i + 1] for i in range(3))
    deg = round(np.sqrt(sh.shape[1])) - 1
    r = SH_C0 * sh[:, 0]
    if deg > 0:
        r = r - SH_C1 * y * sh[:, 1] + SH_C1 * z * sh[:, 2] - SH_C1 * x * sh[:, 3]
        if deg > 1:
            xx, yy, zz, xy, yz, xz = x * x, y * y, z * z, x * y, y * z, x * z
            r = (r + SH_C2[0] * xy * sh[:, 4] + SH_C2[1] * yz * sh[:, 5]
                 + SH_C2[2] * (2.0 * zz - xx - yy) * sh[:, 6]
                 + SH_C2[3] * xz * sh[:, 7] + SH_C2[4] * (xx - yy) * sh[:, 8])
            if deg > 2:
                r = (r + SH_C3[0] * y * (3.0 * xx - yy) * sh[:, 9]
                     + SH_C3[1] * xy * z * sh[:, 10]
                     + SH_C3[2] * y * (4.0 * zz - xx - yy) * sh[:, 11]
                     + SH_C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy) * sh[:, 12]
                     + SH_C3[4] * x * (4.0 * zz - xx - yy) * sh[:, 13]
                     + SH_C3[5] * z * (xx - yy) * sh[:, 14]
                     + SH_C3[6] * x * (xx - 3.0 * yy) * sh[:, 15])
    return np.maximum(r + 0.5, 0.0)


def quat_matrix(q: np.ndarray) -> np.ndarray:
    """The renderer's rotation matrix of (w, x, y, z) quaternions (normalised first)."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def covariance(q: np.ndarray, log_scales: np.ndarray) -> np.ndarray:
    """Σ = R S Sᵀ Rᵀ with S = diag(exp(scale)) (the renderer's computeCov3D)."""
    r = quat_matrix(q)
    s = np.exp(np.asarray(log_scales, dtype=np.float64))
    if s.shape[1] == 2:
        s = np.concatenate([s, np.zeros((s.shape[0], 1))], axis=1)
    return np.einsum("nij,nj,nkj->nik", r, s * s, r)


def random_splats(n: int, degree: int = 3, seed: int = 0, scales: int = 3) -> dict:
    """Random splats as plain arrays (trainer conventions): pos, log_scales, rot (w first),
    opacity logit, sh (N, K, 3) with sh[:, 0] = f_dc."""
    rng = np.random.default_rng(seed)
    k = (degree + 1) ** 2
    return {"pos": rng.normal(size=(n, 3)).astype(np.float32) * 2,
            "log_scales": (rng.normal(size=(n, scales)) - 3).astype(np.float32),
            "rot": rng.normal(size=(n, 4)).astype(np.float32),
            "opacity": rng.normal(size=n).astype(np.float32),
            "sh": (rng.normal(size=(n, k, 3)) * 0.3).astype(np.float32)}


def write_trainer_ply(path, s: dict, fmt: str = "binary_little_endian") -> None:
    """A PLY laid out as graphdeco-inria's save_ply writes it (written here with numpy alone):
    x y z nx ny nz f_dc_0..2 f_rest_* (channel-major) opacity scale_* rot_0..3, all float."""
    n, k = s["sh"].shape[:2]
    nscale = s["log_scales"].shape[1]
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    names += [f"f_rest_{i}" for i in range(3 * (k - 1))] + ["opacity"]
    names += [f"scale_{i}" for i in range(nscale)] + [f"rot_{i}" for i in range(4)]
    end = "<" if fmt == "binary_little_endian" else ">"
    rec = np.zeros(n, dtype=[(nm, end + "f4") for nm in names])
    for i, c in enumerate("xyz"):
        rec[c] = s["pos"][:, i]
    for c in range(3):
        rec[f"f_dc_{c}"] = s["sh"][:, 0, c]
    rest = s["sh"][:, 1:, :].transpose(0, 2, 1).reshape(n, 3 * (k - 1))  # channel-major
    for i in range(rest.shape[1]):
        rec[f"f_rest_{i}"] = rest[:, i]
    rec["opacity"] = s["opacity"]
    for i in range(nscale):
        rec[f"scale_{i}"] = s["log_scales"][:, i]
    for i in range(4):
        rec[f"rot_{i}"] = s["rot"][:, i]
    head = ["ply", f"format {fmt} 1.0", f"element vertex {n}"]
    head += [f"property float {nm}" for nm in names] + ["end_header"]
    with open(path, "wb") as f:
        f.write(("\n".join(head) + "\n").encode())
        f.write(rec.tobytes())


def read_trainer_ply(path) -> dict:
    """The arrays of a trainer-layout PLY (little-endian floats), read with numpy alone."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    lines = data[:end].decode().splitlines()
    n = int(next(ln.split()[2] for ln in lines if ln.startswith("element vertex")))
    names = [ln.split()[2] for ln in lines if ln.startswith("property")]
    types = {"float": "<f4", "double": "<f8", "uchar": "u1"}
    dtype = [(ln.split()[2], types[ln.split()[1]]) for ln in lines if ln.startswith("property")]
    rec = np.frombuffer(data, dtype=dtype, count=n, offset=end)
    rest = sorted((nm for nm in names if nm.startswith("f_rest_")), key=lambda x: int(x[7:]))
    k = len(rest) // 3 + 1
    sh = np.zeros((n, k, 3), np.float32)
    for c in range(3):
        sh[:, 0, c] = rec[f"f_dc_{c}"]
        for j in range(k - 1):
            sh[:, j + 1, c] = rec[f"f_rest_{c * (k - 1) + j}"]
    nscale = sum(1 for nm in names if nm.startswith("scale_"))
    return {"pos": np.stack([rec[c] for c in "xyz"], 1),
            "log_scales": np.stack([rec[f"scale_{i}"] for i in range(nscale)], 1),
            "rot": np.stack([rec[f"rot_{i}"] for i in range(4)], 1),
            "opacity": np.array(rec["opacity"]), "sh": sh, "names": names}
