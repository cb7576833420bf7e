r"""Albedo textures: images stored flat, per-triangle texture coordinates, and the lookup kernels use.

A textured triangle's diffuse albedo at a point is ``albedo[f] * T(u, v)``: the triangle's colour
(MTL ``Kd``, glTF ``baseColorFactor``) times the texture's bilinearly filtered, sRGB-decoded value at
the point's texture coordinates (both formats multiply the two). Coordinates follow the OBJ convention:
``v = 0`` is the image's bottom row; both repeat outside [0, 1). Texels are decoded to linear RGB
once, when the image is read, so the filter blends linear values.

Kernels take one tuple, :meth:`TextureSet.kernel_data`, and call :func:`albedo_at` where they read a
hit's albedo. Without textures every array in it is empty and :func:`albedo_at` returns
``albedo[f]`` after one length test, so a scene without textures pays nothing measurable. The
texture coordinates of a point come from a per-triangle affine map (:func:`uv_maps`): the point's
barycentric coordinates are two dot products with the triangle's dual edge vectors, so a kernel
needs only the hit point, not the caster's barycentrics.

Any finite texture coordinate gives its texel: coordinates are reduced to [0, 1) in float64 (``u -
floor(u)``, exact) before any conversion to an integer, per triangle when the uv maps are made and
again in the lookup, so ``u = 3e18`` reads the texel ``u = 0`` does. Images are checked from their
header before they are decoded: at most ``MAX_TEXELS`` texels each and ``MAX_SCENE_TEXELS`` in all
(lightcuts.limits, :class:`TexelBudget`).
"""

from __future__ import annotations

import io
import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_SCENE_TEXELS, MAX_TEXELS
from lightcuts.scene.files import regular_file

#: Columns of a triangle's uv map (:func:`uv_maps`): corner 0, d(u)/dx, d(v)/dx, (u, v) at corner 0 in [0, 1).
UV_P0, UV_GU, UV_GV, UV_0 = 0, 3, 6, 9
UV_COLUMNS = 11
#: Columns of the texture table: first texel row, width, height.
TEX_OFFSET, TEX_WIDTH, TEX_HEIGHT = 0, 1, 2


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function inverted (IEC 61966-2-1): encoded values in [0, 1] -> linear."""
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


class TexelBudget:
    """The texels one scene has read so far, against ``MAX_SCENE_TEXELS``: every image read for a
    scene takes its share before it is decoded (an image two meshes use is stored twice, so counts
    twice)."""

    def __init__(self):
        self.used = 0

    def take(self, n: int, where: str) -> None:
        if self.used + n > MAX_SCENE_TEXELS:
            raise LightcutsError(f"{where}: its {n:,} texels bring the scene's textures to {self.used + n:,}, "
                                 f"more than the {MAX_SCENE_TEXELS:,} a scene may have")
        self.used += n


def read_image(source, where: str, budget: TexelBudget | None = None) -> np.ndarray:
    """(H, W, 3) float32 linear RGB of an 8-bit image (PNG, JPEG, ...: what Pillow reads), from a file
    path or the bytes of one, sRGB-decoded; greyscale is grey, alpha is dropped.

    The size comes from the header and is checked (``MAX_TEXELS``, then ``budget``) before the
    pixels are decoded. Every problem is one LightcutsError ``<where>: <problem>``: ``where``
    names the image (the file, or the glTF image and its file).
    """
    from PIL import Image

    stream = io.BytesIO(source) if isinstance(source, (bytes, bytearray)) else regular_file(source, where)
    try:
        with warnings.catch_warnings():  # Pillow warns from 89 million pixels on: below, the limit says more
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            im = Image.open(stream)
    except Image.DecompressionBombError:
        raise LightcutsError(f"{where}: its header claims more than {2 * Image.MAX_IMAGE_PIXELS:,} texels, more than "
                             f"the {MAX_TEXELS:,} a texture may have") from None
    except Image.UnidentifiedImageError:
        raise LightcutsError(f"{where}: cannot read image (not a format Pillow knows, or a broken header)") from None
    except Exception as exc:  # Pillow raises many types on malformed headers
        raise LightcutsError(f"{where}: cannot read image ({_reason(exc)})") from None
    with im:
        w, h = im.size
        if w * h > MAX_TEXELS:
            raise LightcutsError(f"{where}: {w} x {h} texels, more than the {MAX_TEXELS:,} a texture may have")
        if w * h == 0:
            raise LightcutsError(f"{where}: an empty image ({w} x {h} texels)")
        if budget is not None:
            budget.take(w * h, where)
        try:
            rgb = np.asarray(im.convert("RGB"), np.uint8)
        except Exception as exc:  # truncated or corrupt data: OSError, ValueError, EOFError, zlib.error, ...
            raise LightcutsError(f"{where}: cannot read image: its data does not decode ({_reason(exc)})") from None
    return image_to_linear(rgb)


def _reason(exc: BaseException) -> str:
    """A decoder's exception as the first line of its message (its type when it has none)."""
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def image_to_linear(rgb8: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 sRGB -> (H, W, 3) float32 linear (a lookup table of the 256 codes)."""
    table = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)
    return table[np.asarray(rgb8, np.uint8)]


@dataclass
class TextureSet:
    """The images of a scene, stored flat.

    texels : (T, 3) float32, linear RGB, every image's rows top to bottom, one after the other
    table : (K, 3) int64, per image its first texel row, width and height (``TEX_*`` columns)
    names : K strings, where each image came from (a file, or ``glTF <material>``), for reports
    """

    texels: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))
    table: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    names: list = field(default_factory=list)

    def __post_init__(self):
        self.texels = np.ascontiguousarray(self.texels, np.float32).reshape(-1, 3)
        self.table = np.ascontiguousarray(self.table, np.int64).reshape(-1, 3)
        self.names = [str(n) for n in self.names]

    def __len__(self) -> int:
        return len(self.table)

    @classmethod
    def of(cls, images: list, names: list) -> "TextureSet":
        """The set of (H, W, 3) linear images, in order (one copy of the texels)."""
        shapes = [np.shape(im)[:2] for im in images]
        sizes = [h * w for h, w in shapes]
        table = np.array([[o, w, h] for o, (h, w) in zip(np.cumsum([0] + sizes[:-1]), shapes)], np.int64)
        texels = np.concatenate([np.asarray(im, np.float32).reshape(-1, 3) for im in images]) if images else None
        return cls(texels if texels is not None else np.zeros((0, 3), np.float32), table, names)

    @classmethod
    def concatenate(cls, sets: list) -> tuple["TextureSet", list]:
        """One set of every image of ``sets`` in order (one copy of the texels), and the index the
        first image of each set got in it."""
        if not sets:
            return cls(), []
        bases = np.cumsum([0] + [len(t) for t in sets[:-1]]).tolist()
        offsets = np.cumsum([0] + [len(t.texels) for t in sets[:-1]])
        tables = []
        for t, o in zip(sets, offsets):
            table = t.table.copy()
            table[:, TEX_OFFSET] += o
            tables.append(table)
        return cls(np.concatenate([t.texels for t in sets]), np.concatenate(tables),
                   [n for t in sets for n in t.names]), bases

    def add(self, image: np.ndarray, name: str) -> int:
        """Append an (H, W, 3) linear image; returns its index."""
        merged, (_, k) = TextureSet.concatenate([self, TextureSet.of([image], [name])])
        self.texels, self.table, self.names = merged.texels, merged.table, merged.names
        return k

    def image(self, k: int) -> np.ndarray:
        """(H, W, 3) float32 view of image k."""
        o, w, h = (int(x) for x in self.table[k])
        return self.texels[o:o + w * h].reshape(h, w, 3)


def uv_maps(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(F, UV_COLUMNS) float64: per triangle, corner p0 and the gradients of u and v in world space,
    so that ``u(x) = u0 + (x - p0) . grad u`` on the triangle (and likewise v), u0 the corner's u
    less its floor (whole periods of the repeat: the same texels, and small values for the kernel).

    vertices (V, 3), faces (F, 3), uv (F, 3, 2) the corners' texture coordinates. With e1, e2 the
    edges from p0, a point's barycentrics are (x - p0) . c1 and (x - p0) . c2 for the dual vectors
    c1 = (|e2|^2 e1 - (e1.e2) e2) / D, c2 = (|e1|^2 e2 - (e1.e2) e1) / D, D = |e1 x e2|^2.
    """
    t = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    uv = np.asarray(uv, np.float64).reshape(-1, 3, 2)
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    g11, g12, g22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    det = g11 * g22 - g12 * g12
    det = np.where(det > 0, det, 1.0)
    c1 = (g22[:, None] * e1 - g12[:, None] * e2) / det[:, None]
    c2 = (g11[:, None] * e2 - g12[:, None] * e1) / det[:, None]
    du1, du2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    out = np.empty((len(t), UV_COLUMNS))
    out[:, UV_P0:UV_P0 + 3] = t[:, 0]
    out[:, UV_GU:UV_GU + 3] = du1[:, 0:1] * c1 + du2[:, 0:1] * c2
    out[:, UV_GV:UV_GV + 3] = du1[:, 1:2] * c1 + du2[:, 1:2] * c2
    out[:, UV_0:UV_0 + 2] = uv[:, 0] - np.floor(uv[:, 0])  # a whole number of periods off: the same texels
    return out


def check_uv(uv: np.ndarray, where: str, vertices: np.ndarray | None = None, faces: np.ndarray | None = None) -> None:
    """LightcutsError ``<where>: ...`` unless every triangle's texture coordinates (F, 3, 2) and
    their differences between corners are finite, and (given the ``vertices`` and ``faces`` as
    rendered) so is its uv map (:func:`uv_maps`). Coordinates whose differences overflow float64
    (1e308 and -1e308 on one triangle) or change faster than it holds across a triangle have no
    texel to give between the corners."""
    uv = np.asarray(uv, np.float64).reshape(-1, 3, 2)
    bad = ~np.all(np.isfinite(uv), axis=(1, 2))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise LightcutsError(f"{where}: {int(bad.sum())} triangles have NaN or infinite texture coordinates "
                             f"(triangle {i}: {uv[i].tolist()})")
    with np.errstate(over="ignore", invalid="ignore"):
        bad = ~np.all(np.isfinite(uv[:, 1:] - uv[:, :1]), axis=(1, 2))
        if vertices is not None:
            bad |= ~np.all(np.isfinite(uv_maps(vertices, faces, uv)), axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise LightcutsError(f"{where}: the texture coordinates of {int(bad.sum())} triangles change faster "
                             f"across them than float64 holds (triangle {i}: {uv[i].tolist()})")


def empty_kernel_data():
    """The kernels' texture tuple of a scene without textures (every array empty)."""
    return (np.zeros(0, np.int32), np.zeros((0, UV_COLUMNS)), np.zeros((0, 3), np.float32),
            np.zeros((0, 3), np.int64))


def face_texture_means(textures: TextureSet, face_texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(F, 3) float64: each textured triangle's texture averaged over its uv triangle (the mean of
    the filtered lookups at 15 points of a barycentric grid); 1 where ``face_texture`` is -1. For
    quantities kept per triangle, such as emitted radiance (lights sample triangles)."""
    k = np.arange(5)
    b1, b2 = np.meshgrid(k, k, indexing="ij")
    keep = b1 + b2 <= 4
    bary = np.stack([b1[keep], b2[keep]], 1) / 4.0
    bary = 0.25 / 3.0 + bary * (1.0 - 0.25)  # inside the triangle, off its edges
    out = np.ones((len(face_texture), 3))
    has = np.flatnonzero(face_texture >= 0)
    if len(has) == 0:
        return out
    uvh = np.asarray(uv, np.float64)[has]
    uvh = uvh - np.floor(uvh[:, :1])  # whole periods off: small values, whose steps keep their precision
    pts = uvh[:, None, 0] + bary[None, :, 0:1] * (uvh[:, None, 1] - uvh[:, None, 0]) \
        + bary[None, :, 1:2] * (uvh[:, None, 2] - uvh[:, None, 0])
    vals = _lookup_many(textures.texels, textures.table, np.repeat(face_texture[has], len(bary)).astype(np.int64),
                        np.ascontiguousarray(pts.reshape(-1, 2)))
    out[has] = vals.reshape(len(has), len(bary), 3).mean(axis=1)
    return out


@njit(cache=True, error_model="numpy")
def _lookup_many(texels, table, which, uv):
    out = np.empty((uv.shape[0], 3))
    for i in range(uv.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = texture_lookup(texels, table, which[i], uv[i, 0], uv[i, 1])
    return out


@njit(cache=True, error_model="numpy", inline="always")
def _wrap(i, n):
    i = i % n
    return i + n if i < 0 else i


@njit(cache=True, error_model="numpy")
def texture_lookup(texels, table, k, u, v):
    """Image k at (u, v), bilinear between texel centres, repeating: ``(r, g, b)`` linear."""
    o = table[k, TEX_OFFSET]
    w = table[k, TEX_WIDTH]
    h = table[k, TEX_HEIGHT]
    if not (math.isfinite(u) and math.isfinite(v)):
        u, v = 0.0, 0.0
    u -= np.floor(u)  # into [0, 1], in float64: exact, and no integer conversion of a huge value
    v -= np.floor(v)
    fx = u * w - 0.5  # in [-0.5, w - 0.5]
    fy = (1.0 - v) * h - 0.5
    x0 = np.int64(np.floor(fx))  # in [-1, w - 1]
    y0 = np.int64(np.floor(fy))
    tx = fx - x0
    ty = fy - y0
    x0 = _wrap(x0, w)
    y0 = _wrap(y0, h)
    x1 = _wrap(x0 + 1, w)
    y1 = _wrap(y0 + 1, h)
    a = o + y0 * w
    b = o + y1 * w
    w00 = (1.0 - tx) * (1.0 - ty)
    w10 = tx * (1.0 - ty)
    w01 = (1.0 - tx) * ty
    w11 = tx * ty
    r = w00 * texels[a + x0, 0] + w10 * texels[a + x1, 0] + w01 * texels[b + x0, 0] + w11 * texels[b + x1, 0]
    g = w00 * texels[a + x0, 1] + w10 * texels[a + x1, 1] + w01 * texels[b + x0, 1] + w11 * texels[b + x1, 1]
    bl = w00 * texels[a + x0, 2] + w10 * texels[a + x1, 2] + w01 * texels[b + x0, 2] + w11 * texels[b + x1, 2]
    return r, g, bl


@njit(cache=True, error_model="numpy")
def albedo_at(albedo, tex, f, x0, x1, x2):
    """The diffuse albedo ``(r, g, b)`` of triangle f at the point x on it: ``albedo[f]``, times its
    texture at x's texture coordinates when it has one. tex : :meth:`TextureSet.kernel_data`."""
    face_tex, maps, texels, table = tex
    r, g, b = albedo[f, 0], albedo[f, 1], albedo[f, 2]
    if face_tex.shape[0] == 0:
        return r, g, b
    k = face_tex[f]
    if k < 0:
        return r, g, b
    q0 = x0 - maps[f, UV_P0]
    q1 = x1 - maps[f, UV_P0 + 1]
    q2 = x2 - maps[f, UV_P0 + 2]
    u = maps[f, UV_0] + q0 * maps[f, UV_GU] + q1 * maps[f, UV_GU + 1] + q2 * maps[f, UV_GU + 2]
    v = maps[f, UV_0 + 1] + q0 * maps[f, UV_GV] + q1 * maps[f, UV_GV + 1] + q2 * maps[f, UV_GV + 2]
    tr, tg, tb = texture_lookup(texels, table, k, u, v)
    return r * tr, g * tg, b * tb
