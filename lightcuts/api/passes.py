"""Progressive passes (``render.passes``): the run rendered N times, each pass with its own lights,
trees and eye-ray samples, and the images averaged.

Pass 0 uses the run's seed itself, so one pass is the plain render, byte for byte; pass p > 0 uses
:func:`pass_seed` (seed, p), from which the lights' sub-seeds, the trees' and the eye rays' follow
as in any run. Each pass is an independent estimate, so the mean's error falls as 1 / sqrt(N) to
the bias that remains (with fixed representatives, the cut's; with compensation off, the clamped
and glossy light: docs/math.md, "Converging images").
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np


def pass_seed(seed: int, p: int) -> int:
    """The run seed of pass p (p = 0: ``seed`` itself), a 63-bit integer."""
    if p == 0:
        return int(seed)
    state = np.random.SeedSequence(int(seed), spawn_key=(0x5041535345, int(p))).generate_state(2, np.uint32)
    return ((int(state[0]) << 31) ^ int(state[1])) & ((1 << 63) - 1)


@dataclass
class Passes:
    """The average of N passes.

    image : (H, W, 3) float32, the mean of the passes' images (pass 0's own array for N = 1)
    cut_size : (H, W) float32, the mean cut per pixel; result0 : pass 0's RenderResult
    shadow_rays, eye_rays : totals over the passes; clamped_fraction : the passes' mean
    load_seconds : loading (or compiling) the render kernel before pass 0, untimed elsewhere
    records : per pass ``{"pass", "seed", "lights_seconds", "build_seconds", "render_seconds",
        "seconds", "change"}``; change = mean |running mean after the pass - before| / mean of the
        running mean, in luminance (None for pass 0): how much the estimate still moves
    lights, trees : pass 0's light sets and trees (the run's own, for the report)
    """

    image: np.ndarray
    cut_size: np.ndarray
    result0: object
    shadow_rays: int
    eye_rays: int
    clamped_fraction: float
    load_seconds: float
    records: list = field(default_factory=list)
    lights: dict = field(default_factory=dict)
    trees: dict = field(default_factory=dict)

    @property
    def render_seconds(self) -> float:
        return float(sum(r["render_seconds"] for r in self.records))

    @property
    def seconds(self) -> float:
        """Wall time of all passes (lights, trees and image; pass 0's lights and trees included)."""
        return float(sum(r["seconds"] for r in self.records))


def render_passes(cfg, plan, scene, caster, envmap, *, desc: str = "lightcuts", progress: bool = True,
                  lights: dict | None = None, trees: dict | None = None, on_pass=None, before_render=None) -> Passes:
    """Render ``cfg.render.passes`` passes (module docstring) with the plan's integrator.

    lights, trees : pass 0's, when the caller has made them already (their time is then not in
    pass 0's record); on_pass(p, running_mean (H, W, 3) float64, seconds so far) after each pass;
    before_render() once, before pass 0's image (e.g. waiting for the kernel's compile child).
    """
    from lightcuts.commands.common import render_timed
    from lightcuts.lights.lightset import LUMINANCE

    n = int(cfg.render.passes)
    acc = cut = None
    rays = eye = 0
    clamped = 0.0
    records, load = [], 0.0
    first = {}
    prev_lum = None
    elapsed = 0.0
    for p in range(n):
        seed = pass_seed(cfg.seed, p)
        pcfg = cfg if p == 0 else cfg.model_copy(update={"seed": seed})
        t0 = time.perf_counter()
        ls = lights if (p == 0 and lights is not None) else plan.lights(scene, caster, envmap, seed=seed)
        t_lights = time.perf_counter() - t0
        t0 = time.perf_counter()
        tr = trees if (p == 0 and trees is not None) else plan.trees(ls, seed=seed)
        t_build = time.perf_counter() - t0
        if p == 0 and before_render is not None:
            before_render()
        label = desc if n == 1 else f"{desc} pass {p + 1}/{n}"
        result, t_render, t_load = render_timed(pcfg, scene, caster, ls, tr, envmap, label, not progress,
                                                plan.integrator, load=p == 0)
        if p == 0:
            load, first = t_load, {"lights": ls, "trees": tr, "result": result}
        img = result.image.astype(np.float64)
        acc = img if acc is None else acc + img
        cut = result.cut_size.astype(np.float64) if cut is None else cut + result.cut_size
        rays += int(result.shadow_rays)
        eye += int(result.eye_rays)
        clamped += float(result.clamped_fraction)
        mean = acc / (p + 1)
        lum = mean @ LUMINANCE
        change = None
        if prev_lum is not None:
            m = float(lum.mean())
            change = float(np.abs(lum - prev_lum).mean()) / m if m > 0 else 0.0
        prev_lum = lum
        seconds = t_lights + t_build + t_render
        elapsed += seconds
        records.append({"pass": p, "seed": seed, "lights_seconds": t_lights, "build_seconds": t_build,
                        "render_seconds": t_render, "seconds": seconds, "change": change})
        if on_pass is not None:
            on_pass(p, mean, elapsed)
        if n > 1:
            del result
    r0 = first["result"]
    image = r0.image if n == 1 else (acc / n).astype(np.float32)
    cut_size = r0.cut_size if n == 1 else (cut / n).astype(np.float32)
    return Passes(image, cut_size, r0, rays, eye, clamped / n, load, records, first["lights"], first["trees"])
