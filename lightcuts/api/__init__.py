"""The Python API: the CLI's ``render`` and ``compare`` as functions returning arrays, for notebooks.

    import lightcuts
    cfg = lightcuts.load_config("configs/cornell.yaml", **{"camera.resolution": [128, 128]}, render__eps=0.01)
    r = lightcuts.render(cfg)          # r.image (H, W, 3) float32, r.cut_size (H, W), r.report
    r                                  # in Jupyter: the tone-mapped image
    r.save("renders/mine")             # the files `lightcuts render` writes; nothing is written before

Each function runs the same plan step and stages as its command (``lightcuts render`` and
``lightcuts compare`` call them), so the same config gives the same pixels. Errors in the config or
the arguments raise :class:`lightcuts.LightcutsError` (one line naming the key) before any work.
Importing this module loads no stage; the stages are imported when a function runs.
"""

from __future__ import annotations

import os
from pathlib import Path

from lightcuts.errors import LightcutsError
from lightcuts.pipeline.comparing import DEFAULT_PIXELS, Comparison
from lightcuts.pipeline.rendering import Render

__all__ = ["load_config", "render", "compare", "Render", "Comparison"]


def load_config(path, **overrides):
    """The validated :class:`~lightcuts.config.RunConfig` of a YAML run file, with overrides.

    overrides : config keys and Python values, as ``--set`` takes them: a dotted key
        (``**{"render.eps": 0.01}``) or the same with ``__`` for each dot (``render__eps=0.01``).
        The values are Python objects (``[64, 64]``, ``"bvh-sah"``), not YAML text.
    """
    from lightcuts.config import load_config as load

    return load(path, values={key.replace("__", "."): value for key, value in overrides.items()})


def _config(config):
    """(RunConfig, the file it came from or None) of a RunConfig or a path. A RunConfig is validated
    again (its fields can be assigned after loading), from what it sets (:func:`_given`)."""
    from lightcuts.config import RunConfig
    from lightcuts.config.schema import config_from_dict
    from lightcuts.errors import LightcutsError

    if isinstance(config, RunConfig):
        try:
            data = _given(config)
        except RecursionError:
            raise LightcutsError("config: a field holds a value that contains itself") from None
        return config_from_dict(data, "config", config.base_dir), None
    if not isinstance(config, (str, os.PathLike)):
        raise LightcutsError(f"config {config!r}: expected a RunConfig (lightcuts.load_config) or the path of a "
                             f"YAML run file, got {type(config).__name__}")
    return load_config(config), str(Path(config))


def _given(value):
    """A config model as the dict of what it sets, as it set it, and of the sections left at their
    default where fields were assigned since: validated again, it sets the same fields, for
    stages that tell a given value from a default (e.g. ``lights.direct.count`` in a scene without
    emitters). Values that are not models are kept as they are, for the validation to judge."""
    from pydantic import BaseModel

    if isinstance(value, BaseModel):
        out = {}
        for k, f in type(value).model_fields.items():
            given = _given(getattr(value, k))
            if not f.exclude and (k in value.model_fields_set or (isinstance(getattr(value, k), BaseModel) and given)):
                out[k] = given
        return out
    if isinstance(value, (list, tuple)):
        return [_given(v) for v in value]
    if isinstance(value, dict):
        return {k: _given(v) for k, v in value.items()}
    return value


def _flag(value, key: str) -> bool:
    """``value`` as a bool; LightcutsError naming ``key`` unless it is one (Python's or numpy's)."""
    from lightcuts.errors import LightcutsError

    if isinstance(value, bool) or type(value).__name__ == "bool_":
        return bool(value)
    raise LightcutsError(f"{key} {value!r}: expected True or False, got {type(value).__name__}")


def _count(value, key: str, lo: int, hi: int) -> int:
    """``value`` as an int in [lo, hi]; LightcutsError naming ``key`` and the bounds otherwise."""
    import numbers

    from lightcuts.errors import LightcutsError

    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise LightcutsError(f"{key} {value!r}: expected an integer, got {type(value).__name__}")
    if not lo <= value <= hi:
        raise LightcutsError(f"{key} {value}: must be from {lo} to {hi:,}")
    return int(value)


def render(config, *, reference: bool = False, progress: bool = True, cluster=None,
           tile_size: int | None = None) -> Render:
    """Render a run: config -> plan -> scene -> lights -> trees -> image, as ``lightcuts render``.

    config : a RunConfig (:func:`load_config`) or the path of a YAML run file
    reference : also render the all-lights reference (every light, every pixel; slow) and put its
        error in the report
    progress : progress bars on stderr
    cluster : None (this process), or a ``distributed.Client`` or a scheduler address
        (``tcp://host:port``) whose workers render the image's tiles and passes, as ``--scheduler``
        does (the same pixels); a Client is left open. tile_size : the tiles' side, pixels (default
        as ``--tile-size``)
    """
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.pipeline.rendering import render_run

    cfg, source = _config(config)
    reference, progress = _flag(reference, "reference"), _flag(progress, "progress")
    plan = plan_run(cfg, render=True)
    if cluster is None:
        if tile_size is not None:
            raise LightcutsError("tile_size: only with a cluster")
        return render_run(cfg, plan, source, reference, progress)
    from lightcuts.distributed.options import DEFAULT_TILE_SIZE, MAX_TILE_SIZE
    from lightcuts.distributed.runner import ClusterRunner
    from lightcuts.distributed.session import cluster_session

    tile_size = _count(DEFAULT_TILE_SIZE if tile_size is None else tile_size, "tile_size", 1, MAX_TILE_SIZE)
    with cluster_session(cluster, plan.integrator.trait("kernels")) as session:
        return render_run(cfg, plan, source, reference, progress, ClusterRunner(session, tile_size))


def compare(config, builders=None, metrics=None, *, pixels: int = DEFAULT_PIXELS, store=None,
            force: bool = False, mitsuba_spp: int | None = None, progress: bool = True,
            cluster=None) -> Comparison:
    """Render the run once per builder (and metric), as ``lightcuts compare``: the 2008 paper's Fig. 8.

    builders, metrics : names, as a list or comma-separated (default the five builders of
        ``lightcuts compare`` and the config's metric); a builder that reads a metric gets a row per metric
    pixels : size of the seeded pixel sample the error against the all-lights reference is measured
        on (0: no error columns)
    store : folder keeping finished rows between calls (``lightcuts compare`` uses ``<out>/rows``);
        None keeps nothing. force : recompute rows the store has
    mitsuba_spp : add the study against Mitsuba's path tracer at equal time, with a long Mitsuba
        render of that many spp (needs the ``mitsuba`` extra)
    cluster : None, or a ``distributed.Client`` or a scheduler address whose workers compute the
        rows, as ``lightcuts compare --scheduler`` (the same rows); a Client is left open

    Returns a :class:`Comparison`: ``.rows`` as table.csv has them, ``.cut_sizes`` and ``.images``
    per row label, ``.report``, ``.save(folder)``.
    """
    from lightcuts.pipeline.comparing import compare_run, resolve_rows, sample_pixels
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.pipeline.rendering import check_reference_lights
    from lightcuts.io import check_store_dir
    from lightcuts.limits import MAX_PIXELS, MAX_REFERENCE_SPP
    from lightcuts.report.compare_store import RowStore
    from lightcuts.scene.build import image_size

    cfg, source = _config(config)
    pixels = _count(pixels, "pixels", 0, MAX_PIXELS)
    force, progress = _flag(force, "force"), _flag(progress, "progress")
    if store is not None:
        store = check_store_dir(store, "store")
    if mitsuba_spp is not None:
        from lightcuts.mitsuba import load_mitsuba

        mitsuba_spp = _count(mitsuba_spp, "mitsuba_spp", 1, MAX_REFERENCE_SPP)
        load_mitsuba()
    rows = resolve_rows(cfg, builders, metrics, keys=("builders", "metrics"))
    plans = [plan_run(cfg, render=True, tree=spec) for _, spec in rows]
    if pixels:
        check_reference_lights(cfg, "pixels", "give pixels=0 (no error columns) or ")
    labels = [label for label, _ in rows]
    width, height = image_size(cfg)
    sample = sample_pixels(width, height, cfg.render.crop, pixels, cfg.seed) if pixels else None
    def run(runner=None):
        return compare_run(cfg, plans, labels, sample, RowStore(store, force), source=source,
                           mitsuba_spp=mitsuba_spp, progress=progress, runner=runner)

    if cluster is None:
        return run()
    from lightcuts.distributed.runner import ClusterRunner
    from lightcuts.distributed.session import cluster_session

    with cluster_session(cluster, plans[0].integrator.trait("kernels")) as session:
        return run(ClusterRunner(session))
