"""Image tiles: the crop windows a cluster renders, and the mosaic that puts their results together.

The render kernel seeds every pixel by its absolute coordinates and writes each pixel once
(lightcuts.integrators.lightcut), so a tile, rendered as a crop window of the full image, holds exactly
the pixels of the whole render; the mosaic of all tiles is the local render's image and cut sizes,
byte for byte, whatever the tile size or the order in which tiles finish.
"""

from __future__ import annotations

import numpy as np


def tile_windows(width: int, height: int, crop, size: int) -> list[tuple[int, int, int, int]]:
    """(x0, y0, x1, y1) windows of at most ``size`` x ``size`` pixels covering the image (or the crop
    window ``crop``), row by row."""
    x0, y0, x1, y1 = (0, 0, int(width), int(height)) if crop is None else (int(c) for c in crop)
    size = max(1, int(size))
    return [(x, y, min(x + size, x1), min(y + size, y1))
            for y in range(y0, y1, size) for x in range(x0, x1, size)]


class Mosaic:
    """The results of tiles placed into the image (H, W of the crop window, or the whole image).

    window : (x0, y0, x1, y1) of the image the tiles cover. add(window, result) places a tile's
    RenderResult; result() gives the whole image's RenderResult once every pixel is in.
    """

    def __init__(self, window):
        self.x0, self.y0, x1, y1 = (int(c) for c in window)
        h, w = y1 - self.y0, x1 - self.x0
        self.image = np.zeros((h, w, 3), np.float32)
        self.cut = np.zeros((h, w), np.float32)
        self.rays = np.zeros((h, w), np.int64)
        self.filled = np.zeros((h, w), bool)
        self.clamped_sum = 0.0
        self.first = None

    def add(self, window, r) -> None:
        """Place the RenderResult ``r`` of the tile ``window`` (full-image coordinates)."""
        x0, y0, x1, y1 = window
        rows, cols = slice(y0 - self.y0, y1 - self.y0), slice(x0 - self.x0, x1 - self.x0)
        if self.filled[rows, cols].any():
            raise ValueError(f"tile {window} placed twice")
        self.image[rows, cols] = r.image
        self.cut[rows, cols] = r.cut_size
        self.rays[rows, cols] = r.shadow_rays_image
        self.filled[rows, cols] = True
        self.clamped_sum += float(r.clamped_energy) * r.cut_size.size
        self.first = self.first or r

    @property
    def complete(self) -> bool:
        return bool(self.filled.all())

    def result(self, seconds: float):
        """The whole image's RenderResult: image, cut sizes and shadow rays as the tiles computed
        them (those of a local render); the clamped energy from the tiles' means (equal to a local
        render's up to float rounding); the light sampler's record the first tile's (its build
        seconds its worker's)."""
        from lightcuts.lights.lightset import LUMINANCE
        from lightcuts.integrators.driver import RenderResult

        if not self.complete:
            raise ValueError(f"{int((~self.filled).sum())} pixels have no tile")
        r = self.first
        n = self.cut.size
        clamped = self.clamped_sum / n
        total = float((self.image.astype(np.float64) @ LUMINANCE).mean()) + clamped
        h, w = self.cut.shape
        return RenderResult(image=self.image, cut_size=self.cut, shadow_rays_image=self.rays,
                            shadow_rays=int(self.rays.sum()), eye_rays=n * r.spp, clamped_energy=clamped,
                            clamped_fraction=clamped / total if total > 0 else 0.0, seconds=seconds, spp=r.spp,
                            eps=r.eps, max_cut=r.max_cut, reference=r.reference,
                            crop=(self.x0, self.y0, self.x0 + w, self.y0 + h), n_lights=dict(r.n_lights),
                            clamp_radius=r.clamp_radius,
                            light_sampler=dict(r.light_sampler))
