"""What the commands share: the ``--set`` option, per-type output names, progress bars."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_set(p: argparse.ArgumentParser) -> None:
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config key, e.g. --set render.eps=0.01 (repeatable)")


def per_type_path(out: Path, typ: str, n_types: int) -> Path:
    """``out`` itself for a single light type, else ``<stem>-<type>.npz`` beside it."""
    return out if n_types == 1 else out.with_name(f"{out.stem}-{typ}{out.suffix or '.npz'}")


def progress_bar(total: int, desc: str, disable: bool = False, unit: str = "row"):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, disable=disable, file=sys.stderr, leave=False,
                dynamic_ncols=True)


def render_settings(cfg, camera, envmap=None) -> dict:
    """The keyword arguments of ``render_image`` / ``render_reference`` that the config sets (all but
    eps and max_cut, which the reference does not take)."""
    return dict(camera=camera, spp=cfg.render.spp, envmap=envmap, seed=cfg.seed, crop=cfg.render.crop,
                clamp=cfg.render.clamp.enabled, clamp_min_distance=cfg.render.clamp.min_distance,
                aperture=cfg.camera.aperture, focus_distance=cfg.camera.focus_distance)


def image_settings(cfg, camera, envmap, integrator) -> dict:
    """:func:`render_settings` and, for an integrator with the ``converging`` trait, the config's
    ``render.compensation``, ``render.representatives`` and ``render.continuation_rays``: every
    keyword of the image's ``integrator.obj`` call but eps, max_cut, progress and the integrator's
    own parameters."""
    settings = render_settings(cfg, camera, envmap)
    if integrator.trait("converging", False):
        settings.update(compensation=cfg.render.compensation, representatives=cfg.render.representatives,
                        continuation_rays=cfg.render.continuation_rays)
    return settings


def render_timed(cfg, scene, caster, lights: dict, trees: dict, envmap=None, desc: str = "lightcuts",
                 no_progress: bool = False, integrator=None, load: bool = True):
    """The config's image: ``(result, seconds, load_seconds)``. The render kernel is loaded (or
    compiled) on one pixel first, untimed in ``seconds`` (its time is ``load_seconds``), so that
    ``seconds`` measures rendering; a progress bar ``desc`` counts rows. ``integrator``: the plan's
    resolved ``render.integrator`` (else resolved here); load False skips the one-pixel render (the
    kernel is loaded already; load_seconds is then 0). The image uses ``cfg.seed`` and, for an
    integrator with the ``converging`` trait, ``render.compensation``, ``render.continuation_rays``
    and ``render.representatives``."""
    import time

    from lightcuts.render.integrators import INTEGRATORS

    if integrator is None:
        integrator = INTEGRATORS.resolve(cfg.render.integrator, "render.integrator")
    render_image = integrator.obj
    settings = image_settings(cfg, scene.camera, envmap, integrator)
    crop = cfg.render.crop
    x0, y0 = (0, 0) if crop is None else crop[:2]
    rows = scene.camera.height if crop is None else crop[3] - crop[1]
    t0 = time.perf_counter()
    if load:
        render_image(scene, caster, lights, trees, eps=cfg.render.eps, max_cut=cfg.render.max_cut,
                     **{**settings, "crop": (x0, y0, x0 + 1, y0 + 1)}, **integrator.params)
    load = time.perf_counter() - t0 if load else 0.0
    with progress_bar(rows, desc, no_progress) as bar:
        t0 = time.perf_counter()
        result = render_image(scene, caster, lights, trees, eps=cfg.render.eps, max_cut=cfg.render.max_cut,
                              progress=bar.update, **settings, **integrator.params)
        seconds = time.perf_counter() - t0
    return result, seconds, load
