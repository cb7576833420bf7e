"""glTF files read and checked before trimesh sees them (lightcuts.scene.gltf): materials read at
full precision and refused as strictly as MTL ones, the container and every object the render
uses checked with one line naming the file and the JSON path, the triangle order independent of
trimesh's random frame names, and fuzzing: any file either loads with finite values or is one
LightcutsError naming it."""

from __future__ import annotations

import base64
import json
import math
import random

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_EMITTED_POWER, MAX_RADIANCE
from lightcuts.scene.gltf import make_glb
from lightcuts.scene.loaders import load_mesh
from lightcuts.scene.materials import pbr_to_phong
from lightcuts.scene.textures import image_to_linear
from scene_files import (broken_png, checkerboard, image_bytes, png_bytes, png_claiming, quad_gltf, textured_material,
                         write_gltf)

KEY = "scene.meshes.2"


def _refused(path, *words) -> str:
    """The one-line LightcutsError ``load_mesh(path)`` raises, checked to start with the key and
    the file, to contain ``words`` and to name no exception class."""
    with pytest.raises(LightcutsError) as e:
        load_mesh(path, key=KEY)
    msg = str(e.value)
    assert msg.startswith(f"{KEY}: {path}: ") and "\n" not in msg, msg
    assert not any(name in msg for name in ("Error:", "Error)", "Exception")), msg
    for w in words:
        assert w in msg, msg
    return msg


def _textured(tmp_path, images: list, textures: list | None = None, material: dict | None = None, ext="glb"):
    doc, blob = quad_gltf(material or textured_material())
    doc["images"], doc["textures"] = images, textures if textures is not None else [{"source": 0}]
    return write_gltf(tmp_path / f"m.{ext}", doc, blob)


def test_material_values_are_read_at_full_precision_with_emissive_strength(tmp_path):
    """baseColorFactor is not rounded to 8 bits (trimesh's own reader does); emission is
    emissiveFactor x KHR_materials_emissive_strength."""
    mat = {"pbrMetallicRoughness": {"baseColorFactor": [0.123456, 0.5, 0.9, 1.0], "metallicFactor": 0.25,
                                    "roughnessFactor": 0.5},
           "emissiveFactor": [1.0, 0.5, 0.25],
           "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 8}}}
    for ext in ("glb", "gltf"):
        doc, blob = quad_gltf(mat)
        s = load_mesh(write_gltf(tmp_path / f"m.{ext}", doc, blob))
        rd, rs, n = pbr_to_phong([0.123456, 0.5, 0.9], 0.25, 0.5)
        np.testing.assert_array_equal(s.albedo, [rd, rd])
        np.testing.assert_array_equal(s.specular, [rs, rs])
        assert np.all(s.exponent == n)
        np.testing.assert_array_equal(s.emission, [[8.0, 4.0, 2.0]] * 2)


def test_an_image_in_a_buffer_view_a_data_uri_or_a_file_is_the_same_texture(tmp_path):
    png = png_bytes(checkerboard())
    (tmp_path / "c d.png").write_bytes(png)
    expected = image_to_linear(checkerboard())
    for image in ({"uri": "c%20d.png"}, {"uri": "data:image/png;base64," + base64.b64encode(png).decode()},
                  {"bufferView": 3, "mimeType": "image/png"}):
        doc, blob = quad_gltf(textured_material())
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(png)})
        doc["buffers"][0]["byteLength"] = len(blob) + len(png)
        doc["images"], doc["textures"] = [image], [{"source": 0}]
        s = load_mesh(write_gltf(tmp_path / "m.glb", doc, blob + png))
        assert s.textured and list(s.texture) == [0, 0]
        np.testing.assert_array_equal(s.textures.image(0), expected)
        np.testing.assert_allclose(s.uv[0], [[0, 0], [1, 0], [1, 1]])  # glTF's v flipped to OBJ's


# (id, images, textures, material or None for the textured default, words of the message)
MATERIAL_CASES = [
    ("image-file-missing", [{"uri": "nowhere.png"}], None, None, ["images[0]", "nowhere.png: no such file"]),
    ("image-file-is-a-folder", [{"uri": "folder"}], None, None, ["images[0]", "is a folder"]),
    ("image-corrupt", [{"uri": "broken.png"}], None, None, ["images[0]", "broken.png", "does not decode"]),
    ("image-not-an-image", [{"uri": "data:image/png;base64," + base64.b64encode(b"hello").decode()}], None, None,
     ["images[0] (data: URI): cannot read image"]),
    ("image-bomb", [{"uri": "bomb.png"}], None, None, ["images[0]", "bomb.png", "texels"]),
    ("image-no-source", [{}], None, None, ["images[0]: neither uri nor bufferView"]),
    ("image-remote", [{"uri": "https://example.com/a.png"}], None, None, ["images[0].uri", "not a relative path"]),
    ("image-bad-base64", [{"uri": "data:image/png;base64,@@@"}], None, None, ["images[0].uri", "base64"]),
    ("texture-source-out-of-range", [{"uri": "c.png"}], [{"source": 3}], None,
     ["textures[0].source: 3 is not an index of images"]),
    ("texture-without-source", [{"uri": "c.png"}], [{}], None, ["textures[0]: no source"]),
    ("texture-sampler-out-of-range", [{"uri": "c.png"}], [{"source": 0, "sampler": 0}], None,
     ["textures[0].sampler: 0 is not an index of samplers (there are none)"]),
    ("texture-index-out-of-range", [{"uri": "c.png"}], None,
     {"pbrMetallicRoughness": {"baseColorTexture": {"index": 1}}}, ["baseColorTexture.index: 1"]),
    ("texcoord-1", [{"uri": "c.png"}], None,
     {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 1}}}, ["only TEXCOORD_0"]),
    ("normal-texture-out-of-range", [{"uri": "c.png"}], None, {"normalTexture": {"index": 5}},
     ["normalTexture.index: 5"]),
    ("base-colour-nan", [], [], {"pbrMetallicRoughness": {"baseColorFactor": [math.nan, 1, 1, 1]}},
     ["materials[0]: pbrMetallicRoughness.baseColorFactor", "NaN"]),
    ("base-colour-three-values", [], [], {"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1]}},
     ["baseColorFactor: expected 4"]),
    ("metallic-nan", [], [], {"pbrMetallicRoughness": {"metallicFactor": math.nan}}, ["metallicFactor"]),
    ("metallic-text", [], [], {"pbrMetallicRoughness": {"metallicFactor": "0.5"}}, ["metallicFactor"]),
    ("roughness-above-1", [], [], {"name": "rough", "pbrMetallicRoughness": {"roughnessFactor": 1.5}},
     ["materials[0] 'rough': pbrMetallicRoughness.roughnessFactor"]),
    ("emissive-1e300", [], [], {"emissiveFactor": [1e300, 1, 1]},
     ["emissiveFactor", "KHR_materials_emissive_strength"]),
    ("emissive-nan", [], [], {"emissiveFactor": [math.nan, 1, 1]}, ["emissiveFactor"]),
    ("emissive-strength-negative", [], [],
     {"emissiveFactor": [1, 1, 1], "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": -1}}},
     ["emissiveStrength"]),
    ("emissive-strength-beyond-the-radiance-limit", [], [],
     {"emissiveFactor": [1, 1, 1], "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 1e31}}},
     ["emissiveStrength"]),
]


@pytest.mark.parametrize("images, textures, material, words", [c[1:] for c in MATERIAL_CASES],
                         ids=[c[0] for c in MATERIAL_CASES])
def test_a_bad_material_is_one_line_naming_the_file_and_key(tmp_path, images, textures, material, words):
    (tmp_path / "folder").mkdir()
    (tmp_path / "broken.png").write_bytes(broken_png())
    (tmp_path / "bomb.png").write_bytes(png_claiming(16000, 16000))
    (tmp_path / "c.png").write_bytes(png_bytes(checkerboard()))
    for ext in ("glb", "gltf"):
        _refused(_textured(tmp_path, images, textures, material, ext), *words)


def test_an_emissive_texture_scales_each_triangles_emission_by_its_mean(tmp_path):
    """emissiveTexture, averaged per triangle, times emissiveFactor x emissiveStrength; with no
    base colour texture the quad is not textured."""
    grey = np.full((4, 4, 3), 128, np.uint8)
    (tmp_path / "g.png").write_bytes(png_bytes(grey))
    mat = {"emissiveFactor": [1.0, 0.5, 0.25], "emissiveTexture": {"index": 0},
           "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2.0}}}
    s = load_mesh(_textured(tmp_path, [{"uri": "g.png"}], material=mat))
    assert not s.textured
    np.testing.assert_allclose(s.emission, [np.array([2.0, 1.0, 0.5]) * image_to_linear(grey)[0, 0]] * 2, rtol=1e-6)


def _corrupt_json_chunk(raw: bytes) -> bytes:
    return raw[:30] + b"\xff" * 8 + raw[38:]


def _edit(change):
    def make(tmp_path):
        doc, blob = quad_gltf()
        change(doc)
        return write_gltf(tmp_path / "m.glb", doc, blob)
    return make


def _raw(data_of):
    def make(tmp_path):
        doc, blob = quad_gltf()
        p = tmp_path / "m.glb"
        p.write_bytes(data_of(make_glb(doc, blob)))
        return p
    return make


def _short_buffer(tmp_path):
    doc, blob = quad_gltf()
    return write_gltf(tmp_path / "m.gltf", doc, blob[:50])


def _missing_buffer_file(tmp_path):
    doc, blob = quad_gltf()
    doc["buffers"][0]["uri"] = "nowhere.bin"
    p = tmp_path / "m.gltf"
    p.write_text(json.dumps(doc))
    return p


# (id, maker of the file, words of the message)
STRUCTURE_CASES = [
    ("glb-not-glb", _raw(lambda raw: b"glTF but not really"), ["cannot read mesh: not a valid glTF binary"]),
    ("glb-wrong-magic", _raw(lambda raw: b"GLTF" + raw[4:]), ["cannot read mesh: not a valid glTF binary"]),
    ("glb-truncated", _raw(lambda raw: raw[:len(raw) // 2]), ["cannot read mesh: not a valid glTF binary (truncated"]),
    ("glb-json-not-utf8", _raw(_corrupt_json_chunk), ["cannot read mesh: its JSON is not UTF-8"]),
    ("glb-json-broken", _raw(lambda raw: raw[:20] + b"[" + raw[21:]), ["cannot read mesh: its JSON does not parse"]),
    ("glb-version-1", _raw(lambda raw: raw[:4] + b"\x01\0\0\0" + raw[8:]), ["GLB version 1"]),
    ("asset-version-1", _edit(lambda d: d["asset"].update(version="1.0")), ["asset.version"]),
    ("extension-required", _edit(lambda d: d.update(extensionsRequired=["KHR_draco_mesh_compression"])),
     ["extensionsRequired[0]", "KHR_draco_mesh_compression"]),
    ("buffer-short", _short_buffer, ["buffers[0]: byteLength 92, but its data has 50 bytes"]),
    ("buffer-file-missing", _missing_buffer_file, ["buffers[0]", "nowhere.bin: no such file"]),
    ("view-past-buffer", _edit(lambda d: d["bufferViews"][2].update(byteLength=200)), ["bufferViews[2]", "run past"]),
    ("accessor-past-view", _edit(lambda d: d["accessors"][2].update(count=9)), ["accessors[2]: 9 elements"]),
    ("accessor-wrong-type", _edit(lambda d: d["accessors"][0].update(type="VEC2")), ["accessors[0].type"]),
    ("accessor-index-out-of-range", _edit(lambda d: d["meshes"][0]["primitives"][0].update(indices=7)),
     ["primitives[0].indices: 7 is not an index of accessors"]),
    ("accessor-sparse", _edit(lambda d: d["accessors"][0].update(sparse={})), ["accessors[0]: sparse"]),
    ("indices-not-triangles", _edit(lambda d: d["accessors"][2].update(count=5)), ["5 corners"]),
    ("texcoord-count", _edit(lambda d: d["accessors"][1].update(count=3)), ["TEXCOORD_0: 3 coordinates for 4"]),
    ("material-out-of-range", _edit(lambda d: d["meshes"][0]["primitives"][0].update(material=4)),
     ["material: 4 is not an index of materials"]),
    ("mesh-out-of-range", _edit(lambda d: d["nodes"][0].update(mesh=1)), ["nodes[0].mesh"]),
    ("node-matrix-nan", _edit(lambda d: d["nodes"][0].update(matrix=[math.nan] * 16)), ["nodes[0].matrix"]),
    ("node-cycle", _edit(lambda d: d["nodes"].extend([{"children": [2]}, {"children": [1]}])), ["cycle"]),
    ("node-two-parents", _edit(lambda d: d["nodes"].extend([{"children": [0]}, {"children": [0]}])),
     ["node 0 is a child of node 1 already"]),
    ("scene-root-is-a-child", _edit(lambda d: d["nodes"].append({"children": [0]})),
     ["scenes[0].nodes: node 0 is a child of node 1"]),
    ("no-scenes", _edit(lambda d: [d.pop("scenes"), d.pop("scene")]), ["scenes: none"]),
    ("not-an-object", _edit(lambda d: d["meshes"].__setitem__(0, [1, 2])), ["meshes[0]: expected a JSON object"]),
]


@pytest.mark.parametrize("make, words", [c[1:] for c in STRUCTURE_CASES], ids=[c[0] for c in STRUCTURE_CASES])
def test_a_malformed_file_is_one_line_naming_the_file_and_key(tmp_path, make, words):
    _refused(make(tmp_path), *words)


def test_the_triangle_order_does_not_depend_on_trimeshs_random_names(tmp_path):
    """A node whose mesh has several primitives: trimesh names their frames at random, and the
    loader orders instances by name; each primitive gets a node named after it instead, so the
    triangles come in primitive order whatever the random state."""
    doc, blob = quad_gltf()
    prim = doc["meshes"][0]["primitives"][0]
    doc["meshes"][0]["primitives"] = [dict(prim, material=k) for k in range(4)]
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [k / 4, 0, 0, 1], "metallicFactor": 0.0}}
                        for k in range(4)]
    path = write_gltf(tmp_path / "m.glb", doc, blob)
    for seed in range(6):
        random.seed(seed)
        s = load_mesh(path)
        np.testing.assert_allclose(s.albedo[::2, 0], np.arange(4) / 4 * 0.96)


# Fuzzing: random materials, texture coordinates, image headers and damaged files.

_FUZZ = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                        HealthCheck.too_slow])
_NUMBER = (st.floats(allow_nan=True, allow_infinity=True) | st.floats(-2, 2) | st.integers(-3, 3)
           | st.sampled_from([0.0, 1.0, 1e300, -1e300, 1e-300]))
_JSON = st.recursive(st.none() | st.booleans() | _NUMBER | st.text(max_size=4),
                     lambda kids: st.lists(kids, max_size=5) | st.dictionaries(st.text(max_size=4), kids, max_size=3),
                     max_leaves=8)


def _assert_loads_or_names_the_file(path):
    try:
        s = load_mesh(path, key=KEY)
    except LightcutsError as exc:
        msg = str(exc)
        assert msg.startswith(f"{KEY}: {path}: ") and "\n" not in msg, msg
        return None
    for a in (s.vertices, s.albedo, s.specular, s.exponent, s.emission):
        assert np.all(np.isfinite(a))
    assert np.all(s.emission <= MAX_RADIANCE)
    assert float((s.emission.max(axis=1) * s.face_areas).sum()) <= MAX_EMITTED_POWER
    if s.textured:
        assert np.all(np.isfinite(s.uv)) and np.all(np.isfinite(s.textures.texels))
        assert np.all(np.isfinite(s.texture_data()[1]))
    return s


_UNIT = st.floats(0, 1)
#: Each material field valid, or (for the one field drawn to be wild) any JSON value.
_FIELDS = {
    "baseColorFactor": st.lists(_UNIT, min_size=4, max_size=4), "metallicFactor": _UNIT, "roughnessFactor": _UNIT,
    "emissiveFactor": st.lists(_UNIT, min_size=3, max_size=3), "emissiveStrength": st.floats(0, 1e6),
    "baseColorTexture": st.just({"index": 0}),
}


@_FUZZ
@given(values=st.fixed_dictionaries(_FIELDS), wild=st.none() | st.sampled_from(list(_FIELDS)),
       wild_value=_JSON | st.lists(_NUMBER, min_size=3, max_size=4) | _NUMBER, image=image_bytes(),
       uv=st.lists(st.lists(st.floats(width=32, allow_nan=False, allow_infinity=False) | st.floats(-3, 3),
                            min_size=2, max_size=2), min_size=4, max_size=4),
       ext=st.sampled_from(["glb", "gltf"]))
def test_fuzz_gltf_materials_uvs_and_images(tmp_path, values, wild, wild_value, image, uv, ext):
    """A textured quad with material factors in range but for at most one, any finite (float32)
    texture coordinates, and an image that is real, damaged or only a header."""
    if wild is not None:
        values[wild] = wild_value
    pbr = {k: values[k] for k in ("baseColorFactor", "metallicFactor", "roughnessFactor", "baseColorTexture")}
    mat = {"pbrMetallicRoughness": pbr, "emissiveFactor": values["emissiveFactor"],
           "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": values["emissiveStrength"]}}}
    doc, blob = quad_gltf(mat, np.array(uv, np.float32))
    doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(image).decode()}]
    doc["textures"] = [{"source": 0}]
    _assert_loads_or_names_the_file(write_gltf(tmp_path / f"f.{ext}", doc, blob))


def _paths(node, prefix=()):
    """Every (container, key) of a JSON document, depth first."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else []
    for k, v in items:
        yield node, k
        yield from _paths(v, prefix + (k,))


@_FUZZ
@given(edits=st.lists(st.tuples(st.integers(0, 10**6), st.none() | _JSON), max_size=2),
       damage=st.sampled_from(["none", "cut", "flip"]), at=st.integers(0, 10**6), bits=st.integers(1, 255),
       ext=st.sampled_from(["glb", "gltf"]))
def test_fuzz_gltf_documents_and_bytes(tmp_path, edits, damage, at, bits, ext):
    """Random values put in (or keys taken out of) a valid document, then the file cut short or
    one of its bytes flipped."""
    doc, blob = quad_gltf(textured_material())
    doc["images"], doc["textures"] = [{"uri": "c.png"}], [{"source": 0}]
    (tmp_path / "c.png").write_bytes(png_bytes(checkerboard()))
    for where, value in edits:
        places = list(_paths(doc))
        node, key = places[where % len(places)]
        if value is None and isinstance(node, dict):
            del node[key]
        else:
            node[key] = value
    path = tmp_path / f"f.{ext}"
    try:
        write_gltf(path, doc, blob)
    except (KeyError, IndexError, TypeError, AttributeError):  # the edit took out what the writer needs
        path.write_bytes(make_glb(doc, blob) if ext == "glb" else json.dumps(doc).encode())
    raw = bytearray(path.read_bytes())
    if damage == "cut":
        raw = raw[:at % len(raw)]
    elif damage == "flip":
        raw[at % len(raw)] ^= bits
    path.write_bytes(bytes(raw))
    _assert_loads_or_names_the_file(path)
