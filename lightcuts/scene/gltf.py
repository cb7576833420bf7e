"""glTF 2.0 files (.gltf, .glb), read and checked here before trimesh sees them.

trimesh's glTF reader fails on a malformed file with whatever its code meets first (an
AssertionError for a buffer shorter than it says, a missing optional module for a JSON chunk that
is not UTF-8, which it hands to ``charset_normalizer`` to guess an encoding) and skips a material's
image it cannot read without a word. So the container, the JSON and every object the render uses
are read and checked here against the specification, each problem one LightcutsError naming the
file and the JSON path (``materials[2] 'lamp': pbrMetallicRoughness.metallicFactor: ...``):
scenes, nodes (one parent each, no cycles), the triangle primitives of meshes (points, lines and
fans are skipped), their accessors and buffer views (within their buffers), buffers (present, as
long as they say), materials (factors in the specification's ranges), and the textures and images
of the materials a primitive uses (present, decodable, within the texel limits).

trimesh then reads the file reduced to the geometry, as one GLB in memory (:attr:`GltfFile.glb`),
as the MTL resolver hands it material names only: node transforms, one mesh per primitive (a node
whose mesh has several gets one child node per primitive, named after it, so the triangle order
does not depend on trimesh's random frame names), and each material reduced to a name saying
which of ours it is (``MATERIAL_TAG``). The materials (lightcuts.scene.materials) are made here.
"""

from __future__ import annotations

import base64
import binascii
import json
import math
import re
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_RADIANCE
from lightcuts.scene.files import regular_file
from lightcuts.scene.materials import FileMaterial, default_material, pbr_to_phong
from lightcuts.scene.textures import TexelBudget, read_image

GLB_MAGIC, CHUNK_JSON, CHUNK_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942
COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
FLOAT, INDEX_TYPES = (5126,), (5121, 5123, 5125)
TYPE_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
TRIANGLES, TRIANGLE_STRIP = 4, 5
#: Extensions a file may list in ``extensionsRequired``: the ones read here.
SUPPORTED_EXTENSIONS = ("KHR_materials_emissive_strength",)
#: The name trimesh gets for material i: ``MATERIAL_TAG + str(i)``.
MATERIAL_TAG = "lightcuts-gltf-material-"


class _Checker:
    """Typed reads of JSON values; a wrong one is LightcutsError ``<where>: <key>: <problem>``."""

    def __init__(self, where: str):
        self.where = where

    def fail(self, key: str, problem: str):
        raise LightcutsError(f"{self.where}: {key}: {problem}")

    def object(self, value, key: str) -> dict:
        if not isinstance(value, dict):
            self.fail(key, f"expected a JSON object, got {_short(value)}")
        return value

    def array(self, value, key: str) -> list:
        if not isinstance(value, list):
            self.fail(key, f"expected a JSON array, got {_short(value)}")
        return value

    def int(self, value, key: str, lo: int = 0, hi: int | None = None) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or value < lo or (hi is not None and value > hi):
            self.fail(key, f"expected an integer in [{lo}, {'...' if hi is None else hi}], got {_short(value)}")
        return value

    def index(self, value, key: str, n: int, what: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < n:
            self.fail(key, f"{_short(value)} is not an index of {what} ({f'0 to {n - 1}' if n else 'there are none'})")
        return value

    def numbers(self, value, key: str, n: int, lo: float = -math.inf, hi: float = math.inf) -> np.ndarray:
        """n finite numbers in [lo, hi] (JSON's NaN and Infinity, which Python reads, are refused)."""
        if not (isinstance(value, list) and len(value) == n and all(_finite(x) and lo <= x <= hi for x in value)):
            self.fail(key, f"expected {n} finite numbers" + (f" in [{lo:g}, {hi:g}]" if lo > -math.inf else "")
                      + f", got {_short(value)}")
        return np.array(value, np.float64)

    def number(self, value, key: str, lo: float, hi: float) -> float:
        if not (_finite(value) and lo <= value <= hi):
            self.fail(key, f"expected a number in [{lo:g}, {hi:g}], got {_short(value)}")
        return float(value)


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _short(value) -> str:
    text = json.dumps(value) if not isinstance(value, float) else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def split_glb(raw: bytes, where: str) -> tuple[bytes, bytes | None]:
    """The JSON chunk and the BIN chunk (None if absent) of a GLB file's bytes."""
    def bad(reason: str) -> LightcutsError:
        return LightcutsError(f"{where}: cannot read mesh: not a valid glTF binary ({reason})")

    if len(raw) < 20:
        raise bad(f"{len(raw)} bytes, less than its headers")
    magic, version, length = struct.unpack_from("<III", raw, 0)
    if magic != GLB_MAGIC:
        raise bad("it does not start with 'glTF'")
    if version != 2:
        raise LightcutsError(f"{where}: cannot read mesh: GLB version {version}; only glTF 2 is read")
    if length > len(raw):
        raise bad(f"truncated: its header says {length} bytes, the file has {len(raw)}")
    chunks, pos = [], 12
    while pos + 8 <= length:
        size, kind = struct.unpack_from("<II", raw, pos)
        if pos + 8 + size > length:
            raise bad(f"the chunk at byte {pos} says {size} bytes, {length - pos - 8} are left")
        chunks.append((kind, raw[pos + 8:pos + 8 + size]))
        pos += 8 + size
    if not chunks or chunks[0][0] != CHUNK_JSON:
        raise bad("no JSON chunk first")
    return chunks[0][1], (chunks[1][1] if len(chunks) > 1 and chunks[1][0] == CHUNK_BIN else None)


def make_glb(doc: dict, binary: bytes = b"") -> bytes:
    """A GLB file of a glTF JSON document and its BIN chunk (none if empty)."""
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), CHUNK_JSON) + text
    if binary:
        binary += b"\0" * (-len(binary) % 4)
        body += struct.pack("<II", len(binary), CHUNK_BIN) + binary
    return struct.pack("<III", GLB_MAGIC, 2, 12 + len(body)) + body


def read_json(path: Path, where: str) -> tuple[dict, bytes | None]:
    """A .gltf or .glb file's JSON document (checked: an object, glTF 2, required extensions
    supported) and its GLB BIN chunk (None for .gltf or without one)."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise LightcutsError(f"{where}: cannot read file ({exc.strerror or exc})") from None
    text, binary = split_glb(raw, where) if path.suffix.lower() == ".glb" else (raw, None)
    try:
        doc = json.loads(text.decode("utf-8").removeprefix("\ufeff"))
    except UnicodeDecodeError as exc:
        raise LightcutsError(f"{where}: cannot read mesh: its JSON is not UTF-8, as glTF requires "
                             f"(byte {exc.start}: {exc.reason})") from None
    except (ValueError, RecursionError) as exc:
        raise LightcutsError(f"{where}: cannot read mesh: its JSON does not parse "
                             f"({str(exc) or type(exc).__name__})") from None
    check = _Checker(where)
    doc = check.object(doc, "the document")
    version = check.object(doc.get("asset"), "asset").get("version")
    if not isinstance(version, str) or version.split(".")[0] != "2":
        check.fail("asset.version", f"{_short(version)}; only glTF 2 is read")
    for i, name in enumerate(check.array(doc.get("extensionsRequired", []), "extensionsRequired")):
        if name not in SUPPORTED_EXTENSIONS:
            check.fail(f"extensionsRequired[{i}]",
                       f"{_short(name)} is not supported (read: {', '.join(SUPPORTED_EXTENSIONS)})")
    return doc, binary


class GltfFile:
    """One glTF file, read and checked (module docstring).

    glb : bytes, the file reduced to its geometry, for trimesh
    material_of(geometry) : the FileMaterial of a trimesh geometry loaded from ``glb``
    ``where`` prefixes every message; ``budget`` takes the texels of the images the materials read.
    With ``materials=False`` the materials are neither checked nor handed on (a config material
    replaces them).
    """

    def __init__(self, path, where: str, budget: TexelBudget | None = None, materials: bool = True):
        self.path, self.where, self.budget = Path(path), where, budget
        self.check = _Checker(where)
        doc, binary = read_json(self.path, where)
        self.doc = doc
        self.buffers = self._buffers(binary)
        arrays = {k: self.check.array(doc.get(k, []), k) for k in (
            "bufferViews", "accessors", "meshes", "nodes", "scenes", "materials", "textures", "images", "samplers")}
        self.views, self.accessors = arrays["bufferViews"], arrays["accessors"]
        self.meshes, self.nodes, self.scenes = arrays["meshes"], arrays["nodes"], arrays["scenes"]
        self.textures, self.images, self.samplers = arrays["textures"], arrays["images"], arrays["samplers"]
        self.materials = [self._material(i, m) for i, m in enumerate(arrays["materials"])] if materials else []
        self._built: dict[int, FileMaterial] = {}
        self._decoded: dict[int, np.ndarray] = {}
        self.glb = self._reduced()

    # -- data ------------------------------------------------------------------------------------

    def _uri(self, uri, key: str) -> bytes | Path:
        """The bytes of a data: URI, or the path of a relative one (percent-decoded)."""
        if not isinstance(uri, str):
            self.check.fail(key, f"expected a string, got {_short(uri)}")
        if uri.startswith("data:"):
            head, comma, payload = uri.partition(",")
            if not comma or not head.endswith(";base64"):
                self.check.fail(key, "a data: URI that is not base64")
            try:
                return base64.b64decode(payload, validate=True)
            except (binascii.Error, ValueError) as exc:
                self.check.fail(key, f"its base64 does not decode ({exc})")
        if re.match(r"[A-Za-z][A-Za-z0-9+.-]*:", uri) or uri.startswith("/"):
            self.check.fail(key, f"{_short(uri)} is not a relative path or a data: URI (nothing else is read)")
        return self.path.parent / unquote(uri)

    def _buffers(self, binary: bytes | None) -> list[bytes]:
        out = []
        for i, b in enumerate(self.check.array(self.doc.get("buffers", []), "buffers")):
            key = f"buffers[{i}]"
            b = self.check.object(b, key)
            size = self.check.int(b.get("byteLength"), f"{key}.byteLength", lo=1)
            if "uri" not in b:
                if i != 0 or binary is None:
                    self.check.fail(key, "no uri, and it is not a GLB's first buffer with a BIN chunk")
                data = binary
            else:
                data = self._uri(b["uri"], f"{key}.uri")
                if isinstance(data, Path):
                    data = regular_file(data, f"{self.where}: {key} {data}").read_bytes()
            if len(data) < size:
                self.check.fail(key, f"byteLength {size}, but its data has {len(data)} bytes")
            out.append(memoryview(data)[:size])
        return out

    def _view(self, j: int) -> tuple[memoryview, int | None]:
        """The bytes of buffer view j and its byteStride (None: tightly packed)."""
        key = f"bufferViews[{j}]"
        v = self.check.object(self.views[j], key)
        b = self.check.index(v.get("buffer"), f"{key}.buffer", len(self.buffers), "buffers")
        offset = self.check.int(v.get("byteOffset", 0), f"{key}.byteOffset")
        size = self.check.int(v.get("byteLength"), f"{key}.byteLength", lo=1)
        stride = v.get("byteStride")
        if stride is not None and self.check.int(stride, f"{key}.byteStride", 4, 252) % 4:
            self.check.fail(f"{key}.byteStride", f"{stride} is not a multiple of 4")
        if offset + size > len(self.buffers[b]):
            self.check.fail(key, f"bytes {offset} to {offset + size} run past the end of buffers[{b}] "
                                 f"({len(self.buffers[b])} bytes)")
        return self.buffers[b][offset:offset + size], stride

    def _accessor(self, i, key: str, types: tuple, components: tuple) -> tuple[dict, int]:
        """Accessor i, checked to lie within its buffer view, as trimesh needs it (without its
        bufferView), and the index of that view."""
        i = self.check.index(i, key, len(self.accessors), "accessors")
        key = f"accessors[{i}]"
        a = self.check.object(self.accessors[i], key)
        if "sparse" in a or "bufferView" not in a:
            self.check.fail(key, "sparse accessors and accessors without a bufferView are not read")
        j = self.check.index(a["bufferView"], f"{key}.bufferView", len(self.views), "bufferViews")
        data, stride = self._view(j)
        if a.get("type") not in types:
            self.check.fail(f"{key}.type", f"{_short(a.get('type'))}, expected {' or '.join(types)} here")
        if a.get("componentType") not in components or a.get("normalized", False) is not False:
            self.check.fail(f"{key}.componentType", f"{_short(a.get('componentType'))}"
                            f"{' normalized' if a.get('normalized') else ''}, expected one of {list(components)} here")
        count = self.check.int(a.get("count"), f"{key}.count", lo=1)
        offset = self.check.int(a.get("byteOffset", 0), f"{key}.byteOffset")
        element = COMPONENT_BYTES[a["componentType"]] * TYPE_WIDTH[a["type"]]
        if stride is not None and stride < element:
            self.check.fail(f"bufferViews[{j}].byteStride", f"{stride}, less than the {element} bytes of {key}")
        need = offset + (count - 1) * (stride or element) + element
        if need > len(data):
            self.check.fail(key, f"{count} elements from byte {offset} need {need} bytes of bufferViews[{j}], "
                                 f"which has {len(data)}")
        return {"componentType": a["componentType"], "count": count, "type": a["type"], "byteOffset": offset}, j

    # -- materials -------------------------------------------------------------------------------

    def _material(self, i: int, m) -> dict:
        """Material i's values, checked: ``base`` colour (4,), ``metallic``, ``roughness``, emitted
        radiance ``emission`` (3,) (``emissiveFactor`` x ``emissiveStrength``, at most
        MAX_RADIANCE as the strength is), and the image indices ``base_image``, ``emissive_image``
        of its base colour and emissive textures (None without)."""
        key = f"materials[{i}]"
        m = self.check.object(m, key)
        name = m.get("name", "")
        if not isinstance(name, str):
            self.check.fail(f"{key}.name", f"expected a string, got {_short(name)}")
        key = f"{key} {name!r}" if name else key
        pk = f"{key}: pbrMetallicRoughness"
        pbr = self.check.object(m.get("pbrMetallicRoughness", {}), pk)
        values = {
            "base": self.check.numbers(pbr.get("baseColorFactor", [1.0] * 4), f"{pk}.baseColorFactor", 4, 0.0, 1.0),
            "metallic": self.check.number(pbr.get("metallicFactor", 1.0), f"{pk}.metallicFactor", 0.0, 1.0),
            "roughness": self.check.number(pbr.get("roughnessFactor", 1.0), f"{pk}.roughnessFactor", 0.0, 1.0),
            "base_image": self._texture(pbr.get("baseColorTexture"), f"{pk}.baseColorTexture"),
            "emissive_image": self._texture(m.get("emissiveTexture"), f"{key}: emissiveTexture"),
        }
        for slot, owner, k in (("metallicRoughnessTexture", pbr, f"{pk}."), ("normalTexture", m, f"{key}: "),
                               ("occlusionTexture", m, f"{key}: ")):
            if slot in owner:  # not read, but its index must name a texture
                info = self.check.object(owner[slot], k + slot)
                self.check.index(info.get("index"), f"{k}{slot}.index", len(self.textures), "textures")
        factor = m.get("emissiveFactor", [0.0] * 3)
        if isinstance(factor, list) and any(_finite(x) and x > 1 for x in factor):
            self.check.fail(f"{key}: emissiveFactor", f"{_short(factor)}: above 1, the specification's largest "
                                                      "(brighter emission: KHR_materials_emissive_strength)")
        factor = self.check.numbers(factor, f"{key}: emissiveFactor", 3, 0.0, 1.0)
        ext = self.check.object(m.get("extensions", {}), f"{key}: extensions")
        strength = 1.0
        if "KHR_materials_emissive_strength" in ext:
            k = f"{key}: extensions.KHR_materials_emissive_strength"
            strength = self.check.number(self.check.object(ext["KHR_materials_emissive_strength"], k).get(
                "emissiveStrength", 1.0), f"{k}.emissiveStrength", 0.0, MAX_RADIANCE)
        values["emission"] = factor * strength
        return values

    def _texture(self, info, key: str) -> int | None:
        """The image index of a texture reference (None when absent), checked through ``textures``."""
        if info is None:
            return None
        info = self.check.object(info, key)
        t = self.check.index(info.get("index"), f"{key}.index", len(self.textures), "textures")
        if self.check.int(info.get("texCoord", 0), f"{key}.texCoord") != 0:
            self.check.fail(f"{key}.texCoord", f"{info['texCoord']}; only TEXCOORD_0 is read")
        tex = self.check.object(self.textures[t], f"textures[{t}]")
        if "sampler" in tex:
            self.check.index(tex["sampler"], f"textures[{t}].sampler", len(self.samplers), "samplers")
        if "source" not in tex:
            self.check.fail(f"textures[{t}]", "no source (images given by extensions are not read)")
        return self.check.index(tex["source"], f"textures[{t}].source", len(self.images), "images")

    def _image(self, j: int) -> np.ndarray:
        """Image j decoded (once), linear RGB."""
        if j not in self._decoded:
            key = f"images[{j}]"
            img = self.check.object(self.images[j], key)
            if "bufferView" in img:
                v = self.check.index(img["bufferView"], f"{key}.bufferView", len(self.views), "bufferViews")
                source, where = bytes(self._view(v)[0]), f"{self.where}: {key} (bufferViews[{v}])"
            elif "uri" in img:
                source = self._uri(img["uri"], f"{key}.uri")
                where = f"{self.where}: {key} " + (str(source) if isinstance(source, Path) else "(data: URI)")
            else:
                self.check.fail(key, "neither uri nor bufferView")
            self._decoded[j] = read_image(source, where, self.budget)
        return self._decoded[j]

    def material_of(self, geometry) -> FileMaterial:
        """The material of a geometry trimesh read from :attr:`glb` (diffuse grey without one)."""
        name = getattr(getattr(geometry.visual, "material", None), "name", None)
        if not (isinstance(name, str) and name.startswith(MATERIAL_TAG)):
            return default_material()
        i = int(name[len(MATERIAL_TAG):])
        if i not in self._built:
            m = self.materials[i]
            rd, rs, n = pbr_to_phong(m["base"][:3], m["metallic"], m["roughness"])
            out = FileMaterial(rd, rs, n, m["emission"])
            if m["base_image"] is not None:
                out = out._replace(texture=self._image(m["base_image"]),
                                   texture_name=f"{self.path} images[{m['base_image']}]")
            if m["emissive_image"] is not None:
                out = out._replace(emissive=self._image(m["emissive_image"]))
            self._built[i] = out
        return self._built[i]

    # -- the geometry trimesh reads --------------------------------------------------------------

    def _reduced(self) -> bytes:
        """The GLB trimesh reads (module docstring)."""
        accessors, views, blob = [], [], bytearray()
        taken: dict[int, int] = {}  # accessor, buffer view -> its index in the reduced file
        copied: dict[int, int] = {}

        def take(i, key, types, components) -> tuple[int, int]:
            """(index in the reduced file, count) of accessor i."""
            a, j = self._accessor(i, key, types, components)
            if j not in copied:
                data, stride = self._view(j)
                blob.extend(b"\0" * (-len(blob) % 4))
                views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data),
                              **({"byteStride": stride} if stride else {})})
                blob.extend(data)
                copied[j] = len(views) - 1
            if i not in taken:
                accessors.append({**a, "bufferView": copied[j]})
                taken[i] = len(accessors) - 1
            return taken[i], a["count"]

        meshes, per_mesh = [], []
        for mi, m in enumerate(self.meshes):
            key = f"meshes[{mi}]"
            m = self.check.object(m, key)
            name = m.get("name", "GLTF")
            if not isinstance(name, str):
                self.check.fail(f"{key}.name", f"expected a string, got {_short(name)}")
            kept = []
            for pi, p in enumerate(self.check.array(m.get("primitives"), f"{key}.primitives")):
                pk = f"{key}.primitives[{pi}]"
                p = self.check.object(p, pk)
                mode = self.check.int(p.get("mode", TRIANGLES), f"{pk}.mode", 0, 6)
                if mode not in (TRIANGLES, TRIANGLE_STRIP):
                    continue
                attrs = self.check.object(p.get("attributes"), f"{pk}.attributes")
                if "POSITION" not in attrs:
                    self.check.fail(f"{pk}.attributes", "no POSITION")
                pos, n = take(attrs["POSITION"], f"{pk}.attributes.POSITION", ("VEC3",), FLOAT)
                prim = {"attributes": {"POSITION": pos}, "mode": mode}
                if "material" in p and self.materials:
                    prim["material"] = self.check.index(p["material"], f"{pk}.material", len(self.materials),
                                                        "materials")
                    if "TEXCOORD_0" in attrs:
                        uv, n_uv = take(attrs["TEXCOORD_0"], f"{pk}.attributes.TEXCOORD_0", ("VEC2",), FLOAT)
                        if n_uv != n:
                            self.check.fail(f"{pk}.attributes.TEXCOORD_0", f"{n_uv} coordinates for {n} positions")
                        prim["attributes"]["TEXCOORD_0"] = uv
                corners = n
                if "indices" in p:
                    prim["indices"], corners = take(p["indices"], f"{pk}.indices", ("SCALAR",), INDEX_TYPES)
                if corners < 3 or (mode == TRIANGLES and corners % 3):
                    self.check.fail(pk, f"{corners} corners do not make triangles")
                kept.append(len(meshes))
                meshes.append({"name": name, "primitives": [prim]})
            per_mesh.append(kept)

        nodes, parent = [], [-1] * len(self.nodes)
        extra = []  # one child node per primitive of a node whose mesh has several
        for k, node in enumerate(self.nodes):
            key = f"nodes[{k}]"
            node = self.check.object(node, key)
            out = {}
            if "name" in node:
                if not isinstance(node["name"], str):
                    self.check.fail(f"{key}.name", f"expected a string, got {_short(node['name'])}")
                out["name"] = node["name"]
            for field, n in (("matrix", 16), ("translation", 3), ("rotation", 4), ("scale", 3)):
                if field in node:
                    out[field] = self.check.numbers(node[field], f"{key}.{field}", n).tolist()
            children = [self.check.index(c, f"{key}.children", len(self.nodes), "nodes")
                        for c in self.check.array(node.get("children", []), f"{key}.children")]
            for c in children:
                if c == k or parent[c] != -1:
                    self.check.fail(f"{key}.children", f"node {c} " + ("is the node itself" if c == k else
                                                                       f"is a child of node {parent[c]} already"))
                parent[c] = k
            if "mesh" in node:
                prims = per_mesh[self.check.index(node["mesh"], f"{key}.mesh", len(self.meshes), "meshes")]
                if len(prims) == 1:
                    out["mesh"] = prims[0]
                for q, mesh in enumerate(prims if len(prims) > 1 else []):
                    children.append(len(self.nodes) + len(extra))
                    extra.append({"name": f"{out.get('name', str(k))} primitive {q:06d}", "mesh": mesh})
            if children:
                out["children"] = children
            nodes.append(out)
        roots = [k for k in range(len(self.nodes)) if parent[k] == -1]
        reached, stack = set(roots), list(roots)
        while stack:
            for c in nodes[stack.pop()].get("children", []):
                if c < len(self.nodes) and c not in reached:
                    reached.add(c)
                    stack.append(c)
        if len(reached) < len(self.nodes):
            k = min(set(range(len(self.nodes))) - reached)
            self.check.fail(f"nodes[{k}]", "is in a cycle of children")

        scenes = []
        for s, scene in enumerate(self.scenes):
            key = f"scenes[{s}]"
            scene = self.check.object(scene, key)
            top = [self.check.index(k, f"{key}.nodes", len(self.nodes), "nodes")
                   for k in self.check.array(scene.get("nodes", []), f"{key}.nodes")]
            for k in top:
                if parent[k] != -1:
                    self.check.fail(f"{key}.nodes", f"node {k} is a child of node {parent[k]}, not a root")
            scenes.append({"nodes": top})
        doc = {"asset": {"version": "2.0"}, "nodes": nodes + extra, "meshes": meshes, "accessors": accessors,
               "bufferViews": views, "buffers": [{"byteLength": len(blob)}] if blob else [],
               "materials": [{"name": f"{MATERIAL_TAG}{i}"} for i in range(len(self.materials))]}
        if meshes and not scenes:
            self.check.fail("scenes", "none, so no node places a mesh")
        if scenes:
            doc["scenes"] = scenes
            doc["scene"] = self.check.index(self.doc.get("scene", 0), "scene", len(scenes), "scenes")
        return make_glb(doc, bytes(blob))
