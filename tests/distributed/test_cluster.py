"""Renders on a Dask LocalCluster of two worker processes: the local render's bytes whatever the tile
size, with passes, after a worker is killed mid-render; one lightcuts task at a time per worker; a
scheduler that cannot be reached, has no worker or other versions; no worker process left behind."""

import json
import logging
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import psutil
import pytest

from lightcuts.cli import main
from lightcuts.distributed.runner import ClusterRunner
from lightcuts.distributed.session import Session

ROOT = Path(__file__).parents[2]
#: Tests that start worker processes (a LocalCluster of processes): ``slow``, as tests/conftest.py marks
#: the tests that start the CLI.
SPAWNS = pytest.mark.slow
SMALL = {"camera.resolution": "[48,36]", "lights.indirect.count": "2000", "lights.direct.count": "64"}
CONFIGS = {"cornell": ("cornell.yaml", SMALL),
           "kitchen": ("kitchen.yaml", {**SMALL, "scene.procedural.triangles": "20000"}),
           "cornell-multidimensional": ("cornell.yaml", {**SMALL, "render.spp": "4",
                                                         "render.integrator": "multidimensional"}),
           "cornell-path": ("cornell.yaml", {**SMALL, "render.spp": "4", "render.passes": "2",
                                             "render.integrator": "{type: path, max_depth: 8}"}),
           "cornell-path-tree": ("cornell.yaml", {**SMALL, "render.spp": "4", "render.passes": "2",
                                                  "render.integrator": "{type: path, max_depth: 8, light_sampler: tree}"}),
           "cornell-stochastic": ("cornell.yaml", {**SMALL, "render.spp": "2", "render.passes": "2",
                                                   "lights.direct.source": "triangles",
                                                   "render.integrator": "{type: stochastic-lightcuts, max_cut: 8}"}),
           "kitchen-passes": ("kitchen.yaml", {**SMALL, "scene.procedural.triangles": "20000", "render.passes": "3",
                                                "render.compensation": "true"}),
           "kitchen-slow": ("kitchen.yaml", {**SMALL, "scene.procedural.triangles": "20000",
                                             "camera.resolution": "[64,48]", "render.spp": "4"})}


def config(name):
    from lightcuts.config import load_config

    file, overrides = CONFIGS[name]
    return load_config(ROOT / "configs" / file, [f"{k}={v}" for k, v in overrides.items()])


def render(cfg, runner=None):
    from lightcuts.pipeline.rendering import render_run
    from lightcuts.pipeline.plan import plan_run

    return render_run(cfg, plan_run(cfg, render=True), None, progress=False, runner=runner)


@lru_cache
def local(name):
    return render(config(name))


@pytest.fixture(scope="module")
def cluster():
    from distributed import Client, LocalCluster

    lc = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address="127.0.0.1:0",
                      silence_logs=logging.ERROR)
    client = Client(lc, set_as_default=False)
    yield SimpleNamespace(cluster=lc, client=client, address=lc.scheduler_address)
    client.close()
    lc.close()


@contextmanager
def session(cluster):
    cluster.client.wait_for_workers(2, timeout=60)  # a killed worker's nanny starts a new one
    s = Session(cluster.client, None, cluster.address, owned=False)
    try:
        yield s
    finally:
        s.close()


def same_pixels(a, b):
    return (a.image.tobytes() == b.image.tobytes() and a.cut_size.tobytes() == b.cut_size.tobytes()
            and a.report["shadow_rays"] == b.report["shadow_rays"] and a.report["eye_rays"] == b.report["eye_rays"])


@SPAWNS
def test_the_python_api_renders_and_compares_on_a_client_or_an_address(cluster):
    """``lightcuts.render(cfg, cluster=...)`` with the caller's Client (left open) or the scheduler's
    address gives the local pixels; ``lightcuts.compare(cfg, cluster=...)`` the local rows."""
    import lightcuts

    cfg = config("cornell")
    cluster.client.wait_for_workers(2, timeout=60)
    on_client = lightcuts.render(cfg, progress=False, cluster=cluster.client, tile_size=16)
    assert cluster.client.status == "running"
    assert on_client.report["cluster"]["tiles"] > 1
    on_address = lightcuts.render(cfg, progress=False, cluster=cluster.address)
    assert same_pixels(on_client, local("cornell")) and same_pixels(on_address, local("cornell"))
    here = lightcuts.compare(cfg, builders="divisive-3d,saoh", pixels=8, progress=False)
    there = lightcuts.compare(cfg, builders="divisive-3d,saoh", pixels=8, progress=False, cluster=cluster.client)
    assert cluster.client.status == "running"
    for label in here.images:
        assert here.images[label].tobytes() == there.images[label].tobytes()
        assert here.cut_sizes[label].tobytes() == there.cut_sizes[label].tobytes()


@SPAWNS
@pytest.mark.parametrize("name", ["cornell", "kitchen", "cornell-multidimensional", "cornell-path", "cornell-path-tree",
                                  "cornell-stochastic"])
def test_tiles_give_the_local_bytes_whatever_their_size(cluster, name):
    from lightcuts.distributed.worker import runs

    for tile in (16, 20):
        with session(cluster) as s:
            runner = ClusterRunner(s, tile)
            r = render(config(name), runner)
        assert same_pixels(r, local(name)), (name, tile)
        assert all(kept == [] for kept in cluster.client.run(runs).values())  # each worker forgot the run
        rec = r.report["cluster"]
        n = -(-48 // tile) * -(-36 // tile)
        assert rec["tiles"] == n and sum(w["tiles"] for w in rec["per_worker"].values()) == n
        assert rec["workers"] == 2 and rec["ship_bytes"] > 0 and rec["given"] == cluster.address
        assert r.report["clamping"]["clamped_energy_fraction"] == pytest.approx(
            local(name).report["clamping"]["clamped_energy_fraction"], rel=1e-7)  # from the tiles' means
        sampler = {k: v for k, v in r.report.get("light_sampler", {}).items() if k != "build_seconds"}
        assert sampler == {k: v for k, v in local(name).report.get("light_sampler", {}).items() if k != "build_seconds"}
        if name.startswith("cornell-path"):  # no lights or trees, for pass 0 nor for pass 1's task
            assert r.report["lights"] == {} and len(r.report["passes"]) == 2
            assert all(p["lights_seconds"] == p["build_seconds"] == 0.0 for p in r.report["passes"])


@SPAWNS
def test_passes_as_tasks_give_the_local_mean(cluster):
    with session(cluster) as s:
        r = render(config("kitchen-passes"), ClusterRunner(s, 24))
    ref = local("kitchen-passes")
    assert same_pixels(r, ref)
    assert [p["seed"] for p in r.report["passes"]] == [p["seed"] for p in ref.report["passes"]]
    assert [p["change"] for p in r.report["passes"]] == [p["change"] for p in ref.report["passes"]]
    assert sum(w["tasks"] for w in r.report["cluster"]["per_worker"].values()) == 2 + 4  # passes 1, 2 and 4 tiles


@SPAWNS
def test_the_command_on_a_scheduler_writes_the_local_files(cluster, tmp_path):
    file, overrides = CONFIGS["kitchen"]
    args = ["render", str(ROOT / "configs" / file), "--no-progress"]
    for k, v in overrides.items():
        args += ["--set", f"{k}={v}"]
    assert main(args + ["--out", str(tmp_path / "local"), "--reference"]) == 0
    assert main(args + ["--out", str(tmp_path / "cluster"), "--reference", "--scheduler", cluster.address,
                        "--tile-size", "32"]) == 0
    for f in ("image.exr", "image.png", "cutsize.png", "reference.exr"):
        assert (tmp_path / "local" / f).read_bytes() == (tmp_path / "cluster" / f).read_bytes(), f
    report = json.loads((tmp_path / "cluster" / "report.json").read_text())
    rec = report["cluster"]
    assert rec["given"] == cluster.address and rec["tiles"] == 4 + 4 and rec["tile_size"] == 32  # image, reference
    assert report["reference"]["relative_error"] == \
        json.loads((tmp_path / "local" / "report.json").read_text())["reference"]["relative_error"]
    assert "cluster" not in json.loads((tmp_path / "local" / "report.json").read_text())


@SPAWNS
def test_a_killed_worker_loses_only_its_running_tiles(cluster):
    client = cluster.client
    out = {}
    with session(cluster) as s:
        runner = ClusterRunner(s, 8)  # 48 tiles
        thread = threading.Thread(target=lambda: out.update(r=render(config("kitchen-slow"), runner)))
        thread.start()
        victim, lost = None, set()
        deadline = time.time() + 120
        while time.time() < deadline and victim is None:
            running = {w: {k for k in keys if "-tile-" in str(k)} for w, keys in client.processing().items()}
            if any("-tile-" in t["key"] for t in runner.tasks):
                victim = next((w for w, keys in running.items() if keys), None)
                lost = running.get(victim, set())
            time.sleep(0.01)
        assert victim is not None, "no tile was running"
        pid = client.run(os.getpid, workers=[victim])[victim]
        killed = time.time()
        os.kill(pid, signal.SIGKILL)
        thread.join(180)
    assert same_pixels(out["r"], local("kitchen-slow"))
    where = {t["key"]: t["worker"] for t in runner.tasks}
    assert len(where) == 48 and all(t["end"] < killed for t in runner.tasks if t["worker"] == victim)
    # the tiles it had (at most one finished between the look and the kill) ran again elsewhere
    assert lost and sum(where[str(k)] != victim for k in lost) >= max(1, len(lost) - 1)


def test_a_worker_runs_one_lightcuts_task_at_a_time_on_its_cores():
    """A worker of two threads: its tasks never overlap, each with two numba threads."""
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address="127.0.0.1:0",
                      silence_logs=logging.ERROR) as lc, Client(lc, set_as_default=False) as client:
        s = Session(client, None, "in-process", owned=False)
        runner = ClusterRunner(s, 12)
        r = render(config("kitchen"), runner)
        s.close()
    assert same_pixels(r, local("kitchen"))
    spans = sorted((t["start"], t["end"]) for t in runner.tasks)
    assert len(spans) == 12 and all(t["threads"] == 2 for t in runner.tasks)
    assert all(b[0] >= a[1] for a, b in zip(spans, spans[1:])), spans


def _free_port():
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _render_args(tmp_path, *flags):
    file, overrides = CONFIGS["cornell"]
    args = ["render", str(ROOT / "configs" / file), "--no-progress", "--out", str(tmp_path / "out"), *flags]
    for k, v in overrides.items():
        args += ["--set", f"{k}={v}"]
    return args


def _one_error_line(capsys, monkeypatch, args):
    """(exit code, stderr lines, seconds, whether a scene was made) of ``lightcuts ARGS`` in this process."""
    import lightcuts.scene.build

    made = []
    real = lightcuts.scene.build.scene_from_config
    monkeypatch.setattr(lightcuts.scene.build, "scene_from_config", lambda *a, **k: made.append(1) or real(*a, **k))
    t0 = time.perf_counter()
    rc = main(args)
    return rc, capsys.readouterr().err.strip().splitlines(), time.perf_counter() - t0, bool(made)


def _certificate(folder: Path, name: str) -> tuple[str, str]:
    """A self-signed certificate for 127.0.0.1 and its key (PEM files): its own CA."""
    cert, key = folder / f"{name}.pem", folder / f"{name}-key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out", str(cert),
                    "-days", "1", "-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1"],
                   check=True, capture_output=True)
    return str(cert), str(key)


def test_a_tls_scheduler_with_the_tls_files(tmp_path, capsys, monkeypatch):
    """--scheduler tls://... with --tls-ca/--tls-cert/--tls-key renders; a certificate of another CA is
    one line naming --scheduler."""
    if subprocess.run(["which", "openssl"], capture_output=True).returncode != 0:
        pytest.skip("needs the openssl command to make certificates")
    from distributed import LocalCluster
    from distributed.security import Security

    cert, key = _certificate(tmp_path, "cluster")
    other, other_key = _certificate(tmp_path, "other")
    sec = Security(tls_ca_file=cert, tls_scheduler_cert=cert, tls_scheduler_key=key, tls_worker_cert=cert,
                   tls_worker_key=key, tls_client_cert=cert, tls_client_key=key, require_encryption=True)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tls://", host="127.0.0.1",
                      security=sec, dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR) as lc:
        address = lc.scheduler_address
        assert address.startswith("tls://")
        args = _render_args(tmp_path, "--scheduler", address, "--tls-ca", cert, "--tls-cert", cert, "--tls-key", key)
        assert main(args) == 0
        rc, err, _, made = _one_error_line(capsys, monkeypatch, _render_args(
            tmp_path, "--scheduler", address, "--tls-ca", other, "--tls-cert", other, "--tls-key", other_key,
            "--connect-timeout", "2"))
    assert (tmp_path / "out" / "report.json").exists()
    assert rc == 2 and len(err) == 1 and err[0].startswith(f"error: --scheduler: cannot reach {address}") and not made


def test_a_local_cluster_that_cannot_start_is_one_line(tmp_path, capsys, monkeypatch):
    import distributed

    def refuse(*args, **kwargs):
        raise OSError("no free port")

    monkeypatch.setattr(distributed, "LocalCluster", refuse)
    rc, err, _, _ = _one_error_line(capsys, monkeypatch, _render_args(tmp_path, "--workers", "2"))
    assert rc == 2 and err == ["error: --workers 2: cannot start a Dask LocalCluster: no free port"]
    assert not (tmp_path / "out").exists()


def test_an_unreachable_scheduler_is_one_line_within_the_timeout(tmp_path, capsys, monkeypatch):
    address = f"tcp://127.0.0.1:{_free_port()}"
    rc, err, seconds, made = _one_error_line(capsys, monkeypatch,
                                             _render_args(tmp_path, "--scheduler", address, "--connect-timeout", "2"))
    assert rc == 2 and len(err) == 1 and err[0].startswith(f"error: --scheduler: cannot reach {address} within 2 s")
    assert 1.5 < seconds < 3.5 and not made and not (tmp_path / "out").exists()


def test_a_scheduler_without_workers_is_one_line(tmp_path, capsys, monkeypatch):
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, protocol="tcp", host="127.0.0.1", dashboard_address="127.0.0.1:0",
                      silence_logs=logging.ERROR) as lc:
        rc, err, seconds, made = _one_error_line(capsys, monkeypatch, _render_args(
            tmp_path, "--scheduler", lc.scheduler_address, "--connect-timeout", "1"))
    assert rc == 2 and len(err) == 1 and f"no worker has joined {lc.scheduler_address} within 1 s" in err[0]
    assert seconds < 3 and not made


def test_a_cluster_left_without_workers_is_one_line_not_a_hang():
    from distributed import Client, LocalCluster

    from lightcuts.errors import LightcutsError

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address="127.0.0.1:0",
                      silence_logs=logging.ERROR) as lc, Client(lc, set_as_default=False) as client:
        s = Session(client, None, "a cluster", owned=False, timeout=1.0)
        runner = ClusterRunner(s, 4)  # 108 tiles
        failure = []

        def run():
            try:
                render(config("kitchen-slow"), runner)
            except LightcutsError as exc:
                failure.append(str(exc))

        thread = threading.Thread(target=run)
        thread.start()
        deadline = time.time() + 60
        while time.time() < deadline and not any("-tile-" in t["key"] for t in runner.tasks):
            time.sleep(0.01)
        lc.scale(0)
        thread.join(30)
        s.close()
    assert not thread.is_alive() and len(failure) == 1 and "\n" not in failure[0]
    assert failure[0].startswith(("a cluster: no worker on the cluster for 1 s",
                                  "a cluster: the cluster lost the run's tasks or their inputs"))


def test_tasks_waiting_for_a_worker_give_up_after_the_timeout():
    from distributed import Client, LocalCluster

    from lightcuts.errors import LightcutsError

    with LocalCluster(n_workers=0, processes=False, dashboard_address="127.0.0.1:0",
                      silence_logs=logging.ERROR) as lc, Client(lc, set_as_default=False) as client:
        s = Session(client, None, "a cluster", owned=False, timeout=1.0)
        runner = ClusterRunner(s)
        t0 = time.perf_counter()
        with pytest.raises(LightcutsError, match="^a cluster: no worker on the cluster for 1 s"):
            runner.gather(s.track([client.submit(sum, [1, 2])]), "waiting", False, print)
        with pytest.raises(LightcutsError, match="^a cluster: cannot ship the inputs to the workers within 1 s"):
            runner.ship(np.zeros(3))
        s.close()
    assert time.perf_counter() - t0 < 6


@SPAWNS
def test_closing_a_local_cluster_ends_its_worker_processes():
    """What every run on --workers does at its end; the workers are among the processes recorded for
    the CLI's signal handler (lightcuts.distributed.processes)."""
    from lightcuts.distributed import processes
    from lightcuts.distributed import session as sessions

    s = sessions.local_cluster(2)  # started on a thread
    s.client.wait_for_workers(2)
    pids = list(s.worker_pids)
    assert len(pids) == 2 and all(psutil.pid_exists(p) for p in pids) and s in sessions._OPEN
    assert set(pids) <= set(processes.started())
    s.close()
    assert not [p for p in pids if psutil.pid_exists(p)] and s not in sessions._OPEN and s.closed


@SPAWNS
def test_workers_of_another_lightcuts_version_are_refused(cluster, tmp_path, capsys, monkeypatch):
    def pretend(version):
        import distributed.versions as v

        real = getattr(v, "_real_version_cached", v._version_cached)
        v._real_version_cached = real
        v._version_cached = real if version is None else (lambda pkg: version if pkg == "lightcuts" else real(pkg))

    cluster.client.run(pretend, "0.0.1")
    try:
        rc, err, _, made = _one_error_line(capsys, monkeypatch,
                                           _render_args(tmp_path, "--scheduler", cluster.address))
    finally:
        cluster.client.run(pretend, None)
    assert rc == 2 and len(err) == 1 and not made, err
    assert "has lightcuts 0.0.1, this machine 0.1.0; install the same version on every worker" in err[0]


def _descendants(pid):
    """The processes under ``pid`` but multiprocessing's resource tracker (one per process that spawns,
    alive as long as its parent)."""
    out = set()
    try:
        children = psutil.Process(pid).children(recursive=True)
    except psutil.Error:
        return out
    for p in children:
        try:
            if not any("resource_tracker" in part for part in p.cmdline()):
                out.add(p.pid)
        except psutil.Error:
            pass
    return out


@SPAWNS
def test_a_finished_run_leaves_no_worker_process(tmp_path, capfd):
    before = _descendants(os.getpid())
    seen = set()
    stop = threading.Event()

    def watch():
        while not stop.is_set():
            seen.update(_descendants(os.getpid()) - before)
            time.sleep(0.05)

    watcher = threading.Thread(target=watch)
    watcher.start()
    try:
        assert main(_render_args(tmp_path, "--workers", "2")) == 0
    finally:
        stop.set()
        watcher.join()
    assert len(seen) >= 2  # the LocalCluster's worker processes
    assert not [p for p in seen if psutil.pid_exists(p) and psutil.Process(p).status() != psutil.STATUS_ZOMBIE]
    assert capfd.readouterr().err == ""  # no line of Dask's own (--no-progress)


@pytest.mark.parametrize("flag", ["--workers", "--scheduler"])
def test_ctrl_c_cancels_the_tasks_and_leaves_no_worker_process(cluster, tmp_path, flag):
    file, overrides = CONFIGS["cornell"]
    args = ["render", str(ROOT / "configs" / file), "--no-progress", "--out", str(tmp_path / "out"),
            "--set", "camera.resolution=[96,96]", "--set", "render.spp=16", "--tile-size", "8",
            flag, "2" if flag == "--workers" else cluster.address]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen([sys.executable, "-m", "lightcuts", *args], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    seen = set()
    deadline = time.time() + 120
    while time.time() < deadline:  # until the cluster is busy with the run's tiles
        seen |= _descendants(p.pid)
        busy = cluster.client.processing() if flag == "--scheduler" else {}
        if (flag == "--workers" and len(seen) >= 2) or any(keys for keys in busy.values()):
            break
        time.sleep(0.05)
    time.sleep(3.0 if flag == "--workers" else 0.5)  # the workers at work on the tiles
    seen |= _descendants(p.pid)
    os.killpg(p.pid, signal.SIGINT)  # as Ctrl-C in a terminal: the command and its worker processes
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and err.strip().splitlines() == ["error: interrupted"], err
    deadline = time.time() + 10
    while time.time() < deadline and [q for q in seen if psutil.pid_exists(q)]:
        time.sleep(0.1)
    assert not [q for q in seen if psutil.pid_exists(q)]
    if flag == "--scheduler":
        count = lambda dask_scheduler: len(dask_scheduler.tasks)  # noqa: E731
        deadline = time.time() + 10
        while time.time() < deadline and cluster.client.run_on_scheduler(count):
            time.sleep(0.1)
        assert cluster.client.run_on_scheduler(count) == 0
    assert not (tmp_path / "out").exists()


@SPAWNS
def test_a_textured_scene_gives_the_local_bytes(cluster, tmp_path):
    """Textures travel with the scene: a textured floor under an area light, with indirect VPLs (whose
    colours come from the texture), tiled on the cluster as rendered locally."""
    from PIL import Image

    from lightcuts.config import load_config

    rng = np.random.default_rng(0)
    Image.fromarray(rng.integers(0, 256, size=(8, 8, 3), dtype=np.uint8)).save(tmp_path / "t.png")
    (tmp_path / "floor.obj").write_text(
        "mtllib floor.mtl\nv -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "usemtl m\nf 1/1 3/3 2/2\nf 1/1 4/4 3/3\n")
    (tmp_path / "floor.mtl").write_text("newmtl m\nKd 0.9 0.9 0.9\nmap_Kd t.png\n")
    (tmp_path / "run.yaml").write_text(
        "scene:\n  meshes: [{file: floor.obj}]\n"
        "  emitters: [{position: [0, 1.5, 0], normal: [0, -1, 0], size: [1, 1], radiance: [5, 5, 5]}]\n"
        "camera: {position: [0, 3, 3], look_at: [0, 0, 0], resolution: [40, 30]}\n"
        "lights: {direct: {count: 64}, indirect: {count: 500}}\n")
    cfg = load_config(tmp_path / "run.yaml")
    with session(cluster) as s:
        r = render(cfg, ClusterRunner(s, 16))
    assert r.image.mean() > 0 and same_pixels(r, render(cfg))


def test_a_run_builds_its_light_forest_once_for_its_tiles():
    """Run.forest: one forest per (lights, trees) the tiles share, a new one for other lights; the
    tiles' bytes with it are the local ones (the tests above)."""
    from lightcuts.distributed.worker import Run
    from lightcuts.integrators.lightcut import Lightcuts
    from lightcuts.integrators.path import Path
    from lightcuts.lights.direct import direct_lights
    from lightcuts.scene.cornell import cornell_box
    from lightcuts.trees import build_tree

    scene = cornell_box()
    lights = {"oriented": direct_lights(scene, 64, seed=1)}
    trees = {"oriented": build_tree(lights["oriented"], "agglomerative", seed=1)}
    run = Run(None, scene, None, None, 0.0)
    integ = Lightcuts()
    f = run.forest(integ, lights, trees)
    assert run.forest(integ, lights, trees) is f and len(f.light_f) == 64
    ref = integ.reference()
    assert run.forest(ref, lights, None) is not f and run.forest(ref, lights, None) is run.forest(ref, lights, None)
    other = {"oriented": direct_lights(scene, 32, seed=2)}
    other_trees = {"oriented": build_tree(other["oriented"], "agglomerative", seed=1)}
    assert len(run.forest(integ, other, other_trees).light_f) == 32
    # the path integrator's light tree over the scene's emitting triangles: once per run too
    path_run = Run(None, scene, None, None, 0.0)
    tree = Path(light_sampler="tree")
    made = path_run.forest(tree, lights, trees)
    assert made.record["type"] == "tree" and made.n_lights == {"oriented": 2}
    assert path_run.forest(tree, lights, trees) is made
