"""The cluster flags: one line naming the flag for bad values, before any work; without them, no Dask."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import cli_recording_work
from lightcuts.cli import main

ROOT = Path(__file__).parents[2]
SMALL = ["--set", "camera.resolution=[8,8]", "--set", "lights.indirect.count=200", "--set", "lights.direct.count=16"]


@pytest.mark.parametrize("flags, message", [
    (["--workers", "0"], "--workers '0': expected an integer from 1 to 1024"),
    (["--workers", "two"], "--workers 'two': expected an integer from 1 to 1024"),
    (["--workers", "1024"], "--workers 1024: this machine starts at most "),  # on fewer than 128 cores
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"], "--workers: not with --scheduler"),
    (["--scheduler", "127.0.0.1"], "--scheduler '127.0.0.1': expected tcp://HOST:PORT or tls://HOST:PORT"),
    (["--scheduler", "udp://h:1"], "--scheduler 'udp://h:1': expected tcp://HOST:PORT"),
    (["--scheduler", "tls://127.0.0.1:8786"], "a tls:// scheduler needs --tls-ca, --tls-cert, --tls-key"),
    (["--scheduler", "tls://127.0.0.1:8786", "--tls-ca", "ca.pem", "--tls-cert", "c.pem", "--tls-key", "k.pem"],
     "--tls-ca 'ca.pem': no such file"),
    (["--scheduler", "tcp://127.0.0.1:8786", "--tls-ca", "ca.pem"], "--tls-ca: the TLS files need a tls:// scheduler"),
    (["--workers", "2", "--tls-key", "k.pem"], "--tls-key: only with --scheduler tls://"),
    (["--tls-ca", "ca.pem"], "--tls-ca: only with --workers or --scheduler"),
    (["--tile-size", "64"], "--tile-size: only with --workers or --scheduler"),
    (["--workers", "2", "--tile-size", "0"], "--tile-size '0': expected an integer from 1 to 8192"),
    (["--workers", "2", "--connect-timeout", "0"], "--connect-timeout '0': expected seconds"),
    (["--scheduler", "tcp://127.0.0.1:8786", "--connect-timeout", "nan"], "--connect-timeout 'nan': expected seconds"),
])
def test_bad_flags_one_line_before_any_work(tmp_path, capsys, monkeypatch, flags, message):
    import lightcuts.scene.build

    made = []
    monkeypatch.setattr(lightcuts.scene.build, "scene_from_config", lambda *a, **k: made.append(1))
    monkeypatch.chdir(tmp_path)
    rc = main(["render", str(ROOT / "configs/cornell.yaml"), "--out", "out", "--no-progress", *flags, *SMALL])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("error: ") and message in err[0], err
    assert made == [] and not (tmp_path / "out").exists()


def test_compare_and_scaling_take_the_flags(tmp_path):
    """Their flags are checked as render's are, before any scene is made."""
    for argv in (["compare", str(ROOT / "configs/cornell.yaml"), "--out", str(tmp_path / "c"), "--workers", "0"],
                 ["scaling", str(ROOT / "configs/cornell.yaml"), "--out", str(tmp_path / "s"), "--scheduler", "x"],
                 ["scaling", str(ROOT / "configs/cornell.yaml"), "--out", str(tmp_path / "s"), "--gather", "1,4",
                  "--workers", "2"]):
        rc, calls, err = cli_recording_work(argv, tmp_path)
        assert rc == 2 and calls == [] and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert "--gather: the gather study runs on this machine only" in err


_NO_DASK = """
import json, sys
from lightcuts.cli import main
rc = main(json.loads(sys.argv[1]))
print(json.dumps([rc, sorted(m for m in sys.modules if m == "distributed" or m.startswith(("distributed.", "dask")))]))
"""


def test_without_cluster_flags_dask_is_not_imported(tmp_path):
    """A render, compare and scaling without --workers / --scheduler never load Dask."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    for argv in (["render", str(ROOT / "configs/cornell.yaml"), "--out", str(tmp_path / "r"), "--no-progress", *SMALL],
                 ["compare", str(ROOT / "configs/cornell.yaml"), "--out", str(tmp_path / "c"), "--no-progress",
                  "--builders", "divisive-3d", "--pixels", "4", *SMALL],
                 ["scaling", str(ROOT / "configs/cornell.yaml"), "--out", str(tmp_path / "s"), "--no-progress",
                  "--sizes", "300", "--builders", "divisive-3d", "--repeats", "1", *SMALL]):
        r = subprocess.run([sys.executable, "-c", _NO_DASK, json.dumps(argv)], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=300)
        rc, loaded = json.loads(r.stdout.strip().splitlines()[-1])
        assert rc == 0 and loaded == [], (argv[0], loaded, r.stderr)


def test_a_local_cluster_is_bounded_by_the_cores_and_the_memory(monkeypatch):
    """--workers takes at most 8 worker processes per core and one per 256 MB of available memory,
    refused with one line naming the limit and why."""
    from types import SimpleNamespace

    import psutil

    from lightcuts.distributed import options
    from lightcuts.errors import LightcutsError

    def machine(cores, gigabytes):
        monkeypatch.setattr(options, "cores", lambda: cores)
        monkeypatch.setattr(psutil, "virtual_memory", lambda: SimpleNamespace(available=gigabytes * 2**30))

    machine(2, 24)
    assert options.max_local_workers() == (16, "8 per core on 2 cores")
    assert options.cluster_spec(SimpleNamespace(workers="16")).workers == 16
    with pytest.raises(LightcutsError, match=r"^--workers 17: this machine starts at most 16 worker processes "
                                             r"\(8 per core on 2 cores\); for more, start a cluster"):
        options.cluster_spec(SimpleNamespace(workers="17"))
    machine(64, 1.5)
    assert options.max_local_workers() == (6, "256 MB each in the 1.5 GB of memory available")
    with pytest.raises(LightcutsError, match=r"^--workers 7: this machine starts at most 6 worker processes"):
        options.cluster_spec(SimpleNamespace(workers="7"))
    machine(1, 0.1)
    assert options.max_local_workers()[0] == 1  # one worker always
    machine(256, 1024)
    assert options.max_local_workers()[0] == options.MAX_WORKERS
