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

from pathlib import Path

from lightcuts.api.comparing import DEFAULT_PIXELS, Comparison
from lightcuts.api.rendering import Render

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
    """(RunConfig, the file it came from or None) of a RunConfig or a path."""
    from lightcuts.config import RunConfig

    if isinstance(config, RunConfig):
        return config, None
    return load_config(config), str(Path(config))


def render(config, *, reference: bool = False, progress: bool = True) -> Render:
    """Render a run: config -> plan -> scene -> lights -> trees -> image, as ``lightcuts render``.

    config : a RunConfig (:func:`load_config`) or the path of a YAML run file
    reference : also render the all-lights reference (every light, every pixel; slow) and put its
        error in the report
    progress : progress bars on stderr
    """
    from lightcuts.api.rendering import render_run
    from lightcuts.commands.plan import plan_run

    cfg, source = _config(config)
    return render_run(cfg, plan_run(cfg, render=True), source, reference, progress)


def compare(config, builders=None, metrics=None, *, pixels: int = DEFAULT_PIXELS, store=None,
            force: bool = False, mitsuba_spp: int | None = None, progress: bool = True) -> Comparison:
    """Render the run once per builder (and metric), as ``lightcuts compare``: the 2008 paper's Fig. 8.

    builders, metrics : names, as a list or comma-separated (default the five builders of
        ``lightcuts compare`` and the config's metric); a builder that reads a metric gets a row per metric
    pixels : size of the seeded pixel sample the error against the all-lights reference is measured
        on (0: no error columns)
    store : folder keeping finished rows between calls (``lightcuts compare`` uses ``<out>/rows``);
        None keeps nothing. force : recompute rows the store has
    mitsuba_spp : add the study against Mitsuba's path tracer at equal time, with a long Mitsuba
        render of that many spp (needs the ``mitsuba`` extra)

    Returns a :class:`Comparison`: ``.rows`` as table.csv has them, ``.cut_sizes`` and ``.images``
    per row label, ``.report``, ``.save(folder)``.
    """
    from lightcuts.api.comparing import compare_run, resolve_rows, sample_pixels
    from lightcuts.commands.plan import plan_run
    from lightcuts.errors import LightcutsError
    from lightcuts.report.compare_store import RowStore
    from lightcuts.scene.build import image_size

    cfg, source = _config(config)
    if pixels < 0:
        raise LightcutsError(f"pixels {pixels}: must be >= 0")
    if mitsuba_spp is not None:
        from lightcuts.mitsuba import load_mitsuba

        if mitsuba_spp < 1:
            raise LightcutsError(f"mitsuba_spp {mitsuba_spp}: must be at least 1")
        load_mitsuba()
    rows = resolve_rows(cfg, builders, metrics, keys=("builders", "metrics"))
    plans = [plan_run(cfg, render=True, tree=spec) for _, spec in rows]
    labels = [label for label, _ in rows]
    width, height = image_size(cfg)
    sample = sample_pixels(width, height, cfg.render.crop, pixels, cfg.seed) if pixels else None
    return compare_run(cfg, plans, labels, sample, RowStore(store, force), source=source,
                       mitsuba_spp=mitsuba_spp, progress=progress)
