"""Image outputs: linear EXR, tone-mapped sRGB PNG (:mod:`lightcuts.report.tonemap`), cut-size
heatmap with a colour bar, and the error statistics of an image against a reference.

All writers are atomic (temporary name, then rename). Heavy imports (OpenEXR, matplotlib)
happen inside the functions so that importing lightcuts stays fast.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.io import atomic_path


def write_exr(path, rgb: np.ndarray) -> Path:
    """Write linear RGB (H, W, 3) as a float32 ZIP-compressed scanline EXR (channels R, G, B)."""
    import OpenEXR

    rgb = np.ascontiguousarray(rgb, np.float32)  # float64 raises, a non-contiguous view writes garbage
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected (H, W, 3) RGB, got {rgb.shape}")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    path = Path(path)
    with atomic_path(path, suffix=".exr") as tmp:
        with OpenEXR.File(header, {"RGB": rgb}) as f:
            f.write(str(tmp))
    return path


def read_exr(path) -> np.ndarray:
    """Read an RGB EXR as (H, W, 3) float32; LightcutsError naming the file if it is not one."""
    import OpenEXR

    if not os.path.isfile(path):
        raise LightcutsError(f"{path}: no such EXR file")
    try:
        with OpenEXR.File(str(path)) as f:
            ch = f.channels()
            if "RGB" in ch:
                return np.asarray(ch["RGB"].pixels, np.float32)
            if all(c in ch for c in "RGB"):
                return np.stack([np.asarray(ch[c].pixels, np.float32) for c in "RGB"], axis=-1)
            raise LightcutsError(f"{path}: EXR has no R, G, B channels (has {', '.join(ch)})")
    except LightcutsError:
        raise
    except Exception as exc:
        raise LightcutsError(f"{path}: cannot read EXR ({exc})") from None


def write_png(path, rgb: np.ndarray, tonemap=None) -> Path:
    """Write linear RGB (H, W, 3) as an 8-bit sRGB PNG through ``tonemap`` (a config's
    ``render.tonemap``: ``type`` and ``exposure``; None: clipped at 0 stops)."""
    from PIL import Image

    from lightcuts.report.tonemap import of, srgb8

    path = Path(path)
    with atomic_path(path, suffix=".png") as tmp:
        Image.fromarray(srgb8(rgb, *of(tonemap))).save(tmp, format="PNG")
    return path


def write_heatmap(path, values: np.ndarray, label: str = "cut size (nodes per eye ray)",
                  title: str | None = None) -> Path:
    """False-colour map of a per-pixel scalar (H, W) with a colour bar, as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    values = np.asarray(values, np.float64)
    h, w = values.shape
    fig_w = 6.0
    fig, ax = plt.subplots(figsize=(fig_w, fig_w * h / w * 0.85 + 0.4), dpi=max(100, int(w / 5)))
    im = ax.imshow(values, cmap="inferno", interpolation="nearest", vmin=0.0, vmax=max(1.0, float(values.max())))
    ax.set_axis_off()
    if title:
        ax.set_title(title, fontsize=9)
    cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.03)
    cb.set_label(label)
    fig.tight_layout()
    path = Path(path)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return path


def relative_error(image: np.ndarray, reference: np.ndarray, floor: float | None = None,
                   mask: np.ndarray | None = None) -> dict:
    """Per-pixel relative error of luminance, |L - L_ref| / L_ref, over pixels with L_ref > floor
    and not in ``mask`` (bool, the images' shape without the channel axis; True: left out).

    floor defaults to 1% of the reference's mean luminance over the pixels not masked (dark pixels make
    relative error meaningless). Returns mean, median, p99, max, rms (the root of the mean square)
    and the number of pixels compared.
    """
    from lightcuts.lights.lightset import LUMINANCE

    lum = np.asarray(image, np.float64) @ LUMINANCE
    ref = np.asarray(reference, np.float64) @ LUMINANCE
    keep = np.ones(ref.shape, bool) if mask is None else ~np.asarray(mask, bool)
    if floor is None:
        floor = 0.01 * float(ref[keep].mean()) if keep.any() else 0.0
    keep = keep & (ref > floor)
    if not keep.any():
        return {"pixels": 0, "floor": floor, "mean": 0.0, "median": 0.0, "p99": 0.0, "max": 0.0, "rms": 0.0}
    rel = np.abs(lum[keep] - ref[keep]) / ref[keep]
    return {"pixels": int(keep.sum()), "floor": float(floor), "mean": float(rel.mean()),
            "median": float(np.median(rel)), "p99": float(np.percentile(rel, 99)), "max": float(rel.max()),
            "rms": float(np.sqrt(np.mean(rel * rel)))}


def block_means(image: np.ndarray, block: int = 8) -> np.ndarray:
    """(H // block, W // block, C) means of the image's whole ``block`` x ``block`` tiles (a partial
    last row or column of tiles is left out)."""
    a = np.asarray(image, np.float64)
    h, w = (a.shape[0] // block) * block, (a.shape[1] // block) * block
    a = a[:h, :w]
    return a.reshape(h // block, block, w // block, block, *a.shape[2:]).mean(axis=(1, 3))


def compare_images(image: np.ndarray, reference: np.ndarray, block: int = 8, mask: np.ndarray | None = None,
                   halves: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
    """An image against a reference of the same shape (H, W, 3).

    mask : (H, W) bool, pixels left out of every figure: those that see an emitter directly
        (:func:`lightcuts.integrators.primary.emitter_mask`), whose radiance every renderer shares and which
        can hold most of the frame's energy; None leaves none out
    halves : (A, B), two independent renders of the reference with half its samples each
        (reference = (A + B) / 2); None when there are none

    Returns ``energy_ratio`` (mean luminance image / reference over the pixels not masked; None for a
    black reference), ``energy_ratio_frame`` (the same over every pixel), ``masked_pixels``, ``pixel``
    (:func:`relative_error` per pixel), ``block<k>`` (the same on the means of k x k tiles, taken
    first, tiles holding a masked pixel left out: a path-traced reference's noise mostly averages
    out there) and, with ``halves``, ``reference_noise``: the same figures for the reference's own
    noise, estimated per pixel by (A - B) / 2 (whose spread is the reference's): ``energy_ratio``,
    the relative standard deviation of the reference's mean luminance over the pixels not masked
    (from the per-pixel variances ((A - B) / 2)^2), and ``pixel`` / ``block<k>``, the errors an exact
    image would show against this reference, over the same pixels and floor. An error near its
    noise figure is mostly the reference's noise, not the image's error.
    """
    from lightcuts.lights.lightset import LUMINANCE

    image, reference = np.asarray(image, np.float64), np.asarray(reference, np.float64)
    if image.shape != reference.shape:
        raise ValueError(f"images differ in shape: {image.shape} and {reference.shape}")
    keep = np.ones(reference.shape[:2], bool) if mask is None else ~np.asarray(mask, bool)
    if keep.shape != reference.shape[:2]:
        raise ValueError(f"mask has shape {keep.shape}; expected {reference.shape[:2]}")
    lum, ref = image @ LUMINANCE, reference @ LUMINANCE

    def ratio(sel):
        m = float(ref[sel].mean()) if sel.any() else 0.0
        return float(lum[sel].mean()) / m if m > 0 else None

    out = {"energy_ratio": ratio(keep), "energy_ratio_frame": ratio(np.ones_like(keep)),
           "masked_pixels": int((~keep).sum()), "pixel": relative_error(image, reference, mask=~keep)}
    tiles = image.shape[0] >= block and image.shape[1] >= block
    if tiles:
        tile_mask = block_means(~keep, block) > 0
        out[f"block{block}"] = relative_error(block_means(image, block), block_means(reference, block),
                                              mask=tile_mask)
    if halves is not None:
        noise = (np.asarray(halves[0], np.float64) - np.asarray(halves[1], np.float64)) / 2.0
        if noise.shape != reference.shape:
            raise ValueError(f"halves have shape {noise.shape}; expected {reference.shape}")
        n, m = int(keep.sum()), float(ref[keep].mean()) if keep.any() else 0.0
        spread = float(np.sqrt(np.sum((noise @ LUMINANCE)[keep] ** 2))) / n if n else 0.0
        out["reference_noise"] = {
            "energy_ratio": spread / m if m > 0 else None,
            "pixel": relative_error(reference + noise, reference, out["pixel"]["floor"], ~keep)}
        if tiles:
            out["reference_noise"][f"block{block}"] = relative_error(
                block_means(reference + noise, block), block_means(reference, block), out[f"block{block}"]["floor"],
                tile_mask)
    return out
