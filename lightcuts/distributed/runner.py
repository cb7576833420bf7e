"""A render on a cluster: the inputs shipped to every worker once, the image as tiles, the further
passes of a converging render as tasks, the mean summed in pass order here.

:class:`ClusterRunner` is the ``runner`` of :func:`lightcuts.pipeline.rendering.render_run`: the client
makes the scene, pass 0's lights and trees as a local run does, then :meth:`ClusterRunner.passes`
scatters them to every worker (``broadcast=True``: one copy per worker, kept for the run), submits
passes 1..N-1 as one task each (lights, trees and image on one worker) and then pass 0's image as
tiles (Dask runs earlier submissions first, so the small tiles fill the end), and feeds the results
to the same :class:`~lightcuts.pipeline.passes.PassMean` as a local run, in pass order. A worker that dies
loses only its running tasks, which Dask runs again on the others; the tiles' pixels do not depend on
where they ran.
"""

from __future__ import annotations

import pickle
import secrets
import threading
import time

from lightcuts.distributed.options import DEFAULT_TILE_SIZE
from lightcuts.distributed.worker import in_run
from lightcuts.errors import LightcutsError

#: Seconds between looks for finished tasks (and, once a second, for the cluster's workers).
POLL = 0.02


def nbytes(obj) -> int:
    """Bytes of ``obj`` as Dask sends it (pickle protocol 5, arrays as out-of-band buffers)."""
    buffers = []
    head = pickle.dumps(obj, protocol=5, buffer_callback=buffers.append)
    return len(head) + sum(b.raw().nbytes for b in buffers)


def tile_task(token, cfg, scene, envmap, lights, trees, window, reference: bool) -> dict:
    """On a worker: the RenderResult of the crop window ``window`` of the run's image (with
    ``reference``, of the all-lights reference), as a local render computes those pixels."""
    def body(run):
        from lightcuts.integrators.registry import make_integrator

        integ = make_integrator(cfg, run.plan.integrator)
        used = None if reference else trees
        if reference:
            integ = integ.reference()
        forest = run.forest(integ, lights, used)
        return integ.render(run.scene, run.caster, lights, used, forest=forest, envmap=envmap, seed=cfg.seed,
                            crop=window)

    result, info = in_run(token, cfg, scene, envmap, body)
    return {**info, "window": window, "result": result}


def pass_task(token, cfg, scene, envmap, p: int) -> dict:
    """On a worker: pass ``p`` > 0 of a converging render, as :func:`lightcuts.pipeline.passes.render_passes`
    makes it: lights and trees from the pass's seed (none for an integrator that renders from
    neither), then the image."""
    def body(run):
        from lightcuts.pipeline.passes import pass_lights, pass_seed
        from lightcuts.pipeline.timing import render_timed

        seed = pass_seed(cfg.seed, p)
        ls, tr, t_lights, t_build = pass_lights(run.plan, run.scene, run.caster, envmap, seed)
        result, t_render, _ = render_timed(cfg.model_copy(update={"seed": seed}), run.scene, run.caster, ls, tr, envmap,
                                           no_progress=True, integrator=run.plan.integrator, load=False)
        return {"seed": seed, "result": result, "lights_seconds": t_lights, "build_seconds": t_build,
                "render_seconds": t_render}

    value, info = in_run(token, cfg, scene, envmap, body)
    return {**info, **value, "pass": p}


class ClusterRunner:
    """Renders a run's passes and reference on a :class:`~lightcuts.distributed.session.Session`.

    tile_size : side of the square tiles, pixels. After the run, :meth:`record` gives report.json's
    ``cluster``: the cluster, the bytes and seconds to ship the inputs, tiles and tasks per worker.
    """

    def __init__(self, session, tile_size: int = DEFAULT_TILE_SIZE):
        self.session = session
        self.tile_size = int(tile_size)
        self.token = secrets.token_hex(8)
        session.tokens.append(self.token)  # the workers forget the run when the session closes
        self.shipped = {"bytes": 0, "seconds": 0.0}
        self.tasks = []  # the info of every finished task
        self.wall = 0.0
        self.n_tiles = 0

    @property
    def client(self):
        """The session's Client (waiting for a LocalCluster still starting)."""
        return self.session.client

    def ship(self, *objects) -> list:
        """Futures of ``objects`` held by every worker (scattered with ``broadcast=True``)."""
        t0 = time.perf_counter()
        self.shipped["bytes"] += sum(nbytes(o) for o in objects)
        try:
            futures = self.client.scatter(list(objects), broadcast=True, hash=False, timeout=self.session.timeout)
        except (TimeoutError, OSError) as exc:  # no worker to take them
            raise LightcutsError(f"{self.session.given}: cannot ship the inputs to the workers within "
                                 f"{self.session.timeout:g} s: {' '.join(str(exc).split()) or type(exc).__name__}") from None
        self.shipped["seconds"] += time.perf_counter() - t0
        return self.session.track(futures)

    def key(self, what: str, i: int) -> str:
        """The key of the run's task ``what`` number ``i`` (``what`` without dashes)."""
        return f"lightcuts-{what}-{i}-{self.token}"

    def _tiles(self, cfg, scene, shipped, reference: bool) -> list:
        """Futures of the image's tiles (with ``reference``, the reference's), row by row."""
        from lightcuts.distributed.tiles import tile_windows

        cam = scene.camera
        windows = tile_windows(cam.width, cam.height, cfg.render.crop, self.tile_size)
        scene_f, env_f, lights_f, trees_f = shipped
        what = "referencetile" if reference else "tile"
        futures = [self.client.submit(tile_task, self.token, cfg, scene_f, env_f, lights_f, trees_f, w, reference,
                                      key=self.key(what, i)) for i, w in enumerate(windows)]
        self.n_tiles += len(windows)
        return self.session.track(futures)

    def gather(self, futures, desc: str, progress: bool, on_result, unit: str = "task",
               keep_going: bool = False) -> None:
        """``on_result({**value, "key": the task's key})`` for every future as it finishes (a progress
        bar over them). A task's error is raised here (a cluster's failure as one LightcutsError line):
        at once, or with ``keep_going`` once the other tasks have finished (a study keeps their results)."""
        from distributed import as_completed

        from lightcuts.pipeline.timing import progress_bar

        failed = None
        with progress_bar(len(futures), desc, not progress, unit=unit) as bar:
            for future in self._finished(as_completed(futures, loop=self.client.loop)):
                try:
                    value = {**_result(future, self.session.given), "key": future.key}
                except Exception as exc:
                    if self.session.closed:  # closed under the run by an interrupt: the handler ends the process
                        threading.Event().wait()
                    if not keep_going:
                        raise
                    failed = failed or exc
                    bar.update(1)
                    continue
                self.tasks.append({k: value[k] for k in ("worker", "pid", "threads", "seconds", "setup_seconds",
                                                         "start", "end")} | {"key": future.key,
                                                                             "tile": "window" in value})
                on_result(value)
                future.release()
                bar.update(1)
        if failed is not None:
            raise failed

    def _finished(self, futures):
        """The futures of an ``as_completed`` as they finish; LightcutsError naming the cluster when it
        has had no worker for the session's connect timeout (its tasks would wait for ever)."""
        alone = None
        looked = time.perf_counter()
        while not futures.is_empty():
            batch = futures.next_batch(block=False)
            yield from batch
            if batch:
                alone = None
                continue
            time.sleep(POLL)
            if time.perf_counter() - looked < 1.0:
                continue
            looked = time.perf_counter()
            if self.session.workers():
                alone = None
            elif alone is None:
                alone = looked
            elif looked - alone > self.session.timeout:
                raise LightcutsError(f"{self.session.given}: no worker on the cluster for {self.session.timeout:g} s; "
                                     f"the run's tasks wait for one (start one with: dask worker "
                                     f"{self.client.scheduler.address})")

    def passes(self, cfg, plan, scene, caster, envmap, *, desc: str = "lightcuts", progress: bool = True,
               lights=None, trees=None, on_pass=None, before_render=None):
        """:func:`lightcuts.pipeline.passes.render_passes` on the cluster (pass 0's ``lights`` and ``trees``
        made by the caller): the same image, cut sizes, ray counts and changes, byte for byte (the
        clamped fraction up to rounding, :class:`~lightcuts.distributed.tiles.Mosaic`). Pass 0's
        ``render_seconds`` is the wall time until its last tile, the others' their worker's time."""
        from lightcuts.pipeline.passes import PassMean, pass_seed
        from lightcuts.distributed.tiles import Mosaic

        if before_render is not None:
            before_render()
        n = int(cfg.render.passes)
        shipped = self.ship(scene, envmap, lights, trees)
        t0 = time.perf_counter()
        later = [self.client.submit(pass_task, self.token, cfg, shipped[0], shipped[1], p, key=self.key("pass", p))
                 for p in range(1, n)]
        later = self.session.track(later)
        tiles = self._tiles(cfg, scene, shipped, reference=False)
        cam = scene.camera
        crop = cfg.render.crop if cfg.render.crop is not None else (0, 0, cam.width, cam.height)
        mosaic = Mosaic(crop)
        mean = PassMean(n, on_pass)
        done = {}

        def on_result(value):
            if "window" in value:
                mosaic.add(value["window"], value["result"])
                if mosaic.complete:
                    done[0] = {"seed": pass_seed(cfg.seed, 0), "result": mosaic.result(time.perf_counter() - t0),
                               "lights_seconds": 0.0, "build_seconds": 0.0, "render_seconds": time.perf_counter() - t0}
            else:
                done[value["pass"]] = value
            while len(mean.records) in done:
                v = done.pop(len(mean.records))
                mean.add(len(mean.records), v["seed"], v["result"], v["lights_seconds"], v["build_seconds"],
                         v["render_seconds"])

        self.gather(later + tiles, desc if n == 1 else f"{desc}, {n} passes", progress, on_result)
        self.wall += time.perf_counter() - t0
        return mean.finish(0.0, lights, trees)

    def reference(self, cfg, plan, scene, lights, envmap, desc: str, progress: bool):
        """The all-lights reference image as tiles (a RenderResult, the local one's pixels)."""
        from lightcuts.distributed.tiles import Mosaic

        shipped = self.ship(scene, envmap, lights, None)
        t0 = time.perf_counter()
        tiles = self._tiles(cfg, scene, shipped, reference=True)
        cam = scene.camera
        mosaic = Mosaic(cfg.render.crop if cfg.render.crop is not None else (0, 0, cam.width, cam.height))
        self.gather(tiles, desc, progress, lambda v: mosaic.add(v["window"], v["result"]))
        self.wall += time.perf_counter() - t0
        return mosaic.result(time.perf_counter() - t0)

    def compare_rows(self, cfg, plans, labels, shared, store, pixels, progress: bool) -> tuple:
        """The reference and rows of a compare (:func:`lightcuts.distributed.studies.compare_rows`)."""
        from lightcuts.distributed.studies import compare_rows

        t0 = time.perf_counter()
        try:
            return compare_rows(self, cfg, plans, labels, shared, store, pixels, progress)
        finally:
            self.wall += time.perf_counter() - t0

    def scaling_points(self, cfg, scene, point_cfgs, specs, make_lights, point, progress: bool) -> list:
        """The points of a scaling study (:func:`lightcuts.distributed.studies.scaling_points`)."""
        from lightcuts.distributed.studies import scaling_points

        t0 = time.perf_counter()
        try:
            return scaling_points(self, cfg, scene, point_cfgs, specs, make_lights, point, progress)
        finally:
            self.wall += time.perf_counter() - t0

    def record(self) -> dict:
        """report.json's ``cluster``: the cluster (:meth:`Session.record`), ``tile_size`` and ``tiles`` (if any),
        ``ship_bytes`` and ``ship_seconds`` (scattering the inputs to every worker), ``seconds`` (wall
        time of the tasks), and per worker address its ``tiles``, ``tasks``, busy ``seconds`` and
        ``setup_seconds`` (its ray caster and kernels)."""
        per = {}
        for t in self.tasks:
            w = per.setdefault(t["worker"], {"tiles": 0, "tasks": 0, "seconds": 0.0, "setup_seconds": 0.0,
                                             "threads": t["threads"]})
            w["tasks"] += 1
            w["tiles"] += int(t["tile"])
            w["seconds"] += t["seconds"]
            w["setup_seconds"] += t.get("setup_seconds", 0.0)
        for f in self.session.warming:
            if f.done() and f.status == "finished":
                info = f.result()
                w = per.setdefault(info["worker"], {"tiles": 0, "tasks": 0, "seconds": 0.0, "setup_seconds": 0.0,
                                                    "threads": info["threads"]})
                w["setup_seconds"] += info["warm_seconds"]
        tiles = {"tile_size": self.tile_size, "tiles": self.n_tiles} if self.n_tiles else {}
        return {**self.session.record(), **tiles, "ship_bytes": self.shipped["bytes"],
                "ship_seconds": self.shipped["seconds"], "seconds": self.wall, "per_worker": dict(sorted(per.items()))}


def _result(future, given: str):
    """The future's value; a cluster failure (workers dying again and again, the scheduler gone) as one
    LightcutsError line naming the cluster, the task's own errors as they are."""
    from distributed import CancelledError
    from distributed.scheduler import KilledWorker

    try:
        return future.result()
    except KilledWorker as exc:
        raise LightcutsError(f"{given}: the workers running a task died again and again: {exc}") from None
    except CancelledError:
        raise LightcutsError(f"{given}: the cluster lost the run's tasks or their inputs (every worker holding "
                             "them left, or the scheduler closed)") from None
    except OSError as exc:
        raise LightcutsError(f"{given}: lost the cluster: {' '.join(str(exc).split())}") from None
