"""Convergence studies against a path tracer (``lightcuts reference --curve`` / ``--split``).

Both measure lightcuts' images against one long path-traced render of the same config (its
``--spp``, seed ``seed + 1``) with :func:`lightcuts.report.images.compare_images` (energy ratio,
per-pixel and 8x8-block relative luminance error), the pixels that see an emitter directly left
out (:func:`lightcuts.integrators.primary.emitter_mask`). The path tracer is a reference renderer
(lightcuts.integrators.references.REFERENCES, ``--renderer``): Mitsuba 3's or lightcuts' own with the
exact BRDF.

* :func:`error_curve`: lightcuts' running mean after passes 1, 2, 4, ... N of the config
  (:func:`lightcuts.pipeline.passes.render_passes`, wall time of lights, trees and image summed over the
  passes), and the path tracer run for each of those times (its spp from timing runs of at least
  a second); the slope of lightcuts' error against time, fitted in log-log (an unbiased
  estimator falls as time^-0.5; a biased one flattens at its bias), and at each time who is lower.
* :func:`energy_split`: where a remaining energy gap comes from: the ratio with clamping off, with
  each remedy on in turn, with every material made diffuse (in both renderers) and for direct light
  alone.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from lightcuts.integrators.references import DEFAULT_REFERENCE, make_reference

#: The measures of a curve point, as compare_images gives them: (CSV column, path into its dict).
MEASURES = (("energy_ratio", ("energy_ratio",)), ("pixel_median", ("pixel", "median")),
            ("block8_median", ("block8", "median")))


def measures(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> dict:
    """{"energy_ratio", "pixel_median", "block8_median"} of the image against the reference, the
    pixels of ``mask`` (those that see an emitter directly) left out."""
    from lightcuts.report.images import compare_images

    c = compare_images(image, reference, mask=mask)
    out = {}
    for key, path in MEASURES:
        v = c
        for k in path:
            v = v.get(k) if isinstance(v, dict) else None
        out[key] = v
    return out


def pass_counts(n: int) -> list[int]:
    """1, 2, 4, ... up to n, and n itself."""
    counts = [1 << k for k in range(max(1, n).bit_length()) if 1 << k <= n]
    return counts if counts[-1] == n else counts + [n]


def loglog_slope(x, y) -> float | None:
    """Least-squares slope of log y against log x over the points with x, y > 0 (None below two)."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    keep = (x > 0) & (y > 0)
    if keep.sum() < 2 or np.ptp(np.log(x[keep])) == 0:
        return None
    return float(np.polyfit(np.log(x[keep]), np.log(y[keep]), 1)[0])


def long_reference(cfg, scene, envmap, spp: int, integrator: str = "path",
                   tracer=None) -> tuple[np.ndarray, float]:
    """The long render of the config at ``spp`` (seed ``cfg.seed + 1``, apart from the equal-time
    renders' seed) by ``tracer`` (default Mitsuba's): (image, seconds)."""
    return (tracer or make_reference(DEFAULT_REFERENCE)).render(cfg, scene, envmap, spp, cfg.seed + 1, integrator)


def error_curve(cfg, plan, scene, envmap, caster, reference: np.ndarray, progress: bool = True,
                log=print, tracer=None) -> dict:
    """The curve (module docstring) for ``cfg.render.passes`` passes: {"rows": [{"method",
    "passes", "spp", "seconds", "energy_ratio", "pixel_median", "block8_median"}, ...], "slope":
    {measure: lightcuts' fitted slope}, "verdict": [{"seconds", "pixel": winner, "block8":
    winner}, ...], "image": the final running mean}; the path tracer's rows have its
    :attr:`ReferenceRenderer.label` as "method". Its points are its render times (the render call
    alone), lightcuts' the summed pass times. ``tracer``: the path tracer (default Mitsuba's)."""
    from lightcuts.pipeline.passes import render_passes
    from lightcuts.integrators.primary import emitter_mask

    tracer = tracer or make_reference(DEFAULT_REFERENCE)
    points = set(pass_counts(cfg.render.passes))
    mask = emitter_mask(scene, caster, cfg.render.crop, envmap is not None)
    lc = []

    def on_pass(p, mean, seconds):
        if p + 1 in points:
            lc.append({"method": "lightcuts", "passes": p + 1, "spp": cfg.render.spp * (p + 1),
                       "seconds": seconds, **measures(mean, reference, mask)})
            log(f"{cfg.name}: lightcuts {p + 1} passes, {seconds:.2f} s: block8 median "
                f"{100 * (lc[-1]['block8_median'] or 0):.2f}%")

    result = render_passes(cfg, plan, scene, caster, envmap, desc=f"{cfg.name}: lightcuts", progress=progress,
                           on_pass=on_pass)
    per_spp = tracer.seconds_per_spp(cfg, scene, envmap)
    mi = []
    for r in lc:
        spp = max(1, int(round(r["seconds"] / per_spp)))
        image, seconds = tracer.render(cfg, scene, envmap, spp, cfg.seed)
        mi.append({"method": tracer.label, "passes": None, "spp": spp, "seconds": seconds,
                   **measures(image, reference, mask)})
        log(f"{cfg.name}: {tracer.label} {spp} spp, {seconds:.2f} s: block8 median "
            f"{100 * (mi[-1]['block8_median'] or 0):.2f}%")
    rows = lc + mi
    slope = {key: loglog_slope([r["seconds"] for r in lc], [r[key] for r in lc])
             for key in ("pixel_median", "block8_median")}
    verdict = [{"seconds": a["seconds"], "path_tracer_seconds": b["seconds"],
                **{m: ("lightcuts" if a[f"{m}_median"] < b[f"{m}_median"] else "path tracer")
                   for m in ("pixel", "block8") if a[f"{m}_median"] is not None and b[f"{m}_median"] is not None}}
               for a, b in zip(lc, mi)]
    return {"rows": rows, "slope": slope, "verdict": verdict, "image": result.image,
            "path_tracer_seconds_per_spp": per_spp}


#: The rows of :func:`energy_split`: (label, config overrides, materials made diffuse, the path
#: tracer's integrator). ``{passes}`` stands for the study's pass count.
SPLIT_ROWS = (
    ("as configured", (), False, "path"),
    ("clamping off", ("render.clamp.enabled=false",), False, "path"),
    ("compensation", ("render.compensation=true",), False, "path"),
    ("compensation, stochastic", ("render.compensation=true", "render.representatives=stochastic"), False, "path"),
    ("compensation, stochastic, {passes} passes", ("render.compensation=true", "render.representatives=stochastic",
                                                   "render.passes={passes}"), False, "path"),
    ("diffuse materials", (), True, "path"),
    ("diffuse materials, compensation, stochastic, {passes} passes",
     ("render.compensation=true", "render.representatives=stochastic", "render.passes={passes}"), True, "path"),
    ("direct light only", ("lights.indirect.count=0",), False, "direct"),
    ("direct light only, {passes} passes", ("lights.indirect.count=0", "render.passes={passes}"), False, "direct"),
)


def diffuse_scene(scene):
    """The scene with every Phong lobe removed (rho_s = 0; rho_d kept)."""
    return dataclasses.replace(scene, specular=np.zeros_like(scene.specular), _cache={})


def energy_split(make_run, passes: int, spp: int, progress: bool = True, log=print,
                 tracer=None) -> dict:
    """The energy split (module docstring). ``make_run(overrides) -> (cfg, plan)`` loads the run
    with extra ``--set`` overrides; ``passes`` the pass count of the rows that use passes; ``spp``
    the path tracer's samples per pixel; ``tracer`` the path tracer (default Mitsuba's; rows it
    cannot render, direct light with lightcuts' own, are left out). Returns {"rows": [{"label",
    "overrides", "diffuse", "integrator", "seconds", "energy_ratio", "pixel_median",
    "block8_median"}, ...], "references": {key: {"seconds"}}, "images": {key: image}}, one key per
    long render: "path", "path-diffuse" (materials made diffuse) or "direct"."""
    from lightcuts.pipeline.passes import render_passes
    from lightcuts.integrators.primary import emitter_mask

    tracer = tracer or make_reference(DEFAULT_REFERENCE)
    runs = []  # every row's run is loaded and planned before any work: a refused one stops here
    for label, overrides, diffuse, integrator in SPLIT_ROWS:
        if integrator not in tracer.trait("integrators", ()):
            continue
        overrides = [o.format(passes=passes) for o in overrides]
        runs.append((label.format(passes=passes), overrides, diffuse, integrator, *make_run(overrides)))
    refs, images, rows = {}, {}, []
    for label, overrides, diffuse, integrator, cfg, plan in runs:
        scene = plan.scene()
        if diffuse:
            scene = diffuse_scene(scene)
        envmap = plan.environment()
        key = integrator + ("-diffuse" if diffuse else "")
        if key not in images:
            log(f"{cfg.name}: {tracer.label} {integrator}{' (diffuse materials)' if diffuse else ''}, {spp} spp ...")
            images[key], seconds = long_reference(cfg, scene, envmap, spp, integrator, tracer)
            refs[key] = {"seconds": seconds}
        with plan.make_caster(scene) as caster:
            result = render_passes(cfg, plan, scene, caster, envmap, desc=f"{cfg.name}: {label}", progress=progress)
            mask = emitter_mask(scene, caster, cfg.render.crop, envmap is not None)
        rows.append({"label": label, "overrides": overrides, "diffuse": diffuse, "integrator": integrator,
                     "seconds": result.seconds, **measures(result.image, images[key], mask)})
        log(f"{cfg.name}: {label}: energy lightcuts/{tracer.label} {rows[-1]['energy_ratio']:.4f}")
    return {"rows": rows, "references": refs, "images": images}
