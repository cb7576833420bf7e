"""Lightcuts against Mitsuba's path tracer at equal time (``lightcuts compare --mitsuba``).

One lightcuts image (a compare row's) and a Mitsuba path-traced image whose spp fills that row's
image time (:func:`~lightcuts.mitsuba.render.spp_for_seconds`), each measured against a long
Mitsuba render (energy ratio, per-pixel and 8x8-block relative error,
:func:`lightcuts.report.images.compare_images`); likewise for the converging render (compensation,
stochastic representatives, passes) when one is given, at its own wall time. The long render is
kept in the compare's row store.
"""

from __future__ import annotations

import numpy as np


def equal_time_study(cfg, scene, envmap, base: dict, reference_spp: int, store, converging: dict | None = None,
                     mask: np.ndarray | None = None) -> dict:
    """The study for the row ``base`` ({"row": table row with "label" and "image_s", "image": (H, W, 3)}):
    {"version", "reference_spp", "reference_seconds", "lightcuts_row", "budget_s", "equal_time",
    "lightcuts", "images": {"reference", "equal_time"}}. ``store`` is the compare's
    :class:`~lightcuts.report.compare_store.RowStore` (the long render is looked up, else made and kept).
    ``converging`` ({"label", "seconds", "image"}) adds "converging" (its measures) and
    "converging_equal_time" (Mitsuba's at its seconds), and the image "converging_equal_time".
    ``mask`` ((H, W) bool): the pixels every measure leaves out, those that see an emitter directly
    (:func:`lightcuts.integrators.primary.emitter_mask`, as lightcuts' own reference and study do)."""
    from lightcuts.mitsuba.render import mitsuba_version, render_mitsuba, spp_for_seconds
    from lightcuts.report.compare_store import shared_config, store_key
    from lightcuts.report.images import compare_images

    key = store_key(what="mitsuba", config=shared_config(cfg), spp=reference_spp, version=mitsuba_version())
    cached = store.load("mitsuba-reference", key)
    if cached is None:
        print(f"{cfg.name}: Mitsuba path tracer, {reference_spp} spp (the long reference)", flush=True)
        long_image, long_s = render_mitsuba(cfg, scene, envmap, spp=reference_spp, integrator="path",
                                            seed=cfg.seed + 1)
        store.save("mitsuba-reference", key, image=long_image, seconds=np.array(long_s))
    else:
        long_image, long_s = cached["image"], float(cached["seconds"])
    budget = base["row"]["image_s"]
    spp = spp_for_seconds(cfg, scene, envmap, budget, "path")
    image, seconds = render_mitsuba(cfg, scene, envmap, spp=spp, integrator="path", seed=cfg.seed)
    out = {"version": mitsuba_version(), "reference_spp": reference_spp, "reference_seconds": long_s,
           "lightcuts_row": base["row"]["label"], "budget_s": budget,
           "equal_time": {"spp": spp, "seconds": seconds, **compare_images(image, long_image, mask=mask)},
           "lightcuts": {"seconds": budget, **compare_images(base["image"], long_image, mask=mask)},
           "images": {"reference": long_image, "equal_time": image}}
    if converging is not None:
        c_spp = spp_for_seconds(cfg, scene, envmap, converging["seconds"], "path")
        c_image, c_seconds = render_mitsuba(cfg, scene, envmap, spp=c_spp, integrator="path", seed=cfg.seed)
        out["converging"] = {"label": converging["label"], "seconds": converging["seconds"],
                             **compare_images(converging["image"], long_image, mask=mask)}
        out["converging_equal_time"] = {"spp": c_spp, "seconds": c_seconds, **compare_images(c_image, long_image, mask=mask)}
        out["images"]["converging_equal_time"] = c_image
    return out
