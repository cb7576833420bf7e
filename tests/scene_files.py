"""Small scene files for the tests of textures, glTF and bad inputs: a textured quad as OBJ + MTL
or as glTF, PNG bytes, and a PNG whose header claims any size (no pixels behind it)."""

from __future__ import annotations

import base64
import io
import json
import struct
import zlib
from pathlib import Path

import numpy as np
from hypothesis import strategies as st
from PIL import Image

from lightcuts.scene.gltf import make_glb, split_glb

RED, BLUE = (200, 50, 50), (30, 120, 220)
#: The quad's corners (z = 0, facing +z) and their texture coordinates, OBJ convention (v up).
QUAD = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
QUAD_UV = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)


def checkerboard(n: int = 4, px: int = 8) -> np.ndarray:
    """(n px, n px, 3) uint8: n x n squares, RED where row + column is even (row 0 at the top)."""
    i = np.arange(n * px) // px
    even = (i[:, None] + i[None, :]) % 2 == 0
    return np.where(even[:, :, None], np.array(RED, np.uint8), np.array(BLUE, np.uint8)).astype(np.uint8)


def png_bytes(rgb: np.ndarray) -> bytes:
    out = io.BytesIO()
    Image.fromarray(np.asarray(rgb, np.uint8)).save(out, format="PNG")
    return out.getvalue()


def broken_png() -> bytes:
    """A PNG of noise cut in the middle of its pixel data: a header Pillow reads, data it cannot."""
    png = png_bytes(np.random.default_rng(0).integers(0, 256, (16, 16, 3)).astype(np.uint8))
    return png[:len(png) // 2]


def png_claiming(width: int, height: int) -> bytes:
    """A PNG whose IHDR says ``width`` x ``height`` RGB texels, followed by a few bytes of data:
    what a decompression bomb looks like before it is decoded."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    data = chunk(b"IDAT", zlib.compress(b"\0" * 16))
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + data + chunk(b"IEND", b"")


@st.composite
def image_bytes(draw):
    """A PNG for fuzzing: a real one, cut short, with a byte flipped, or a bare header claiming a
    size up to 2**20 x 2**20."""
    kind = draw(st.sampled_from(["real", "cut", "flipped", "claim"]))
    if kind == "claim":
        return png_claiming(draw(st.integers(0, 1 << 20)), draw(st.integers(0, 1 << 20)))
    png = png_bytes(checkerboard(2, draw(st.integers(1, 4))))
    if kind == "cut":
        return png[:draw(st.integers(0, len(png)))]
    if kind == "flipped":
        at = draw(st.integers(0, len(png) - 1))
        return png[:at] + bytes([png[at] ^ draw(st.integers(1, 255))]) + png[at + 1:]
    return png


def quad_obj(folder: Path, mtl: str, texture: np.ndarray | None = None, name: str = "quad",
             uv: list[str] | None = None) -> Path:
    """``name``.obj: the 2 x 2 quad with material m of ``mtl`` (written as ``name``.mtl), its
    corners' ``vt`` lines ``uv`` (default 0 0, 1 0, 1 1, 0 1); ``texture`` saved as tex.png."""
    uv = uv or ["0 0", "1 0", "1 1", "0 1"]
    (folder / f"{name}.obj").write_text(
        f"mtllib {name}.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n" + "".join(f"vt {t}\n" for t in uv)
        + "usemtl m\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    (folder / f"{name}.mtl").write_text(mtl)
    if texture is not None:
        Image.fromarray(texture).save(folder / "tex.png")
    return folder / f"{name}.obj"


def quad_gltf(material: dict | None = None, uv=None) -> tuple[dict, bytes]:
    """A glTF document of the quad (one node, one triangle primitive with POSITION, TEXCOORD_0 and
    indices, material 0 = ``material``, default a diffuse white) and its buffer's bytes. glTF's v
    runs down the image: TEXCOORD_0 is 1 - v of :data:`QUAD_UV` unless ``uv`` (4, 2) is given."""
    uv = np.stack([QUAD_UV[:, 0], 1 - QUAD_UV[:, 1]], 1) if uv is None else np.asarray(uv, np.float32)
    blob = QUAD.tobytes() + np.asarray(uv, np.float32).tobytes() + np.array([0, 1, 2, 0, 2, 3], np.uint16).tobytes()
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "name": "quad"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
                      {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
                      {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                        {"buffer": 0, "byteOffset": 48, "byteLength": 32},
                        {"buffer": 0, "byteOffset": 80, "byteLength": 12}],
        "buffers": [{"byteLength": len(blob)}],
        "materials": [material if material is not None else {"pbrMetallicRoughness": {"metallicFactor": 0.0}}],
    }
    return doc, blob


def write_gltf(path: Path, doc: dict, blob: bytes) -> Path:
    """``doc`` with buffer 0 = ``blob``: a GLB (``.glb``) or a ``.gltf`` with a data: URI."""
    path = Path(path)
    if path.suffix == ".glb":
        path.write_bytes(make_glb(doc, blob))
    else:
        doc = json.loads(json.dumps(doc))
        doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
        path.write_text(json.dumps(doc))
    return path


def textured_material(extra: dict | None = None) -> dict:
    """A diffuse material with base colour texture 0."""
    return {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}, **(extra or {})}


def edit_glb(path: Path, edit) -> None:
    """Rewrite a GLB file's JSON document by ``edit(doc)`` (in place), keeping its BIN chunk."""
    text, binary = split_glb(path.read_bytes(), str(path))
    doc = json.loads(text)
    edit(doc)
    path.write_bytes(make_glb(doc, binary or b""))
