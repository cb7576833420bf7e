"""Mitsuba 3 as a reference renderer (``--renderer mitsuba``, lightcuts.integrators.references): an
independent renderer of the whole config (emitters, sun, environment, thin lens; ``path`` or
``direct``; ``--max-depth``), with Phong lobes approximated (lightcuts.mitsuba.export)."""

from __future__ import annotations

import time

import numpy as np

from lightcuts.registry import declare
from lightcuts.integrators.references import REFERENCES, ReferenceRenderer


@REFERENCES.register("mitsuba")
@declare(exact_materials=False, light_types=("emitters", "sun", "environment"), lens=True,
         integrators=("path", "direct"), max_depth=True,
         sampler="Mitsuba's multi-jittered sampler (a count it cannot factor is rounded up)")
class MitsubaReference(ReferenceRenderer):
    """Mitsuba 3 (variant scalar_rgb): independent; Phong approximated."""

    label = "mitsuba"
    file = "mitsuba"
    title = "Mitsuba"
    report_key = "mitsuba"

    def check(self, cfg, integrator: str = "path") -> None:
        from lightcuts.mitsuba import load_mitsuba

        load_mitsuba()
        super().check(cfg, integrator)

    def describe(self) -> dict:
        from lightcuts.mitsuba.render import mitsuba_version

        return {"renderer": self.name, **mitsuba_version()}

    def render(self, cfg, scene, envmap, spp: int, seed: int, integrator: str = "path") -> tuple[np.ndarray, float]:
        from lightcuts.mitsuba.render import render_mitsuba

        return render_mitsuba(cfg, scene, envmap, spp=spp, integrator=integrator, seed=seed)

    def prepare(self, cfg, scene, envmap, spp: int, integrator: str = "path", max_depth: int = -1):
        from lightcuts.mitsuba.render import load_scene, render_loaded, sample_count

        t0 = time.perf_counter()
        mi_scene = load_scene(cfg, scene, envmap, spp=spp, integrator=integrator, max_depth=max_depth)
        t_load = time.perf_counter() - t0
        return (lambda seed: render_loaded(mi_scene, seed)), sample_count(mi_scene), t_load
