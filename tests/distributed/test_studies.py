"""compare and scaling on a Dask LocalCluster of two worker processes: the local rows and points, and
compare's row store shared with local runs, so an interrupted study resumes."""

import csv
import json
import logging
from pathlib import Path

import numpy as np
import pytest

from lightcuts.cli import main

ROOT = Path(__file__).parents[2]
pytestmark = pytest.mark.slow  # a LocalCluster of worker processes
SMALL = ["--set", "camera.resolution=[40,30]", "--set", "lights.indirect.count=1500", "--set", "lights.direct.count=128"]
#: Columns that are times (the workers' own), not results.
TIMES = {"build_s", "preprocess_s", "image_s", "summed_s", "median_s", "min_s", "render_s", "image_seconds"}


@pytest.fixture(scope="module")
def cluster():
    from distributed import Client, LocalCluster

    lc = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
    client = Client(lc, set_as_default=False)
    yield lc.scheduler_address, client
    client.close()
    lc.close()


def compare(out, builders, *flags):
    assert main(["compare", str(ROOT / "configs/cornell.yaml"), "--builders", builders, "--pixels", "100",
                 "--out", str(out), "--no-progress", *SMALL, *flags]) == 0
    return json.loads((out / "report.json").read_text())


def same_rows(a, b):
    assert [r["label"] for r in a["rows"]] == [r["label"] for r in b["rows"]]
    for ra, rb in zip(a["rows"], b["rows"]):
        assert {k: v for k, v in ra.items() if k not in TIMES} == {k: v for k, v in rb.items() if k not in TIMES}


def test_compare_rows_through_the_cluster_equal_the_local_rows(cluster, tmp_path):
    address, _ = cluster
    builders = "agglomerative,divisive-6d,saoh"
    local = compare(tmp_path / "local", builders)
    remote = compare(tmp_path / "cluster", builders, "--scheduler", address)
    same_rows(local, remote)
    assert remote["cluster"]["workers"] == 2 and sum(w["tasks"] for w in remote["cluster"]["per_worker"].values()) \
        == 3 + 2  # three rows, the 100-pixel reference in two chunks
    for name in ("agglomerative", "divisive-6d", "saoh", "reference"):
        a, b = np.load(tmp_path / "local/rows" / f"{name}.npz"), np.load(tmp_path / "cluster/rows" / f"{name}.npz")
        for k in a.files:
            if k not in ("row", "seconds"):
                assert a[k].tobytes() == b[k].tobytes(), (name, k)
    assert (tmp_path / "local/table.csv").read_text().count("\n") == (tmp_path / "cluster/table.csv").read_text().count("\n")


def test_an_interrupted_study_resumes_on_the_cluster(cluster, tmp_path, scratch_registries):
    """A row that fails on the workers stops the study; the finished row and the reference stay in the
    store, and the next run on the cluster computes only the missing row."""
    address, client = cluster

    def register():
        from lightcuts.errors import LightcutsError
        from lightcuts.trees.registry import BUILDERS

        def failing(*args):
            raise LightcutsError("stopped")

        if "failing" not in BUILDERS:
            BUILDERS.register("failing", failing, reads=())

    register()
    client.run(register)
    out = tmp_path / "cmp"
    args = ["compare", str(ROOT / "configs/cornell.yaml"), "--pixels", "100", "--out", str(out), "--no-progress",
            *SMALL, "--scheduler", address]
    assert main(args + ["--builders", "divisive-3d,failing"]) == 2  # "error: stopped", raised on a worker
    assert sorted(p.name for p in (out / "rows").iterdir()) == ["divisive-3d.npz", "reference.npz"]
    stored = {p.name: p.stat().st_mtime_ns for p in (out / "rows").iterdir()}
    assert main(args + ["--builders", "divisive-3d,divisive-6d"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert {p.name: p.stat().st_mtime_ns for p in (out / "rows").iterdir() if p.name in stored} == stored
    assert sum(w["tasks"] for w in report["cluster"]["per_worker"].values()) == 1  # divisive-6d only
    same_rows(compare(tmp_path / "local", "divisive-3d,divisive-6d"), report)


def test_scaling_points_through_the_cluster_equal_the_local_points(cluster, tmp_path):
    address, _ = cluster
    args = ["scaling", str(ROOT / "configs/cornell.yaml"), "--sizes", "1000,3000", "--builders",
            "agglomerative,divisive-6d", "--render", "--repeats", "1", "--no-progress", *SMALL]
    assert main(args + ["--out", str(tmp_path / "local")]) == 0
    assert main(args + ["--out", str(tmp_path / "cluster"), "--scheduler", address]) == 0
    for name in ("scaling.csv", "render_scaling.csv"):
        rows = [[{k: v for k, v in r.items() if k not in TIMES} for r in csv.DictReader(open(tmp_path / d / name))]
                for d in ("local", "cluster")]
        assert rows[0] == rows[1] and len(rows[0]) == 4, name
