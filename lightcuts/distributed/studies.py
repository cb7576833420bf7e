"""The study commands on a cluster: compare rows and scaling points as tasks, their values those of
the local run.

Compare (:func:`compare_rows`): the rows and reference the row store lacks are computed on the
workers (the reference on the pixel sample in chunks of :data:`REFERENCE_CHUNK` pixels, each row's
trees and image as one task, as :func:`lightcuts.pipeline.comparing.compute_row` computes them locally,
after the scene and lights were shipped once); the client adds each row's error against the
reference and stores it as soon as both are in, so an interrupted study keeps its finished rows and
the next run (on a cluster or not: the store's keys are the same) computes only the rest. A row that
fails lets the running ones finish (and be stored) before its error stops the study.

Scaling (:func:`scaling_points`): one task per light count traces the VPLs (they stay on the
worker), one task per (count, builder) times the builds there and, with ``--render``, renders.
Times are the workers' own, with their share of the cores.
"""

from __future__ import annotations

import time

import numpy as np

from lightcuts.distributed.worker import in_run

#: Pixels of the compare reference per task.
REFERENCE_CHUNK = 64


def _names(spec) -> tuple:
    """A TreeSpec as (builder, metric name or None, c), which a worker resolves again."""
    return spec.name, spec.metric.name if spec.metric is not None else None, spec.c


def _spec(names):
    from lightcuts.trees.spec import tree_spec

    return tree_spec(*names)


def reference_task(token, cfg, scene, envmap, lights, pixels) -> dict:
    """On a worker: the all-lights reference of the pixels ``pixels`` ((K, 2) int64)."""
    def body(run):
        from lightcuts.integrators.registry import make_integrator

        integ = make_integrator(cfg, run.plan.integrator).reference()
        ref = integ.render(run.scene, run.caster, lights, None, forest=run.forest(integ, lights, None), envmap=envmap,
                           seed=cfg.seed, pixels=pixels)
        return {"image": ref.image[:, 0], "shadow_rays": int(ref.shadow_rays)}

    value, info = in_run(token, cfg, scene, envmap, body)
    return {**info, **value}


def row_task(token, cfg, scene, envmap, lights, tree: tuple, label: str, shared_seconds: float,
             lights_seconds: float) -> dict:
    """On a worker: a compare row without its error columns (:func:`lightcuts.pipeline.comparing.compute_row`)."""
    def body(run):
        from lightcuts.pipeline.comparing import compute_row
        from lightcuts.pipeline.plan import plan_run

        plan = plan_run(cfg, render=True, tree=_spec(tree))
        return compute_row(cfg, plan, label, run.scene, run.caster, lights, envmap, shared_seconds, lights_seconds,
                           progress=False)

    value, info = in_run(token, cfg, scene, envmap, body)
    return {**info, "computed": value}


def compare_rows(runner, cfg, plans, labels, shared, store, pixels, progress: bool) -> tuple:
    """``(reference, results)`` as :func:`lightcuts.pipeline.comparing.compare_run` computes them, with
    what the store lacks computed on the runner's cluster."""
    from lightcuts.pipeline.comparing import (finish_row, reference_key, row_key, save_reference, stored_reference,
                                         stored_row)

    ref_key = reference_key(cfg, pixels) if pixels is not None else None
    reference = stored_reference(store, ref_key) if pixels is not None else None
    keys = [row_key(cfg, plan, pixels) for plan in plans]
    results = [stored_row(store, plan, label, key) for plan, label, key in zip(plans, labels, keys)]
    missing = [i for i, r in enumerate(results) if r is None]
    need_reference = pixels is not None and reference is None
    if not missing and not need_reference:
        return reference, results
    s = shared.get()
    scene_f, env_f, lights_f = runner.ship(s.scene, s.envmap, s.lights)
    client, token = runner.client, runner.token
    t0 = time.perf_counter()
    futures = []
    chunks = []
    if need_reference:
        chunks = [pixels[i:i + REFERENCE_CHUNK] for i in range(0, len(pixels), REFERENCE_CHUNK)]
        futures += [client.submit(reference_task, token, cfg, scene_f, env_f, lights_f, chunk,
                                  key=runner.key("reference", i)) for i, chunk in enumerate(chunks)]
    futures += [client.submit(row_task, token, cfg, scene_f, env_f, lights_f, _names(plans[i].tree), labels[i],
                              s.seconds, s.lights_seconds, key=runner.key("row", i)) for i in missing]
    futures = runner.session.track(futures)
    parts, held = {}, {}
    state = {"reference": reference}

    def finish(i, computed):
        computed["row"]["plugins"] = plans[i].record()
        results[i] = finish_row(cfg, computed, pixels, state["reference"], store, labels[i], keys[i])

    def on_result(value):
        kind, i = value["key"].split("-")[1], int(value["key"].split("-")[2])
        if kind == "reference":
            parts[i] = value
            if len(parts) == len(chunks):
                state["reference"] = {"image": np.concatenate([parts[k]["image"] for k in range(len(chunks))]),
                                      "seconds": time.perf_counter() - t0,
                                      "shadow_rays": int(sum(p["shadow_rays"] for p in parts.values()))}
                save_reference(store, ref_key, state["reference"])
                for j, computed in sorted(held.items()):
                    finish(j, computed)
                held.clear()
        elif pixels is not None and state["reference"] is None:
            held[i] = value["computed"]  # its error needs the whole reference
        else:
            finish(i, value["computed"])

    runner.gather(futures, f"{cfg.name}: {len(missing)} rows" + (", reference" if need_reference else ""),
                  progress, on_result, keep_going=True)
    return state["reference"], results


def lights_task(token, cfg, scene, point_cfg, make_lights):
    """On a worker: ``make_lights(point_cfg, scene, caster)``, a scaling point's light set (it stays on
    the worker for the builds)."""
    value, _ = in_run(token, cfg, scene, None, lambda run: make_lights(point_cfg, run.scene, run.caster))
    return value


def point_task(token, cfg, scene, point_cfg, lights, tree: tuple, point) -> dict:
    """On a worker: ``point(point_cfg, scene, caster, lights, spec, warm)`` for one (count, builder):
    ``warm`` is True the first time the builder runs on this worker (its kernels to load), as locally."""
    def body(run):
        spec = _spec(tree)
        warm = spec.name not in run.warmed
        run.warmed.add(spec.name)
        return point(point_cfg, run.scene, run.caster, lights, spec, warm)

    value, info = in_run(token, cfg, scene, None, body)
    return {**info, "point": value}


def scaling_points(runner, cfg, scene, point_cfgs: list, specs: list, make_lights, point, progress: bool) -> list:
    """``[point(...) for each light count, for each spec]`` in that order, on the runner's cluster:
    ``make_lights(point_cfg, scene, caster)`` once per count (``point_cfgs``, one config each),
    ``point(point_cfg, scene, caster, lights, spec, warm)`` per (count, spec) on the worker that holds
    (or fetches) the count's lights. Both must pickle by reference (module-level functions or
    ``functools.partial`` of them), as the workers import them."""
    client, token = runner.client, runner.token
    (scene_f,) = runner.ship(scene)
    light_futures = runner.session.track([
        client.submit(lights_task, token, cfg, scene_f, pcfg, make_lights, key=runner.key("lights", k))
        for k, pcfg in enumerate(point_cfgs)])
    futures = runner.session.track([
        client.submit(point_task, token, cfg, scene_f, point_cfgs[k], light_futures[k], _names(spec), point,
                      key=runner.key("point", k * len(specs) + j))
        for k in range(len(point_cfgs)) for j, spec in enumerate(specs)])
    out = {}

    def on_result(value):
        out[int(value["key"].split("-")[2])] = value["point"]

    runner.gather(futures, "scaling", progress, on_result, unit="point")
    return [out[i] for i in range(len(futures))]
