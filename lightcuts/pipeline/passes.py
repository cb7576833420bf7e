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
        "seconds", "change", "clamp_radius"}``; clamp_radius : the radius its indirect VPLs were clamped
        within (world units, 0: none); change = mean |running mean after the pass - before| / mean of the
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


class PassMean:
    """The running mean of passes fed in pass order (:func:`render_passes` and a cluster's passes share
    it, so both sum the same float64 arrays in the same order and give the same bytes).

    n : the number of passes; on_pass : as :func:`render_passes`'s.
    """

    def __init__(self, n: int, on_pass=None):
        self.n = int(n)
        self.on_pass = on_pass
        self.acc = self.cut = self.prev_lum = None
        self.rays = self.eye = 0
        self.clamped = self.elapsed = 0.0
        self.records = []
        self.first = None

    def add(self, p: int, seed: int, result, t_lights: float, t_build: float, t_render: float) -> None:
        """Pass ``p`` (the next one): its RenderResult (image, cut_size, shadow_rays, eye_rays,
        clamped_fraction, clamp_radius) and the seconds of its lights, trees and image."""
        from lightcuts.lights.lightset import LUMINANCE

        assert p == len(self.records), f"pass {p} added after {len(self.records)} passes"
        if p == 0:
            self.first = result
        img = result.image.astype(np.float64)
        self.acc = img if self.acc is None else self.acc + img
        self.cut = result.cut_size.astype(np.float64) if self.cut is None else self.cut + result.cut_size
        self.rays += int(result.shadow_rays)
        self.eye += int(result.eye_rays)
        self.clamped += float(result.clamped_fraction)
        mean = self.acc / (p + 1)
        lum = mean @ LUMINANCE
        change = None
        if self.prev_lum is not None:
            m = float(lum.mean())
            change = float(np.abs(lum - self.prev_lum).mean()) / m if m > 0 else 0.0
        self.prev_lum = lum
        seconds = t_lights + t_build + t_render
        self.elapsed += seconds
        self.records.append({"pass": p, "seed": seed, "lights_seconds": t_lights, "build_seconds": t_build,
                             "render_seconds": t_render, "seconds": seconds, "change": change,
                             "clamp_radius": float(result.clamp_radius)})
        if self.on_pass is not None:
            self.on_pass(p, mean, self.elapsed)

    def finish(self, load: float, lights: dict, trees: dict) -> Passes:
        """The Passes once all n were added; ``lights``, ``trees``: pass 0's."""
        n, r0 = self.n, self.first
        image = r0.image if n == 1 else (self.acc / n).astype(np.float32)
        cut_size = r0.cut_size if n == 1 else (self.cut / n).astype(np.float32)
        return Passes(image, cut_size, r0, self.rays, self.eye, self.clamped / n, load, self.records, lights, trees)


def pass_lights(plan, scene, caster, envmap, seed: int) -> tuple[dict, dict | None, float, float]:
    """A pass's light sets and trees from the run seed ``seed`` and the seconds of each, numba's
    compiling left out: ``(lights, trees, lights_seconds, build_seconds)``; ``({}, None, 0.0, 0.0)``
    where the plan's integrator renders from neither (:attr:`~lightcuts.pipeline.plan.Plan.uses_trees`;
    the path tracer draws the scene's emitting triangles itself), so a pass's time is what its image
    needs."""
    from lightcuts.pipeline.warmup import compile_seconds

    if not plan.uses_trees:
        return {}, None, 0.0, 0.0
    t0, c0 = time.perf_counter(), compile_seconds()
    lights = plan.lights(scene, caster, envmap, seed=seed)
    t_lights = time.perf_counter() - t0 - (compile_seconds() - c0)
    t0, c0 = time.perf_counter(), compile_seconds()
    trees = plan.trees(lights, seed=seed)
    return lights, trees, t_lights, time.perf_counter() - t0 - (compile_seconds() - c0)


def render_passes(cfg, plan, scene, caster, envmap, *, desc: str = "lightcuts", progress: bool = True,
                  lights: dict | None = None, trees: dict | None = None, on_pass=None, before_render=None) -> Passes:
    """Render ``cfg.render.passes`` passes (module docstring) with the plan's integrator.

    lights, trees : pass 0's, when the caller has made them already (their time is then not in
    pass 0's record); otherwise each pass's are :func:`pass_lights`' (none for an integrator that
    renders from neither); on_pass(p, running_mean (H, W, 3) float64, seconds so far) after each pass;
    before_render() once, before pass 0's image (e.g. waiting for the kernel's compile child).
    """
    from lightcuts.pipeline.timing import render_timed

    n = int(cfg.render.passes)
    mean = PassMean(n, on_pass)
    load = 0.0
    first = {}
    for p in range(n):
        seed = pass_seed(cfg.seed, p)
        pcfg = cfg if p == 0 else cfg.model_copy(update={"seed": seed})
        if p == 0 and lights is not None:
            ls, tr, t_lights, t_build = lights, trees, 0.0, 0.0
        else:
            ls, tr, t_lights, t_build = pass_lights(plan, scene, caster, envmap, seed)
        if p == 0 and before_render is not None:
            before_render()
        label = desc if n == 1 else f"{desc} pass {p + 1}/{n}"
        result, t_render, t_load = render_timed(pcfg, scene, caster, ls, tr, envmap, label, not progress,
                                                plan.integrator, load=p == 0)
        if p == 0:
            load, first = t_load, {"lights": ls, "trees": tr}
        mean.add(p, seed, result, t_lights, t_build, t_render)
        del result
    return mean.finish(load, first["lights"], first["trees"])
