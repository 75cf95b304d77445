"""Lighting from images of any diffuse object of known shape: per-pixel normals (a G-buffer
normal map), or a mesh seen by cameras (normals from the renderer's ray caster), optionally
with the albedo per vertex fitted jointly (up to the usual global scale)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..scene import Camera, trace
from .document import FitDocument
from .solve import FitSettings, LightingFit, fit_samples

if TYPE_CHECKING:
    pass

__all__ = ["ObjectFit", "fit_mesh", "fit_normals", "read_normal_map"]


@dataclass(repr=False)
class ObjectFit(FitDocument):
    """The fit ([`LightingFit`][shprobe.fitting.LightingFit], world-frame coefficients) and where
    its pixels came from: ``views`` list of (rows, cols) per image, ``shapes`` per image,
    ``normals`` (P, 3) of all views' pixels in order; ``vertex_albedo``
    (V, 3) when fitted jointly (mean 1 over the seen regions: the global scale is in the
    coefficients).

    Attributes
    ----------
    fit
        The lighting fit, world-frame coefficients.
    views
        (rows, cols) of the pixels used, per image.
    shapes
        Each image's (H, W).
    normals
        (P, 3) the pixels' normals, all views in order.
    vertex_albedo
        (V, 3) the albedo fitted jointly, or None.
    info
        Further figures about the fit.
    """

    fit: LightingFit
    views: list[tuple[NDArray[np.intp], NDArray[np.intp]]]
    shapes: list[tuple[int, int]]
    normals: NDArray[np.float64]
    vertex_albedo: NDArray[np.float64] | None = None
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def coeffs(self) -> NDArray[np.float64]:
        return self.fit.coeffs

    def image(self, values: NDArray, view: int = 0) -> NDArray[np.float32]:
        """Per-pixel values (P,) / (P, C) of all views scattered into view ``view``'s image.

        Parameters
        ----------
        values
            (P,) or (P, C) per-pixel values of all views.
        view
            The view whose image is made.

        Returns
        -------
        ndarray of shape (H, W) or (H, W, C), float32
            That view's values in their pixels, 0 elsewhere.
        """
        v = np.asarray(values)
        start = sum(r.size for r, _ in self.views[:view])
        rows, cols = self.views[view]
        out = np.zeros((*self.shapes[view], *v.shape[1:]), dtype=np.float32)
        out[rows, cols] = v[start:start + rows.size]
        return out

    def summary(self) -> str:
        s = f"{len(self.views)} view(s): {self.fit.summary()}"
        if self.vertex_albedo is not None:
            s += f"; per-vertex albedo fitted ({self.info.get('albedo_iterations', 0)} rounds)"
        return s

    def __repr__(self) -> str:
        return f"ObjectFit({len(self.views)} views, {self.fit!r})"


def _photo(img: ArrayLike, what: str) -> NDArray[np.float32]:
    a = np.asarray(img, dtype=np.float32)
    if a.ndim == 2:
        a = np.repeat(a[:, :, None], 3, axis=2)
    if a.ndim != 3 or a.shape[2] < 3:
        raise ShprobeError(f"{what} must be an (H, W, 3) image, got shape {a.shape}")
    if not np.all(np.isfinite(a[..., :3])):
        raise ShprobeError(f"{what} has NaN or infinite pixels")
    return a[..., :3]


def fit_normals(image: ArrayLike, normals: ArrayLike, mask: ArrayLike | None = None, *,
                albedo: ArrayLike | float = 1.0, saturation: float | None = None,
                robust: bool = True) -> ObjectFit:
    """Lighting from an image (H, W, 3) and per-pixel normals (H, W, 3) in the lighting's
    frame (e.g. a G-buffer). Pixels with a zero normal, or outside ``mask``, are background;
    NaN or infinite normals are refused. ``albedo``: a number, or a known (H, W[, 3]) albedo
    image.

    Parameters
    ----------
    image
        (H, W, 3) linear image.
    normals
        (H, W, 3) normals in the lighting's frame; zero marks background.
    mask
        (H, W) pixels to use.
    albedo
        A number, or a known (H, W[, 3]) albedo image.
    saturation
        Pixels with a channel at or above it are left out.
    robust
        Reject outliers (IRLS) rather than fit plain least squares.

    Returns
    -------
    ObjectFit
        The lighting fit.
    """
    img = _photo(image, "image")
    n = np.asarray(normals, dtype=np.float64)
    if n.shape[:2] != img.shape[:2] or n.ndim != 3 or n.shape[2] < 3:
        raise ShprobeError(f"normal map {n.shape} does not match the image {img.shape}")
    n = n[..., :3]
    _check_normals(n)
    ln = np.linalg.norm(n, axis=-1)
    valid = ln > 0.5
    if mask is not None:
        valid &= np.asarray(mask, bool)
    rows, cols = np.nonzero(valid)
    if rows.size == 0:
        raise ShprobeError("the normal map holds no normals (all zero): nothing to fit")
    dirs = n[rows, cols] / ln[rows, cols, None]
    a = np.asarray(albedo, dtype=np.float64)
    alb = a if a.ndim == 0 else a.reshape(*img.shape[:2], -1)[rows, cols]
    fit = fit_samples(dirs, img[rows, cols], albedo=alb, saturation=saturation, black=0.0,
                      robust=robust)
    return ObjectFit(fit, [(rows, cols)], [img.shape[:2]], dirs)


def fit_mesh(images: ArrayLike | Sequence[ArrayLike], mesh, cameras: Camera | Sequence[Camera],
             *, albedo: ArrayLike | float | str = 1.0, groups: ArrayLike | None = None,
             saturation: float | None = None, robust: bool = True,
             albedo_rounds: int = 50) -> ObjectFit:
    """Lighting from one or more images of ``mesh`` (trimesh, or None for the unit sphere)
    taken by ``cameras`` (the renderer's [`Camera`][shprobe.scene.Camera], one per image, image size
    = camera size). Normals are the smooth shading normals the renderer shades with.

    ``albedo``: a number; a (V,) / (V, 3) known per-vertex albedo; ``"vertex"`` to fit an
    albedo per vertex jointly, or ``"groups"`` to fit one albedo per label of ``groups`` (V,)
    (integer labels per vertex: regions of constant albedo). Alternating least squares
    (lighting given albedo: the nine coefficients; albedo given lighting: a sparse
    least-squares problem per channel, barycentric weights × shading), albedo normalised to
    mean 1 over the seen regions so the one global scale stays in the coefficients; regions
    no pixel sees keep albedo 1.

    Identifiability: an albedo that is a function of the normal, ρ(n) = E(n)/E'(n), explains
    the images under any other lighting E' — so a per-vertex albedo is determined only where
    the same normal recurs on differently-coloured vertices (several views do not help on a
    convex object). Regions that each span many normals are well determined; the fit's
    ``info['albedo_change']`` reports the last round's change.

    Parameters
    ----------
    images
        One (H, W, 3) linear image or a sequence of them.
    mesh
        A trimesh mesh, or None for the unit sphere.
    cameras
        The renderer's ``Camera`` of each image (image size = camera size).
    albedo
        A number, a known (V,) / (V, 3) per-vertex albedo, "vertex" or "groups" to fit it.
    groups
        (V,) integer labels of constant-albedo regions (with ``albedo="groups"``).
    saturation
        Pixels with a channel at or above it are left out.
    robust
        Reject outliers (IRLS) rather than fit plain least squares.
    albedo_rounds
        Alternating least-squares rounds when the albedo is fitted.

    Returns
    -------
    ObjectFit
        The lighting fit and, when fitted, the albedo.
    """
    imgs = [images] if isinstance(images, np.ndarray) and np.ndim(images) == 3 else list(images)
    cams = [cameras] if isinstance(cameras, Camera) else list(cameras)
    if len(imgs) != len(cams):
        raise ShprobeError(f"{len(imgs)} images but {len(cams)} cameras")
    views, shapes, dirs, vals, faces, barys = [], [], [], [], [], []
    for i, (im, cam) in enumerate(zip(imgs, cams, strict=True)):
        img = _photo(im, f"image {i}")
        if img.shape[:2] != (cam.height, cam.width):
            raise ShprobeError(f"image {i} is {img.shape[1]}x{img.shape[0]} but its camera is "
                               f"{cam.width}x{cam.height}")
        hits = trace(mesh, cam)
        hit = (hits.face >= 0).reshape(img.shape[:2])
        rows, cols = np.nonzero(hit)
        flat = rows * img.shape[1] + cols
        views.append((rows, cols))
        shapes.append(img.shape[:2])
        dirs.append(np.asarray(hits.normal[flat], np.float64))
        vals.append(img[rows, cols])
        faces.append(hits.face[flat])
        barys.append(hits.bary[flat])
    d = np.concatenate(dirs)
    y = np.concatenate(vals)
    if d.shape[0] == 0:
        raise ShprobeError("the camera sees nothing of the mesh (no pixel hits it): nothing "
                           "to fit")
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-30)
    if isinstance(albedo, str):
        if albedo not in ("vertex", "groups"):
            raise ShprobeError(f"albedo must be a number, per-vertex values, 'vertex' or "
                               f"'groups', got {albedo!r}")
        if mesh is None:
            raise ShprobeError("fitting the albedo needs a mesh (not the analytic sphere)")
        nv = len(mesh.vertices)
        if albedo == "vertex":
            lab = np.arange(nv)
        else:
            if groups is None:
                raise ShprobeError("albedo='groups' needs groups: one integer label per vertex")
            lab = np.asarray(groups)
            if lab.shape != (nv,) or lab.dtype.kind not in "iu" or lab.min() < 0:
                raise ShprobeError(f"groups must be {nv} non-negative integer labels, got "
                                   f"shape {lab.shape}")
        return _fit_albedo((d, y, np.concatenate(faces), np.concatenate(barys)), mesh, lab,
                           (views, shapes),
                           FitSettings(saturation=saturation, black=0.0, robust=robust),
                           albedo_rounds)
    a = np.asarray(albedo, dtype=np.float64)
    if a.ndim >= 1 and a.shape[0] != (0 if mesh is None else len(mesh.vertices)):
        raise ShprobeError(f"per-vertex albedo needs one row per vertex, got shape {a.shape}")
    if a.ndim >= 1:
        B = _bary_matrix(np.concatenate(faces), np.concatenate(barys), mesh)
        a = B @ a.reshape(len(mesh.vertices), -1)
    fit = fit_samples(d, y, albedo=a if a.ndim else float(a), saturation=saturation,
                      black=0.0, robust=robust)
    return ObjectFit(fit, views, shapes, d)


def _bary_matrix(face: NDArray, bary: NDArray, mesh):
    """Sparse (P, V): pixel value = Σ barycentric weight × vertex value."""
    from scipy import sparse

    tri = np.asarray(mesh.faces)[face]
    P = face.size
    return sparse.csr_matrix((np.asarray(bary, np.float64).ravel(),
                              (np.repeat(np.arange(P), 3), tri.ravel())),
                             shape=(P, len(mesh.vertices)))


def _fit_albedo(samples, mesh, labels, seen_by, settings: FitSettings, rounds: int):
    """The joint fit of lighting and albedo (`fit_object`'s alternating least squares):
    ``samples`` = (normals, values, faces, barycentrics) of the pixels, ``seen_by`` = (views,
    shapes) of the images."""
    d, y, face, bary = samples
    views, shapes = seen_by
    robust = settings.robust
    from scipy import sparse
    from scipy.sparse import diags
    from scipy.sparse.linalg import spsolve

    G = int(labels.max()) + 1
    S = sparse.csr_matrix((np.ones(labels.size), (np.arange(labels.size), labels)),
                          shape=(labels.size, G))
    B = (_bary_matrix(face, bary, mesh) @ S).tocsr()  # (P, G)
    V = G
    C = y.shape[1]
    seen = np.asarray(B.sum(axis=0)).ravel() > 0
    rho = np.ones((V, C))
    fit = None
    w = np.ones(y.shape[0])
    for it in range(1, rounds + 1):
        rp = np.maximum(B @ rho, 1e-6)
        # the robust fit picks the outliers once; later rounds reuse its weights
        fit = fit_samples(d, y, replace(settings, robust=robust and it == 1), albedo=rp,
                          weights=None if it == 1 else w)
        w = fit.weights.astype(np.float64) * ~fit.clipped
        shade = fit.fitted / np.maximum(rp, 1e-6)  # A·L per pixel and channel
        new = np.ones((V, C))
        for c in range(C):
            M = diags(shade[:, c] * np.sqrt(w)) @ B
            N = (M.T @ M).tocsc()
            lam = 1e-6 * float(N.diagonal().max() or 1.0)
            rhs = M.T @ (y[:, c] * np.sqrt(w)) + lam
            new[:, c] = spsolve(N + lam * diags(np.ones(V)), rhs)
        new = np.maximum(new, 1e-6)
        new[seen] /= new[seen].mean(axis=0)
        new[~seen] = 1.0
        change = float(np.abs(new - rho).max())
        rho = new
        if change < 1e-5:
            break
    rp = np.maximum(B @ rho, 1e-6)
    fit = fit_samples(d, y, settings, albedo=rp)
    out = ObjectFit(fit, views, shapes, d, vertex_albedo=rho[labels])
    out.info.update(albedo_iterations=it, albedo_change=change, groups=G)
    return out


def read_normal_map(path) -> NDArray[np.float32]:
    """A float normal map (H, W, 3) as stored (.exr .tif .pfm; signed values kept, unlike
    [`shprobe.probes.images.read_image`][shprobe.probes.images.read_image], which refuses negative
    pixels).

    Parameters
    ----------
    path
        A float image (.exr, .tif, .pfm).

    Returns
    -------
    ndarray of shape (H, W, 3), float32
        The normals as stored, signed.
    """
    import os

    p = os.fspath(path)
    ext = os.path.splitext(p)[1].lower()
    if ext not in (".exr", ".pfm", ".tif", ".tiff"):
        raise ShprobeError("normal map must be a float image (.exr .pfm .tif) holding the "
                           "normals themselves", p)
    if not os.path.isfile(p):
        raise ShprobeError("no such file", p)
    if ext == ".pfm":
        from pathlib import Path

        from ..probes.codecs import read_pfm

        a = read_pfm(Path(p))
    else:
        import OpenImageIO as oiio

        inp = oiio.ImageInput.open(p)
        if inp is None:
            raise ShprobeError(f"cannot read normal map: {oiio.geterror().strip()}", p)
        try:
            a = inp.read_image("float")
        finally:
            inp.close()
    a = np.asarray(a, np.float32)
    if a is None or a.ndim != 3 or a.shape[2] < 3:
        raise ShprobeError("normal map must have 3 channels", p)
    _check_normals(a[..., :3], p)
    return a[..., :3]


def _check_normals(n: NDArray, path=None) -> None:
    """Refuse NaN or infinite normals (background is a zero normal, not a missing one)."""
    bad = int(np.count_nonzero(~np.all(np.isfinite(n), axis=-1)))
    if bad:
        raise ShprobeError(f"normal map has {bad} pixels with NaN or infinite normals "
                           "(mark background with zero normals)", path)
