"""The ``SHPROBE_lightmap`` glTF extension: directional lightmaps in a .glb, and the reference
evaluation every shader is tested against.

Habel & Wimmer 2010 ("Efficient Irradiance Normal Mapping", §4.2–4.3) cache directional
irradiance at the texels of a low-resolution texture on a second UV set, expressed in the
tangent frame of the normal map, and evaluate it per pixel with the normal-map normal (eq. 15:
E(n) = Σᵢ cᵢ Bᵢ(n)). This module fixes how such a lightmap lives in glTF 2.0.

The document
------------
* ``extensionsUsed`` lists ``"SHPROBE_lightmap"``; ``extensionsRequired`` does NOT, so a
  plain viewer still opens the scene (it simply ignores the lightmap).
* Every lightmapped primitive has the core attribute ``TEXCOORD_1`` (FLOAT VEC2), the lightmap
  UVs, and ``TANGENT`` (FLOAT VEC4): MikkTSpace of ``TEXCOORD_0``, as glTF requires for normal
  maps (a tangent the scene already had is kept), or the arbitrary frame below. A primitive
  that had no ``TEXCOORD_0`` gets the lightmap UVs as ``TEXCOORD_0`` too (glTF numbers a
  semantic's sets from 0 without gaps).
* The root object carries ``extensions.SHPROBE_lightmap``::

      {"version": 1,
       "encoding": "h6",              # one of ENCODINGS
       "coefficients": 6,             # N_COEFFS[encoding]
       "width": 256, "height": 256,   # texels
       "scale": 1.0,                  # stored value × scale = irradiance
       "quantity": "irradiance",      # E in the probe's radiance units × sr (E = π L under a
                                      # constant sky L); shade with albedo / π · E
       "textures": [{"bufferView": 7, "components": [[0, 0], [1, 0], [2, 0], [3, 0]]}, ...],
       "primitives": [{"mesh": 0, "primitive": 0}, ...],
       "frame": "tangent"}            # see "The texel frame"

  Optional keys a reader must ignore when unknown (``"samples"``, ``"bounces"``, ``"sun"``,
  ``"transfer"``, ...).

Transfer (relightable lightmaps)
--------------------------------
A lightmap baked with ``--transfer`` adds ``"transfer": {"sky_lmax": 2, "scale": s,
"sets": [{"textures": [...]}, ...]}`` with 9 sets, one per sky SH coefficient j (world frame,
flat index as above): set j's textures (same RGBA16F layout and ``components`` as the main
ones, stored value × s) hold T_j, the coefficients the texel would have under a sky of radiance
y_j(ω) in every colour channel, albedo colours, shadows and bounces included (Lisle & Huang
2007 §4 per texel). Under a sky with SH coefficients L_jc (per colour c) the coefficients are
Σ_j T_j[·, c] L_jc; a sun is not part of the transfer. An optional ``"sky"`` (9 × 3 numbers,
L_jc) is the sky the lightmap was baked under, which a viewer turns and relights with.
Writer and reader: ``shprobe.lightmaps.transfer_format`` (``add_transfer``, ``read_transfer``).

Coefficient textures
--------------------
Core glTF images must be PNG or JPEG, so the coefficient textures are raw data: each is one
``bufferView`` (no ``target``, in the GLB's BIN buffer) of ``width × height`` texels, each
texel 4 little-endian IEEE half floats (RGBA16F, 8 bytes), rows in order of increasing v
(row 0 is v ∈ [0, 1/height), i.e. the TOP of the glTF UV space; texel (r, c) has its centre
at u = (c + ½)/width, v = (r + ½)/height), no row padding. Uploaded as is (no flip) to WebGL
this matches glTF UVs directly. Sample with bilinear filtering and clamp-to-edge: the bake
dilates every chart so that no filter tap reads an empty texel.

``components`` names, for each of the 4 channels R, G, B, A of the texture, the pair
``[coefficient index i, colour c]`` (c = 0, 1, 2 for red, green, blue) it holds, or ``null``
(stored as 0). The writer's packing (`texture_layout`) is, per colour channel,
coefficients 4 to a texture: for colour c and j = 0 .. ⌈n/4⌉ − 1 the texture number
c·⌈n/4⌉ + j holds coefficients 4j .. 4j + 3 of colour c. So h6 has 6 textures (R: c0..c3,
R: c4 c5 – –, G: ..., B: ...), sh9 9, h4 / sh4 / hl2 3; ``plain`` (n = 1) is the exception:
one texture holding the red, green and blue irradiance in R, G, B (A null). A reader uses the
``components`` lists, which makes any packing legal.

The encodings and their bases
-----------------------------
All functions are of the unit normal n = (x, y, z) in the texel's tangent frame, z = the
surface normal (n = (0, 0, 1) is the unperturbed surface), and E(n) = Σᵢ cᵢ Bᵢ(n) per colour
(H&W eq. 15). Coefficient order is the order listed.

* ``plain`` (1): B₀ = 1 — irradiance at the geometric normal; the normal map is ignored.
* ``hl2`` (3): Half-Life 2's basis (H&W eq. 1–2), Bᵢ = √(3/2π) n·hᵢ with
  h₀ = (−1/√6, −1/√2, 1/√3), h₁ = (−1/√6, 1/√2, 1/√3), h₂ = (√(2/3), 0, 1/√3); orthonormal
  on the upper hemisphere, coefficients its least-squares projection there.
* ``sh4`` (2 bands, 4): real SH, R&H signs (docs/conventions.md), flat index k = l(l+1)+m:
  0.282095; 0.488603 y; 0.488603 z; 0.488603 x. Coefficients are the irradiance's own SH
  (R&H 2001 eq. 7: Ê_lm = Â_l L_lm) truncated to l ≤ 1.
* ``sh9`` (3 bands, 9): the above, then 1.092548 xy; 1.092548 yz; 0.315392 (3z² − 1);
  1.092548 xz; 0.546274 (x² − y²). Coefficients: irradiance SH, l ≤ 2.
* ``h4`` (4), ``h6`` (6): the H-basis, H&W eq. 8–13, orthonormal on the upper hemisphere:
  1/√(2π); −√(3/2π) y; √(3/2π)(2z − 1); −√(3/2π) x; √(15/2π) xy; ½√(15/2π)(x² − y²).
  Coefficients: T_h (H&W §4.1, shprobe.hbasis.sh_to_h_matrix) times the sh9 coefficients,
  h4 the first four of h6.

The bake gathers radiance once per texel, projects it into tangent-frame SH (l ≤ 2, zero
below the surface) and derives all six encodings from that one projection.

The texel frame
---------------
x = T (``TANGENT.xyz``), y = B = (N × T) · ``TANGENT.w``, z = N (``NORMAL``), at the texel's
surface point, interpolated from the vertices (H&W §4.3: the lightmap shares the normal map's
tangent space, so the shader passes the tangent-space normal-map normal straight to the
evaluation, no change of frame). A shader: n = normalize(normalTexture(uv0).xyz · 2 − 1, with
glTF's normal ``scale`` on x, y); E = evaluate(coefficients(uv1), n); colour = baseColor / π · E.
A primitive without a normal map evaluates at n = (0, 0, 1), so its frame's x and y do not
matter; without ``TEXCOORD_0`` the bake uses x = normalize(a × N) with a = (0, 1, 0), or
(1, 0, 0) where |N_y| > 0.9, and y = N × x.

Python reference
----------------
[`basis_values`][shprobe.lightmaps.basis_values] and [`evaluate`][shprobe.lightmaps.evaluate] are
the reference the GLSL/HLSL/WGSL functions are tested against; `add_lightmap` / `read_lightmap` put
a lightmap into / take it out of a glTF document (JSON dict + BIN bytes) and `encode_glb` /
`parse_glb` / `write_glb` / `read_glb` handle the container.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from .glb import encode_glb, parse_glb, read_glb, write_glb

#: the extension's name
EXTENSION = "SHPROBE_lightmap"
#: the extension version this module writes and reads
VERSION = 1
#: the encodings, cheapest first
ENCODINGS = ("plain", "hl2", "sh4", "sh9", "h4", "h6")
#: coefficients per colour channel of each encoding
N_COEFFS = {"plain": 1, "hl2": 3, "sh4": 4, "sh9": 9, "h4": 4, "h6": 6}

_S3 = math.sqrt(3.0 / (2.0 * math.pi))
_S15 = math.sqrt(15.0 / (2.0 * math.pi))
#: H&W eq. 1, the Half-Life 2 basis directions in the tangent frame (rows h₀, h₁, h₂)
HL2_DIRECTIONS = np.array([[-1 / math.sqrt(6), -1 / math.sqrt(2), 1 / math.sqrt(3)],
                           [-1 / math.sqrt(6), 1 / math.sqrt(2), 1 / math.sqrt(3)],
                           [math.sqrt(2 / 3), 0.0, 1 / math.sqrt(3)]])
HL2_DIRECTIONS.flags.writeable = False



def check_encoding(encoding: str) -> str:
    """The encoding's canonical name, or one [`ShprobeError`][shprobe.errors.ShprobeError] naming
    the known ones.

    Parameters
    ----------
    encoding : str
        An encoding name (case-insensitive).

    Returns
    -------
    str
        One of [`ENCODINGS`][shprobe.lightmaps.ENCODINGS].
    """
    e = str(encoding).lower()
    if e not in N_COEFFS:
        raise ShprobeError(f"unknown lightmap encoding {encoding!r}; known: {', '.join(ENCODINGS)}")
    return e


def basis_values(encoding: str, normals_tangent: ArrayLike) -> NDArray[np.float64]:
    """The encoding's basis functions at tangent-frame unit normals (z = surface normal).

    Parameters
    ----------
    encoding : str
        One of [`ENCODINGS`][shprobe.lightmaps.ENCODINGS].
    normals_tangent : array_like, shape (..., 3)
        Unit normals in the texel's tangent frame.

    Returns
    -------
    ndarray, shape (..., n)
        B₀..B_{n−1}(n) with n = ``N_COEFFS[encoding]``, in the order of the module docstring.
    """
    e = check_encoding(encoding)
    d = np.asarray(normals_tangent, dtype=np.float64)
    if d.ndim < 1 or d.shape[-1] != 3:
        raise ShprobeError(f"normals must have shape (..., 3), got {d.shape}")
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    if e == "plain":
        return np.ones((*d.shape[:-1], 1))
    if e == "hl2":
        return _S3 * (d @ HL2_DIRECTIONS.T)
    if e in ("h4", "h6"):
        cols = [np.full_like(x, 1.0 / math.sqrt(2.0 * math.pi)), -_S3 * y, _S3 * (2 * z - 1),
                -_S3 * x]
        if e == "h6":
            cols += [_S15 * x * y, 0.5 * _S15 * (x * x - y * y)]
        return np.stack(cols, axis=-1)
    cols = [np.full_like(x, 0.282095), 0.488603 * y, 0.488603 * z, 0.488603 * x]
    if e == "sh9":
        cols += [1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3 * z * z - 1),
                 1.092548 * x * z, 0.546274 * (x * x - y * y)]
    return np.stack(cols, axis=-1)


def evaluate(encoding: str, coeffs: ArrayLike, normals_tangent: ArrayLike) -> NDArray[np.float64]:
    """Irradiance E(n) = Σᵢ cᵢ Bᵢ(n) per colour (H&W 2010 eq. 15).

    Parameters
    ----------
    encoding : str
        One of [`ENCODINGS`][shprobe.lightmaps.ENCODINGS].
    coeffs : array_like, shape (..., n, C)
        Coefficients (n on axis −2, colours last), already multiplied by the file's scale.
    normals_tangent : array_like, shape (..., 3)
        Tangent-frame unit normals; leading axes broadcast against the coefficients'.

    Returns
    -------
    ndarray, shape (..., C)
        The irradiance.
    """
    e = check_encoding(encoding)
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim < 2 or c.shape[-2] != N_COEFFS[e]:
        raise ShprobeError(f"{e} coefficients must be (..., {N_COEFFS[e]}, C), got {c.shape}")
    return np.einsum("...i,...ic->...c", basis_values(e, normals_tangent), c)


def texture_layout(encoding: str) -> list[list[tuple[int, int] | None]]:
    """The writer's packing: per texture, the (coefficient, colour) held by R, G, B, A.

    Parameters
    ----------
    encoding : str
        One of [`ENCODINGS`][shprobe.lightmaps.ENCODINGS].

    Returns
    -------
    list of list
        One entry per texture, each 4 items (coefficient index, colour) or None.
    """
    n = N_COEFFS[check_encoding(encoding)]
    if n == 1:
        return [[(0, 0), (0, 1), (0, 2), None]]
    per = -(-n // 4)
    out = []
    for c in range(3):
        for j in range(per):
            out.append([(i, c) if i < n else None for i in range(4 * j, 4 * j + 4)])
    return out


def pack(encoding: str, coeffs: ArrayLike,
         layout: list[list[tuple[int, int] | None]] | None = None) -> list[NDArray[np.float16]]:
    """Coefficient images (H, W, n, 3) → RGBA16F textures (H, W, 4) in ``layout`` order.

    Parameters
    ----------
    encoding : str
        One of [`ENCODINGS`][shprobe.lightmaps.ENCODINGS].
    coeffs : array_like, shape (H, W, n, 3)
        Stored values (irradiance divided by the scale); must be finite and within half range.
    layout : list, optional
        Packing; default `texture_layout`.

    Returns
    -------
    list of ndarray
        float16 textures, row 0 at v = 0.
    """
    e = check_encoding(encoding)
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim != 4 or c.shape[2:] != (N_COEFFS[e], 3):
        raise ShprobeError(f"{e} coefficient images must be (H, W, {N_COEFFS[e]}, 3), "
                           f"got {c.shape}")
    if not np.isfinite(c).all() or (c.size and np.abs(c).max() > 65504.0):
        raise ShprobeError("lightmap coefficients are not finite or exceed the half-float range")
    out = []
    for tex in layout or texture_layout(e):
        t = np.zeros((*c.shape[:2], 4), np.float16)
        for ch, ic in enumerate(tex):
            if ic is not None:
                t[..., ch] = c[:, :, ic[0], ic[1]]
        out.append(t)
    return out


def unpack(encoding: str, textures: list[NDArray],
           layout: list[list[tuple[int, int] | None]] | None = None) -> NDArray[np.float32]:
    """RGBA16F textures → coefficient images (H, W, n, 3) float32 (inverse of `pack`).

    Parameters
    ----------
    encoding : str
        One of [`ENCODINGS`][shprobe.lightmaps.ENCODINGS].
    textures : list of ndarray, each (H, W, 4)
        The textures in ``layout`` order.
    layout : list, optional
        Packing; default `texture_layout`.

    Returns
    -------
    ndarray, shape (H, W, n, 3)
        The stored values (multiply by the scale for irradiance).
    """
    e = check_encoding(encoding)
    layout = layout or texture_layout(e)
    if len(textures) != len(layout) or not textures:
        raise ShprobeError(f"{e} needs {len(layout)} textures, got {len(textures)}")
    h, w = textures[0].shape[:2]
    out = np.zeros((h, w, N_COEFFS[e], 3), np.float32)
    seen = np.zeros((N_COEFFS[e], 3), bool)
    for t, tex in zip(textures, layout, strict=True):
        for ch, ic in enumerate(tex):
            if ic is not None:
                out[:, :, ic[0], ic[1]] = t[..., ch]
                seen[ic] = True
    if not seen.all():
        raise ShprobeError(f"the {e} textures do not hold every coefficient of every colour")
    return out


@dataclass(frozen=True)
class StoredLightmap:
    """A lightmap as a glTF document holds it (see the module docstring).

    Parameters
    ----------
    encoding : str
        One of [`ENCODINGS`][shprobe.lightmaps.ENCODINGS].
    coeffs : ndarray, shape (H, W, n, 3)
        Irradiance coefficients (already multiplied by ``scale``), float32.
    scale : float
        The stored-value multiplier written in the file.
    primitives : list of (mesh, primitive)
        The primitives that use ``TEXCOORD_1``.
    extra : dict
        Any other keys of the extension object.
    """

    encoding: str
    coeffs: NDArray[np.float32] = field(repr=False)
    scale: float = 1.0
    primitives: tuple[tuple[int, int], ...] = ()
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


def choose_scale(coeffs: ArrayLike) -> float:
    """A power of two keeping every stored value ≤ 16384 in magnitude (half-float headroom).

    Parameters
    ----------
    coeffs : array_like
        The coefficients to store.

    Returns
    -------
    float
        1.0 unless the values are large.
    """
    m = float(np.abs(np.asarray(coeffs)).max(initial=0.0))
    return 1.0 if m <= 16384.0 else float(2.0 ** math.ceil(math.log2(m / 16384.0)))


def add_lightmap(doc: dict, binary: bytearray, encoding: str, coeffs: ArrayLike,
                 primitives: list[tuple[int, int]], extra: dict | None = None) -> dict:
    """Add a lightmap to a glTF document in place: bufferViews appended to ``binary``.

    Parameters
    ----------
    doc : dict
        The glTF JSON (with one buffer, the GLB BIN chunk, or none yet).
    binary : bytearray
        The BIN chunk, extended in place (4-byte aligned).
    encoding : str
        One of [`ENCODINGS`][shprobe.lightmaps.ENCODINGS].
    coeffs : array_like, shape (H, W, n, 3)
        Irradiance coefficients.
    primitives : list of (mesh, primitive)
        The primitives that carry ``TEXCOORD_1``.
    extra : dict, optional
        Further keys for the extension object.

    Returns
    -------
    dict
        The extension object written.
    """
    e = check_encoding(encoding)
    c = np.asarray(coeffs, dtype=np.float64)
    scale = choose_scale(c)
    textures = add_textures(doc, binary, e, c, scale)
    ext = {"version": VERSION, "encoding": e, "coefficients": N_COEFFS[e],
           "width": int(c.shape[1]), "height": int(c.shape[0]), "scale": scale,
           "quantity": "irradiance", "frame": "tangent", "textures": textures,
           "primitives": [{"mesh": int(m), "primitive": int(p)} for m, p in primitives],
           **(extra or {})}
    doc.setdefault("extensions", {})[EXTENSION] = ext
    used = doc.setdefault("extensionsUsed", [])
    if EXTENSION not in used:
        used.append(EXTENSION)
    return ext


def read_lightmap(doc: dict, binary: bytes, where: Any = None) -> StoredLightmap:
    """The lightmap of a glTF document (inverse of `add_lightmap`).

    Parameters
    ----------
    doc : dict
        The glTF JSON.
    binary : bytes
        The GLB BIN chunk.
    where : str, optional
        The file, for error messages.

    Returns
    -------
    StoredLightmap
        Encoding, coefficients × scale, primitives and the other keys.
    """
    ext = doc.get("extensions", {}).get(EXTENSION)
    if not isinstance(ext, dict):
        raise ShprobeError(f"has no {EXTENSION} extension: not a shprobe lightmap", where)
    try:
        e = check_encoding(ext["encoding"])
        w, h, scale = int(ext["width"]), int(ext["height"]), float(ext["scale"])
        layout = [[None if ic is None else (int(ic[0]), int(ic[1])) for ic in t["components"]]
                  for t in ext["textures"]]
        views = [doc["bufferViews"][int(t["bufferView"])] for t in ext["textures"]]
        prims = tuple((int(p["mesh"]), int(p["primitive"])) for p in ext.get("primitives", []))
    except (KeyError, IndexError, TypeError, ValueError):
        raise ShprobeError(f"its {EXTENSION} object is malformed", where) from None
    if ext.get("version", VERSION) > VERSION:
        raise ShprobeError(f"{EXTENSION} version {ext['version']} is newer than this reader",
                           where)
    if not (0 < w < 65536 and 0 < h < 65536) or not math.isfinite(scale) or scale <= 0:
        raise ShprobeError(f"{EXTENSION} size {w}×{h} or scale {scale} is invalid", where)
    textures = []
    for v in views:
        start, length = int(v.get("byteOffset", 0)), int(v["byteLength"])
        if length != w * h * 8 or start + length > len(binary):
            raise ShprobeError(f"a {EXTENSION} texture is not {w}×{h} RGBA16F inside the "
                               "buffer (truncated?)", where)
        textures.append(np.frombuffer(binary, "<f2", w * h * 4, start).reshape(h, w, 4))
    coeffs = unpack(e, textures, layout) * np.float32(scale)
    if not np.isfinite(coeffs).all():
        raise ShprobeError(f"{EXTENSION} textures hold NaN or infinite values", where)
    known = {"version", "encoding", "coefficients", "width", "height", "scale", "textures",
             "primitives"}
    return StoredLightmap(e, coeffs, scale, prims, {k: v for k, v in ext.items()
                                                    if k not in known})


def add_textures(doc: dict, binary: bytearray, encoding: str, coeffs: NDArray,
                 scale: float) -> list[dict]:
    """Append the RGBA16F textures of coefficient images (H, W, n, 3) / ``scale`` to
    ``binary`` as bufferViews (writer's packing).

    Parameters
    ----------
    doc : dict
        The glTF JSON (bufferViews appended, buffer 0's length updated).
    binary : bytearray
        The BIN chunk, extended in place.
    encoding : str
        One of [`ENCODINGS`][shprobe.lightmaps.ENCODINGS].
    coeffs : ndarray (H, W, n, 3)
        Coefficients.
    scale : float
        Their divisor.

    Returns
    -------
    list of dict
        The ``textures`` entries (bufferView, components).
    """
    layout = texture_layout(encoding)
    views = doc.setdefault("bufferViews", [])
    textures = []
    for t, tex in zip(pack(encoding, coeffs / scale, layout), layout, strict=True):
        binary.extend(b"\0" * (-len(binary) % 4))
        data = np.ascontiguousarray(t).astype("<f2").tobytes()
        views.append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(data)})
        binary.extend(data)
        textures.append({"bufferView": len(views) - 1,
                         "components": [None if ic is None else list(ic) for ic in tex]})
    binary.extend(b"\0" * (-len(binary) % 4))
    doc.setdefault("buffers", [{}])[0]["byteLength"] = len(binary)
    return textures


__all__ = ["ENCODINGS", "EXTENSION", "HL2_DIRECTIONS", "N_COEFFS", "VERSION", "StoredLightmap",
           "add_lightmap", "add_textures", "basis_values", "check_encoding", "choose_scale",
           "encode_glb", "evaluate", "pack", "parse_glb", "read_glb", "read_lightmap",
           "texture_layout", "unpack", "write_glb"]
