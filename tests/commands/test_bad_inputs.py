"""Bad and extreme inputs: one line ``error: ...``, exit 2 before any work, old outputs untouched.

Each case runs ``lightcuts.cli.main`` in this process with the stage functions recorded (as
:func:`conftest.cli_recording_work` does in a subprocess), in a folder that already holds an older
run's output set. The signal tests run a real process; the fuzz tests feed the config loader and
the light-file reader random trees, bytes and arrays.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lightcuts import limits
from lightcuts.errors import LightcutsError
from scene_files import (broken_png, checkerboard, png_bytes, png_claiming, quad_gltf, quad_obj, textured_material,
                         write_gltf)

ROOT = Path(__file__).parents[2]
BASE = {"name": "old", "scene": {"builtin": "cornell"}, "camera": {"resolution": [16, 16]},
        "lights": {"direct": {"count": 16}}}
OLD_SET = {"image.exr": b"old exr", "image.png": b"old png", "cutsize.png": b"old heat",
           "report.json": b"{}\n"}
OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def _write(folder: Path, name: str, data) -> str:
    p = folder / name
    if isinstance(data, bytes):
        p.write_bytes(data)
    elif isinstance(data, dict):
        p.write_text(yaml.safe_dump(data))
    else:
        p.write_text(data)
    return name


def _config(**changes) -> dict:
    """BASE with dotted keys replaced (a value of ... removes the key)."""
    import copy

    cfg = copy.deepcopy(BASE)
    for key, value in changes.items():
        *parents, last = key.split("__")
        node = cfg
        for p in parents:
            node = node.setdefault(p, {})
        if value is ...:
            node.pop(last, None)
        else:
            node[last] = value
    return cfg


def _npz(folder: Path, name: str, **over) -> str:
    rng = np.random.default_rng(0)
    nrm = rng.normal(size=(8, 3))
    arrays = dict(position=rng.random((8, 3)), normal=nrm / np.linalg.norm(nrm, axis=1, keepdims=True),
                  intensity=rng.random((8, 3)), type=np.array("oriented"), indirect=np.zeros(8, bool))
    for k, v in over.items():
        if v is None:
            arrays.pop(k)
        else:
            arrays[k] = v
    with open(folder / name, "wb") as f:
        np.savez(f, **arrays)
    return name


def _setup_files(folder: Path) -> None:
    _write(folder, "run.yaml", BASE)
    _write(folder, "a_file", "not a folder")
    (folder / "mine").mkdir()
    _write(folder / "mine", "notes.txt", "the user's own file")
    _write(folder, "nan.obj", "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    _write(folder, "garbage.exr", b"not an exr")
    _setup_scene_files(folder)


def _setup_scene_files(folder: Path) -> None:
    """Meshes whose materials, textures or texture coordinates are bad (the ``scene-*`` cases)."""
    _write(folder, "tex.png", png_bytes(checkerboard()))
    _write(folder, "bomb.png", png_claiming(16000, 16000))
    _write(folder, "broken.png", broken_png())
    for name, mtl in (("bomb", "map_Kd bomb.png"), ("folder_tex", "map_Kd mine"), ("null_tex", "map_Kd /dev/null"),
                      ("ke_huge", "Ke 1e300 1 1"), ("plain", "Kd 1 1 1")):
        quad_obj(folder, f"newmtl m\n{mtl}\n", name=name)
    quad_obj(folder, "newmtl m\nmap_Kd tex.png\n", name="uv_overflow", uv=["1e308 0", "-1e308 0", "0 1", "0 1"])
    for name, images, textures, material in (
            ("missing_image", [{"uri": "nowhere.png"}], [{"source": 0}], textured_material()),
            ("broken_image", [{"uri": "broken.png"}], [{"source": 0}], textured_material()),
            ("bomb_image", [{"uri": "bomb.png"}], [{"source": 0}], textured_material()),
            ("source_out_of_range", [{"uri": "tex.png"}], [{"source": 1}], textured_material()),
            ("base_nan", [], [], {"pbrMetallicRoughness": {"baseColorFactor": [float("nan"), 1, 1, 1]}}),
            ("metallic_nan", [], [], {"pbrMetallicRoughness": {"metallicFactor": float("nan")}}),
            ("emissive_1e300", [], [], {"emissiveFactor": [1e300, 1, 1]}),
            ("emissive_nan", [], [], {"emissiveFactor": [float("nan"), 1, 1]})):
        doc, blob = quad_gltf(material)
        doc["images"], doc["textures"] = images, textures
        write_gltf(folder / f"{name}.glb", doc, blob)
    doc, blob = quad_gltf()
    write_gltf(folder / "short_buffer.gltf", doc, blob[:50])
    raw = (folder / "base_nan.glb").read_bytes()
    _write(folder, "not_utf8.glb", raw[:30] + b"\xff" * 8 + raw[38:])


# (id, argv after the command's config, config changes or raw config bytes/text, light-file maker)
CASES = [
    # the config file itself
    ("config-binary", ["render", "bad.yaml"], b"\x00\x01\x02\xff\xfe binary", None),
    ("config-bad-utf8", ["render", "bad.yaml"], b"name: caf\xe9\nscene: {builtin: cornell}\n", None),
    ("config-bad-yaml", ["render", "bad.yaml"], "scene: [unclosed\n", None),
    ("config-not-mapping", ["render", "bad.yaml"], "- just\n- a list\n", None),
    ("config-missing", ["render", "nowhere.yaml"], None, None),
    ("config-unknown-key", ["render", "bad.yaml"], _config(render__epss=0.1), None),
    ("config-wrong-type", ["render", "bad.yaml"], _config(render__spp="many"), None),
    ("config-clamp-key-of-other-mode", ["render", "bad.yaml"],
     _config(render__clamp={"mode": "density", "min_distance": 0.05}), None),
    ("config-clamp-both-modes-keys", ["render", "bad.yaml"],
     _config(render__clamp={"min_distance": 0.05, "vpls": 100}), None),
    ("config-clamp-negative-vpls", ["render", "bad.yaml"], _config(render__clamp={"vpls": -1}), None),
    ("config-no-scene", ["render", "bad.yaml"], _config(scene={}), None),
    ("config-missing-mesh", ["render", "bad.yaml"], _config(scene={"meshes": [{"file": "missing.obj"}]}), None),
    ("config-env-both", ["render", "bad.yaml"],
     _config(lights__environment={"file": "garbage.exr", "procedural": {}}), None),
    ("config-env-missing-file", ["render", "bad.yaml"], _config(lights__environment={"file": "none.exr"}), None),
    ("config-negative-albedo", ["render", "bad.yaml"],
     _config(scene__materials={"floor": {"albedo": [-1, 0, 0]}}), None),
    ("config-huge-emission", ["render", "bad.yaml"],
     _config(scene__materials={"floor": {"emission": [1e308, 0, 0]}}), None),
    ("config-huge-translate", ["render", "bad.yaml"],
     _config(scene__meshes=[{"file": "nan.obj", "translate": [1e308, 0, 0]}]), None),
    ("config-fov-180", ["render", "bad.yaml"], _config(camera__fov=180), None),
    ("config-negative-count", ["render", "bad.yaml"], _config(lights__direct__count=-1), None),
    ("config-max-cut-0", ["render", "bad.yaml"], _config(render__max_cut=0), None),
    # stochastic lightcuts and triangle lights
    ("stochastic-max-cut-0", ["render", "bad.yaml"],
     _config(render__integrator={"type": "stochastic-lightcuts", "max_cut": 0}), None),
    ("direct-source-unknown", ["render", "bad.yaml"], _config(lights__direct__source="points"), None),
    ("direct-triangles-lightcuts", ["render", "bad.yaml"], _config(lights__direct__source="triangles"), None),
    ("direct-triangles-reference", ["render", "bad.yaml", "--reference"],
     _config(lights__direct__source="triangles", render__integrator="stochastic-lightcuts"), None),
    ("direct-triangles-compare-pixels", ["compare", "bad.yaml"],
     _config(lights__direct__source="triangles", render__integrator="stochastic-lightcuts"), None),
    # procedural scenes
    ("procedural-unknown-key", ["render", "bad.yaml"],
     _config(scene={"procedural": {"type": "kitchen", "triangels": 20000}}), None),
    ("procedural-unknown-type", ["render", "bad.yaml"], _config(scene={"procedural": {"type": "castle"}}), None),
    ("procedural-no-type", ["render", "bad.yaml"], _config(scene={"procedural": {"triangles": 20000}}), None),
    ("procedural-few-triangles", ["render", "bad.yaml"],
     _config(scene={"procedural": {"type": "kitchen", "triangles": 5}}), None),
    ("procedural-rooms-0", ["render", "bad.yaml"], _config(scene={"procedural": {"type": "rooms", "rooms": 0}}), None),
    ("procedural-rooms-float", ["render", "bad.yaml"],
     _config(scene={"procedural": {"type": "rooms", "rooms": 2.5}}), None),
    ("procedural-param-not-read", ["render", "bad.yaml"],
     _config(scene={"procedural": {"type": "kitchen", "rooms": 4}}), None),
    ("procedural-gallery-no-meshes", ["render", "bad.yaml"], _config(scene={"procedural": {"type": "gallery"}}), None),
    ("procedural-and-builtin", ["render", "bad.yaml"],
     _config(scene={"builtin": "cornell", "procedural": {"type": "kitchen"}}), None),
    ("procedural-city-negative-emitters", ["render", "bad.yaml"],
     _config(scene={"procedural": {"type": "city", "emitters": -1000}}), None),
    ("procedural-office-too-many-emitters", ["render", "bad.yaml"],
     _config(scene={"procedural": {"type": "office", "emitters": 4_000_001}}), None),
    ("procedural-city-emitters-float", ["render", "bad.yaml"],
     _config(scene={"procedural": {"type": "city", "emitters": 1e4}}), None),
    # --set
    ("set-not-yaml", ["render", "run.yaml", "--set", "name=[oops"], None, None),
    ("set-no-equals", ["render", "run.yaml", "--set", "render.eps"], None, None),
    ("set-not-section", ["render", "run.yaml", "--set", "name.x=1"], None, None),
    # seed, image size, crop, eps, exposure, sun
    ("seed-2**64", ["render", "bad.yaml"], _config(seed=2**64), None),
    ("seed-negative", ["render", "bad.yaml"], _config(seed=-1), None),
    ("tree-seed-2**64", ["tree", "run.yaml", "--seed", str(2**64), "--out", "t.npz"], None, None),
    ("resolution-100000", ["render", "bad.yaml"], _config(camera__resolution=[100000, 100000]), None),
    ("envmap-resolution-huge", ["render", "bad.yaml"],
     _config(lights__environment={"procedural": {"resolution": [100000, 100000]}}), None),
    ("crop-outside", ["render", "bad.yaml"], _config(render__crop=[0, 0, 1000, 1000]), None),
    ("crop-empty", ["render", "bad.yaml"], _config(render__crop=[4, 4, 4, 8]), None),
    ("crop-outside-builtin-size", ["render", "bad.yaml"],
     _config(camera__resolution=..., render__crop=[0, 0, 513, 10]), None),
    ("eps-5", ["render", "bad.yaml"], _config(render__eps=5), None),
    ("eps-0", ["render", "bad.yaml"], _config(render__eps=0), None),
    ("exposure-1024", ["render", "bad.yaml"], _config(render__tonemap={"type": "aces", "exposure": 1024}), None),
    ("exposure-moved", ["render", "bad.yaml"], _config(render__exposure=1), None),
    ("tonemap-unknown", ["render", "bad.yaml"], _config(render__tonemap="filmic"), None),
    ("tonemap-not-section", ["render", "run.yaml", "--set", "render.tonemap=aces", "--set",
                             "render.tonemap.exposure=1"], None, None),
    ("sun-zero", ["render", "bad.yaml"], _config(lights__sun={"direction": [0, 1, 0], "irradiance": [0, 0, 0]}),
     None),
    # names and output places
    ("name-escapes", ["render", "bad.yaml"], _config(name="../../../../elsewhere/x"), None),
    ("name-absolute", ["render", "bad.yaml"], _config(name="/tmp/lightcuts-absolute"), None),
    ("name-empty", ["render", "bad.yaml"], _config(name=""), None),
    ("name-dotdot", ["render", "bad.yaml"], _config(name=".."), None),
    ("name-dot", ["render", "bad.yaml"], _config(name="."), None),
    ("out-under-file", ["render", "run.yaml", "--out", "a_file/x"], None, None),
    ("out-is-file", ["render", "run.yaml", "--out", "a_file"], None, None),
    ("out-user-folder", ["render", "run.yaml", "--out", "mine"], None, None),
    ("lights-out-under-file", ["lights", "run.yaml", "--out", "a_file/l.npz"], None, None),
    ("tree-out-is-folder", ["tree", "run.yaml", "--out", "mine"], None, None),
    ("scaling-out-under-file", ["scaling", "run.yaml", "--sizes", "100", "--out", "a_file/s"], None, None),
    ("convert-missing-exr", ["convert", "none.exr"], None, None),
    ("convert-not-exr", ["convert", "run.yaml", "--out", "x.png"], None, None),
    ("convert-out-not-png", ["convert", "run.yaml", "--out", "x.jpg"], None, None),
    ("convert-out-is-folder", ["convert", "run.yaml", "--out", "mine"], None, None),
    ("convert-exposure-huge", ["convert", "run.yaml", "--exposure", "1e4"], None, None),
    # builders and parameters
    ("tree-c-1e308", ["tree", "run.yaml", "--c", "1e308", "--out", "t.npz"], None, None),
    ("config-c-1e308", ["render", "bad.yaml"], _config(tree={"c": 1e308}), None),
    ("greedy-100000", ["tree", "bad.yaml", "--builder", "greedy", "--out", "t.npz"],
     _config(lights__indirect__count=100000), None),
    ("unknown-builder", ["render", "bad.yaml"], _config(tree={"builder": "nope"}), None),
    ("unknown-metric", ["render", "bad.yaml"], _config(tree={"metric": "nope"}), None),
    ("unread-metric", ["tree", "run.yaml", "--builder", "divisive-3d", "--metric", "walter2008",
                       "--out", "t.npz"], None, None),
    ("unknown-ray-caster", ["render", "bad.yaml"], _config(render__ray_caster="nope"), None),
    ("tree-no-input", ["tree", "--out", "t.npz"], None, None),
    ("scaling-bad-sizes", ["scaling", "run.yaml", "--sizes", "ten"], None, None),
    ("scaling-repeats-0", ["scaling", "run.yaml", "--sizes", "100", "--repeats", "0"], None, None),
    ("scaling-render-path", ["scaling", "run.yaml", "--sizes", "100", "--render", "--set",
                             "render.integrator=path"], None, None),
    # light files
    ("lights-object-array", None, None, dict(position=np.array([[1, 2, 3]] * 8, object))),
    ("lights-npy-renamed", None, None, "npy"),
    ("lights-not-a-file", None, None, "text"),
    ("lights-missing-file", None, None, "missing"),
    ("lights-meta-diagonal-text", None, None, dict(meta_diagonal=np.array("wide"))),
    ("lights-meta-diagonal-array", None, None, dict(meta_scene_diagonal=np.arange(3.0))),
    ("lights-complex", None, None, dict(intensity=np.ones((8, 3), complex))),
    ("lights-string-position", None, None, dict(position=np.full((8, 3), "x"))),
    ("lights-intensity-1e308", None, None, dict(intensity=np.full((8, 3), 1e308))),
    ("lights-position-1e308", None, None, dict(position=np.full((8, 3), 1e308))),
    ("lights-position-nan", None, None, dict(position=np.full((8, 3), np.nan))),
    ("lights-negative-intensity", None, None, dict(intensity=-np.ones((8, 3)))),
    ("lights-bad-shape", None, None, dict(position=np.ones((8, 2)))),
    ("lights-bad-type", None, None, dict(type=np.array("laser"))),
    ("lights-type-bytes", None, None, dict(type=np.array(b"omni"))),
    ("lights-no-type", None, None, dict(type=None)),
    ("lights-indirect-float", None, None, dict(indirect=np.ones(3))),
    ("lights-normal-not-unit", None, None, dict(normal=np.full((8, 3), 2.0))),
    ("lights-direction-not-unit", None, None, dict(type=np.array("directional"), normal=np.zeros((8, 3)),
                                                   position=np.full((8, 3), 3.0))),
    ("lights-meta-diagonal-negative", None, None, dict(meta_diagonal=np.array(-1.0))),
    # a mesh the README promises to refuse
    ("mesh-nan-vertices", ["render", "bad.yaml"], _config(scene={"meshes": [{"file": "nan.obj"}]}), None),
    # textures, texture coordinates, glTF files and materials, emission (files of _setup_scene_files)
    *[(f"scene-{name.replace('_', '-')}", ["render", "bad.yaml"], _config(scene={"meshes": [{"file": name}]}), None)
      for name in ("bomb.obj", "folder_tex.obj", "null_tex.obj", "ke_huge.obj", "uv_overflow.obj", "missing_image.glb",
                   "broken_image.glb", "bomb_image.glb", "source_out_of_range.glb", "base_nan.glb", "metallic_nan.glb",
                   "emissive_1e300.glb", "emissive_nan.glb", "short_buffer.gltf", "not_utf8.glb")],
    ("scene-mesh-emission-power", ["render", "bad.yaml"], _config(scene={"meshes": [
        {"file": "plain.obj", "scale": 1e30, "material": {"emission": [1e30, 1e30, 1e30]}}]}),
     None),
    ("scene-emitters-power-together", ["render", "bad.yaml"], _config(scene={"emitters": [
        {"position": [0, 0, 0], "normal": [0, -1, 0], "size": [1e30, 6e29], "radiance": [1e30, 1e30, 1e30]},
        {"position": [0, 1, 0], "normal": [0, -1, 0], "size": [1e30, 6e29], "radiance": [1e30, 1e30, 1e30]}]}), None),
    # numbers that size work or memory, one past their limit (lightcuts.limits)
    ("spp-1e9", ["render", "run.yaml", "--set", "render.spp=1000000000"], None, None),
    ("spp-2**63-1", ["render", "run.yaml", "--set", f"render.spp={2**63 - 1}"], None, None),
    ("path-light-sampler-unknown", ["render", "run.yaml", "--set", "render.integrator={type: path, light_sampler: foo}"],
     None, None),
    ("gather-points-1e9", ["render", "run.yaml", "--set", "render.integrator=multidimensional",
                           "--set", "render.spp=1000000000"], None, None),
    ("eye-rays", ["render", "run.yaml", "--set", "camera.resolution=[8192,4096]", "--set", "render.spp=2049"],
     None, None),
    ("indirect-count-1e12", ["render", "run.yaml", "--set", "lights.indirect.count=1000000000000"], None, None),
    ("max-bounces-2**40", ["render", "run.yaml", "--set", f"lights.indirect.max_bounces={2**40}"], None, None),
    ("emitter-grid-1024**3", ["render", "bad.yaml"], _config(scene__emitters=[
        {"grid": {"lo": [0, 0, 0], "hi": [1, 1, 1], "count": [1024, 1024, 1024]}, "normal": [0, -1, 0],
         "size": [0.1, 0.1], "radiance": [1, 1, 1]}]), None),
    ("compare-pixels-huge", ["compare", "run.yaml", "--pixels", str(2**40)], None, None),
    ("compare-mitsuba-passes-eye-rays", ["compare", "run.yaml", "--mitsuba", "--mitsuba-passes", "4096", "--set",
                                         "camera.resolution=[4096,4096]", "--set", "render.spp=2"], None, None),
    ("scaling-sizes-1e12", ["scaling", "run.yaml", "--sizes", "1000000000000"], None, None),
    ("scaling-gather-1e9", ["scaling", "run.yaml", "--gather", "1000000000"], None, None),
    ("scaling-repeats-1e9", ["scaling", "run.yaml", "--sizes", "100", "--repeats", "1000000000"], None, None),
    ("accel-repeats-1e9", ["accel", "run.yaml", "--repeats", "1000000000"], None, None),
    ("reference-spp-2**40", ["reference", "run.yaml", "--renderer", "lightcuts", "--spp", str(2**40)], None, None),
    ("reference-max-depth-2**40", ["reference", "run.yaml", "--max-depth", str(2**40)], None, None),
    # the efficiency study's rows and options
    ("study-unknown-integrator", ["study", "run.yaml", "--row", "nope"], None, None),
    ("study-row-unknown-key", ["study", "run.yaml", "--row", "path render.epss=1"], None, None),
    ("study-row-integrator-param", ["study", "run.yaml", "--row", "path:colour=red"], None, None),
    ("study-row-unknown-option", ["study", "run.yaml", "--row", "path colour=red"], None, None),
    ("study-row-builders-without-trees", ["study", "run.yaml", "--row", "path builders=agglomerative"], None, None),
    ("study-unknown-builder", ["study", "run.yaml", "--builders", "nope"], None, None),
    ("study-row-changes-camera", ["study", "run.yaml", "--row", "path camera.resolution=[8,8]"], None, None),
    ("study-row-samples-2**40", ["study", "run.yaml", "--row", f"path samples=1,{2**40}"], None, None),
    ("study-unknown-tracer", ["study", "run.yaml", "--row", "tracer:nope"], None, None),
    ("study-unknown-renderer", ["study", "run.yaml", "--renderer", "nope"], None, None),
    ("study-reference-sun", ["study", "bad.yaml"],
     _config(lights__sun={"direction": [0, -1, 0], "irradiance": [1, 1, 1]}), None),
    ("study-reference-spp-2**40", ["study", "run.yaml", "--reference-spp", str(2**40)], None, None),
    ("study-rows-file-missing", ["study", "run.yaml", "--rows", "nowhere.yaml"], None, None),
    ("study-rows-file-not-rows", ["study", "run.yaml", "--rows", "garbage.exr"], None, None),
    ("study-times-text", ["study", "run.yaml", "--times", "ten"], None, None),
    ("study-times-0", ["study", "run.yaml", "--times", "0,10"], None, None),
    ("study-budget-0", ["study", "run.yaml", "--budget", "0"], None, None),
    ("study-epsilon-nan", ["study", "run.yaml", "--epsilon", "nan"], None, None),
    ("study-out-user-folder", ["study", "run.yaml", "--out", "mine"], None, None),
]
#: Every command, with an --out where nothing can be written: /proc and /sys refuse new entries even
#: to root, who passes every permission check.
UNWRITABLE = ["/proc/lightcuts-out", "/sys/lightcuts-out/deeper"]
OUT_COMMANDS = {"render": [], "lights": [], "tree": [], "compare": [], "scaling": ["--sizes", "100"],
                "scaling-gather": ["--gather", "1,4"], "accel": [], "reference": ["--renderer", "lightcuts"],
                "study": []}
CASES += [(f"unwritable-{where.split('/')[1]}-{name}", [name.split("-")[0], "run.yaml", *extra, "--out", where],
           None, None) for name, extra in OUT_COMMANDS.items() for where in UNWRITABLE]


def _snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None, p.stat().st_mode)
            for p in sorted(folder.rglob("*"))}


@pytest.fixture
def workdir(tmp_path, monkeypatch, stage_calls):
    """A folder with a config, an older run's outputs in renders/old and old/, and the recorder of
    the stage functions called (:func:`conftest.stage_calls`)."""
    _setup_files(tmp_path)
    for folder in (tmp_path / "renders" / "old", tmp_path / "old"):
        folder.mkdir(parents=True)
        for name, data in OLD_SET.items():
            (folder / name).write_bytes(data)
    monkeypatch.chdir(tmp_path)
    return tmp_path, stage_calls


#: Inputs found only by reading a file the scene needs: the read is the check.
SCENE_READ = {"mesh-nan-vertices", *(c[0] for c in CASES if c[0].startswith("scene-"))}


@pytest.mark.parametrize("case, argv, config, lights", CASES, ids=[c[0] for c in CASES])
def test_bad_input_one_line_exit_2_before_work(workdir, capsys, case, argv, config, lights):
    from lightcuts.cli import main

    folder, calls = workdir
    if config is not None:
        _write(folder, "bad.yaml", config)
    if lights is not None:
        if lights == "npy":
            np.save(folder / "l.npy", np.ones((8, 3)))
            os.rename(folder / "l.npy", folder / "l.npz")
        elif lights == "text":
            _write(folder, "l.npz", "position,normal\n1,2\n")
        elif lights == "missing":
            pass
        else:
            _npz(folder, "l.npz", **lights)
        argv = ["tree", "--lights", "l.npz", "--out", "t.npz"]
        # The light checks' kernel loaded (compiled on an empty cache, with numba's one-time notice on
        # stderr) before the case, whose output is then its own.
        from lightcuts.lights import LightSet
        from lightcuts.trees.checks import check_lights

        check_lights(LightSet(np.zeros((1, 3)), [[0.0, 0.0, 1.0]], np.ones((1, 3)), "oriented"))
        capsys.readouterr()
    before = _snapshot(folder)
    rc = main(argv + (["--no-progress"] if argv[0] == "render" else []))
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert rc == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
    assert calls == (["scene_from_config"] if case in SCENE_READ else []), (calls, err)
    assert _snapshot(folder) == before
    if lights is not None:  # a light file's problem is named by the file
        assert lines[0].startswith("error: l.npz: "), err
    if case.startswith("unwritable-"):
        assert lines[0].startswith(f"error: --out '{argv[-1]}': cannot write in '/"), err
    assert not Path("/tmp/lightcuts-absolute").exists()


def test_unwritable_out_refused(workdir, capsys):
    from lightcuts.cli import main

    if os.geteuid() == 0:
        pytest.skip("root writes anywhere")
    folder, calls = workdir
    (folder / "locked").mkdir(mode=0o500)
    try:
        assert main(["render", "run.yaml", "--out", "locked/x", "--no-progress"]) == 2
    finally:
        (folder / "locked").chmod(0o700)
    assert calls == [] and len(capsys.readouterr().err.strip().splitlines()) == 1


def test_probe_proves_writing_and_leaves_nothing(tmp_path, monkeypatch):
    """Each output check makes an entry where the output goes (or where its folder would be made)
    and removes it; a folder that refuses new entries (as /proc, or a read-only mount, does even to
    root) is refused, permissions notwithstanding."""
    import errno

    from lightcuts import io

    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "image.png").write_bytes(b"old")
    made = []
    mkdir, open_ = os.mkdir, os.open
    monkeypatch.setattr(os, "mkdir", lambda p, *a: (made.append(("dir", Path(p))), mkdir(p, *a))[1])
    monkeypatch.setattr(os, "open", lambda p, f, *a: (made.append(("file", Path(p))), open_(p, f, *a))[1])
    io.check_output_dir(tmp_path / "old", "--out")
    io.check_output_dir(tmp_path / "new" / "deeper", "--out")
    io.check_output_file(tmp_path / "l.npz", "--out")
    io.check_output_file(tmp_path / "sub" / "l.npz", "--out")
    io.check_store_dir(tmp_path / "old", "store")
    io.check_store_dir(tmp_path / "rows", "store")
    assert [(kind, p.parent) for kind, p in made] == [
        ("dir", tmp_path), ("dir", tmp_path), ("file", tmp_path), ("dir", tmp_path), ("file", tmp_path / "old"),
        ("dir", tmp_path)]
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["image.png", "old"]

    def refuse(p, *a):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(p))

    monkeypatch.setattr(os, "mkdir", refuse)
    monkeypatch.setattr(os, "open", refuse)
    assert os.access(tmp_path, os.W_OK)  # the permissions say yes
    for check, path in ((io.check_output_dir, tmp_path / "out"), (io.check_output_file, tmp_path / "l.npz"),
                        (io.check_store_dir, tmp_path / "old")):
        with pytest.raises(LightcutsError, match=r"^--out .*: cannot write in .*Read-only file system"):
            check(path, "--out")
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["image.png", "old"]


def test_special_file_out_refused(workdir, capsys):
    """An --out naming a FIFO (or a device, e.g. /dev/null) is not replaced by the atomic write."""
    from lightcuts.cli import main

    folder, calls = workdir
    os.mkfifo(folder / "pipe")
    before = _snapshot(folder)
    assert main(["lights", "run.yaml", "--out", "pipe"]) == 2
    assert capsys.readouterr().err.strip() == "error: --out 'pipe': exists and is not a regular file"
    assert calls == [] and _snapshot(folder) == before


#: (command and options before the bounded one, the option, its limit): the limit passes the option's
#: check (the run then stops at the later --out check), one more is refused naming option and limit.
OPTION_BOUNDS = [
    (["compare", "run.yaml"], "--pixels", limits.MAX_PIXELS),
    (["scaling", "run.yaml", "--sizes", "100"], "--repeats", limits.MAX_REPEATS),
    (["scaling", "run.yaml"], "--sizes", limits.MAX_LIGHTS),
    (["scaling", "run.yaml"], "--gather", limits.MAX_SPP),
    (["accel", "run.yaml"], "--repeats", limits.MAX_REPEATS),
    (["reference", "run.yaml", "--renderer", "lightcuts"], "--spp", limits.MAX_REFERENCE_SPP),
    (["reference", "run.yaml", "--renderer", "lightcuts", "--split"], "--passes", limits.MAX_PASSES),
    (["reference", "run.yaml"], "--max-depth", limits.MAX_BOUNCES),
    (["compare", "run.yaml", "--mitsuba"], "--mitsuba-spp", limits.MAX_REFERENCE_SPP),
    (["compare", "run.yaml", "--mitsuba"], "--mitsuba-passes", limits.MAX_PASSES),
    (["study", "run.yaml"], "--reference-spp", limits.MAX_REFERENCE_SPP),
]


@pytest.mark.parametrize("argv, option, limit", OPTION_BOUNDS, ids=[f"{a[0]}{o}" for a, o, _ in OPTION_BOUNDS])
def test_option_bounds_at_the_limit(workdir, capsys, argv, option, limit):
    from lightcuts.cli import main

    if option == "--max-depth" or "--mitsuba" in argv:
        pytest.importorskip("mitsuba")
    folder, calls = workdir
    out = ["--out", "/proc/lightcuts-out"]
    assert main(argv + [option, str(limit)] + out) == 2
    assert capsys.readouterr().err.strip().startswith("error: --out '/proc/lightcuts-out': cannot write in")
    assert main(argv + [option, str(limit + 1)] + out) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    rest = lines[0].replace(f"{limit + 1:,}", "").replace(str(limit + 1), "")  # the limit, not the value given
    assert len(lines) == 1 and option in lines[0] and (f"{limit:,}" in rest or str(limit) in rest), lines
    assert calls == []


@pytest.mark.parametrize("option", ["--sizes", "--gather"])
def test_study_points_at_the_limit(workdir, capsys, option):
    from lightcuts.cli import main

    folder, calls = workdir
    points = ",".join(str(i) for i in range(1, limits.MAX_POINTS + 2))
    assert main(["scaling", "run.yaml", option, points.rpartition(",")[0], "--out", "/proc/lightcuts-out"]) == 2
    assert "error: --out '/proc/lightcuts-out'" in capsys.readouterr().err
    assert main(["scaling", "run.yaml", option, points, "--out", "/proc/lightcuts-out"]) == 2
    assert capsys.readouterr().err.strip() == (f"error: {option}: {limits.MAX_POINTS + 1} values, more than "
                                               f"{limits.MAX_POINTS} points (lightcuts.limits.MAX_POINTS)")
    assert calls == []


def test_latin1_obj_loads(tmp_path):
    from lightcuts.scene.loaders import load_mesh

    (tmp_path / "m.obj").write_bytes(b"# caf\xe9 cr\xe8me\n" + OBJ.encode())
    assert load_mesh(tmp_path / "m.obj").n_faces == 1


def test_output_set_replaces_old_folder_whole(workdir, capsys):
    """A run replaces the older set (no file of it left) and writes with the umask's modes."""
    from lightcuts.cli import main

    folder, _ = workdir
    (folder / "old" / "reference.png").write_bytes(b"older reference")
    old_umask = os.umask(0o022)
    try:
        assert main(["render", "run.yaml", "--out", "old", "--no-progress"]) == 0
    finally:
        os.umask(old_umask)
    names = sorted(p.name for p in (folder / "old").iterdir())
    assert names == ["cutsize.png", "image.exr", "image.png", "report.html", "report.json"]
    assert all((folder / "old" / n).stat().st_mode & 0o777 == 0o644 for n in names)
    assert (folder / "old" / "image.png").read_bytes() != OLD_SET["image.png"]
    assert [p.name for p in folder.iterdir() if p.name.startswith(".")] == []


_MARKED = """
import sys, lightcuts.integrators.registry as r
fn = r.Integrator.render
def marked(*a, **k):
    print("MARK", file=sys.stderr, flush=True)
    return fn(*a, **k)
r.Integrator.render = marked
from lightcuts.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_signal_during_render(tmp_path, sig, code, word):
    """The signal stops a render at once: one line, 130 / 143, the old set untouched, no temporaries."""
    import time

    _write(tmp_path, "run.yaml", _config(camera__resolution=[256, 256], render={"spp": 16}))
    (tmp_path / "old").mkdir()
    for name, data in OLD_SET.items():
        (tmp_path / "old" / name).write_bytes(data)
    before = _snapshot(tmp_path)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen([sys.executable, "-c", _MARKED, "render", "run.yaml", "--out", "old", "--no-progress"],
                         cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    marks = 0
    for line in p.stderr:
        marks += line.strip() == "MARK"
        if marks == 2:  # the full render, after the one-pixel warm-up
            break
    time.sleep(0.2)
    t0 = time.perf_counter()
    p.send_signal(sig)
    _, err = p.communicate(timeout=60)
    assert time.perf_counter() - t0 < 2.0
    assert p.returncode == code, err
    assert err.strip().splitlines() == [f"error: {word}"]
    assert _snapshot(tmp_path) == before


# Property-based fuzzing: anything either loads or raises LightcutsError.

_KEYS = ["name", "seed", "scene", "builtin", "meshes", "file", "materials", "floor", "albedo", "emission",
         "camera", "resolution", "fov", "position", "lights", "direct", "indirect", "count", "sun", "direction",
         "irradiance", "environment", "procedural", "tree", "builder", "metric", "c", "render", "eps", "spp",
         "crop", "tonemap", "exposure", "clamp", "enabled", "max_cut", "ray_caster", "scale", "rotate", "translate",
         "type", "triangles", "rooms"]
_SCALARS = (st.none() | st.booleans() | st.integers(-2**70, 2**70) | st.floats(allow_nan=True)
            | st.text(max_size=8)
            | st.sampled_from(["cornell", "agglomerative", "walter2008", "sky", "x.obj", "kitchen", "gallery"]))
_TREES = st.recursive(_SCALARS, lambda kids: st.lists(kids, max_size=4)
                      | st.dictionaries(st.sampled_from(_KEYS) | st.text(max_size=4) | st.integers(), kids,
                                        max_size=5), max_leaves=25)
_FUZZ = settings(max_examples=150, deadline=2000, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                          HealthCheck.too_slow])


@_FUZZ
@given(data=_TREES)
def test_fuzz_config_from_dict(tmp_path, data):
    from lightcuts.config.schema import RunConfig, config_from_dict

    try:
        assert isinstance(config_from_dict(data, "fuzz.yaml", tmp_path), RunConfig)
    except LightcutsError as exc:
        assert "\n" not in str(exc)


@_FUZZ
@given(data=_TREES, raw=st.binary(max_size=200), use_raw=st.booleans(),
       overrides=st.lists(st.text(max_size=12), max_size=2))
def test_fuzz_load_config(tmp_path, data, raw, use_raw, overrides):
    from lightcuts.config.schema import RunConfig, load_config

    path = tmp_path / "fuzz.yaml"
    path.write_bytes(raw if use_raw else yaml.safe_dump(data, allow_unicode=True).encode())
    try:
        assert isinstance(load_config(path, overrides), RunConfig)
    except LightcutsError as exc:
        assert "\n" not in str(exc)


_DTYPES = st.sampled_from([np.float64, np.float32, np.int64, np.uint8, np.bool_, np.complex128, "U3", "S3",
                           object])
_LIGHT_KEYS = st.sampled_from(["position", "normal", "intensity", "type", "indirect", "meta_diagonal",
                               "meta_scene_diagonal", "meta_seed", "other"])


@st.composite
def _array(draw):
    dtype = draw(_DTYPES)
    shape = draw(st.sampled_from([(), (0,), (4,), (4, 3), (0, 3), (4, 2), (2, 3, 1)]))
    size = int(np.prod(shape)) if shape else 1
    values = draw(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=size,
                           max_size=size))
    a = np.array(values, np.float64).reshape(shape)
    if dtype == "U3" or dtype == "S3":
        return a.astype(dtype)
    if dtype == object:
        return a.astype(object)
    with np.errstate(all="ignore"):
        return a.astype(dtype) if np.dtype(dtype).kind in "fcb" else np.nan_to_num(a).clip(-1e9, 1e9).astype(dtype)


@_FUZZ
@given(arrays=st.dictionaries(_LIGHT_KEYS, _array(), max_size=7), typ=st.sampled_from(["oriented", "omni", "x"]),
       raw=st.none() | st.binary(max_size=100))
def test_fuzz_lightset_load(tmp_path, arrays, typ, raw):
    from lightcuts.lights import LightSet

    path = tmp_path / "fuzz.npz"
    if raw is not None:
        path.write_bytes(raw)
    else:
        arrays.setdefault("type", np.array(typ))
        with open(path, "wb") as f:
            np.savez(f, **arrays)
    try:
        assert isinstance(LightSet.load(path), LightSet)
    except LightcutsError as exc:
        assert "\n" not in str(exc)
