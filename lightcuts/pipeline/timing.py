"""The timed render of a run's image and the progress bars every stage shows."""

from __future__ import annotations

import sys


def progress_bar(total: int, desc: str, disable: bool = False, unit: str = "row"):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, disable=disable, file=sys.stderr, leave=False,
                dynamic_ncols=True)


def render_timed(cfg, scene, caster, lights: dict, trees: dict, envmap=None, desc: str = "lightcuts",
                 no_progress: bool = False, integrator=None, load: bool = True):
    """The config's image: ``(result, seconds, load_seconds)``. The render kernel is loaded (or
    compiled) on one pixel first, untimed in ``seconds`` (its time is ``load_seconds``), so that
    ``seconds`` measures rendering: the integrator's forest (lights and trees flattened, or a path
    tracer's light tree: :meth:`~lightcuts.integrators.registry.Integrator.forest`, made once for
    both renders; numba compiling in it counts as loading) and the image. A progress bar ``desc``
    counts rows. ``integrator``: the plan's resolved ``render.integrator`` (else resolved here), built
    from the config's settings (lightcuts.integrators.registry.make_integrator); load False skips the
    one-pixel render (the kernel is loaded already; load_seconds is then 0 on a warm cache). The
    image uses ``cfg.seed`` and ``render.crop``."""
    import time

    from lightcuts.integrators.registry import make_integrator
    from lightcuts.pipeline.warmup import compile_seconds

    integ = make_integrator(cfg, integrator)
    crop = cfg.render.crop
    x0, y0 = (0, 0) if crop is None else crop[:2]
    rows = scene.camera.height if crop is None else crop[3] - crop[1]
    t0, c0 = time.perf_counter(), compile_seconds()
    forest = integ.forest(lights, trees, scene)
    c_forest = compile_seconds() - c0  # a cold cache's compile counts as loading
    t_forest = time.perf_counter() - t0 - c_forest
    t0 = time.perf_counter()
    if load:
        integ.render(scene, caster, lights, trees, forest=forest, envmap=envmap, seed=cfg.seed,
                     crop=(x0, y0, x0 + 1, y0 + 1))
    load = (time.perf_counter() - t0 if load else 0.0) + c_forest
    with progress_bar(rows, desc, no_progress) as bar:
        t0 = time.perf_counter()
        result = integ.render(scene, caster, lights, trees, forest=forest, envmap=envmap, seed=cfg.seed, crop=crop,
                              progress=bar.update)
        seconds = time.perf_counter() - t0 + t_forest
    return result, seconds, load
