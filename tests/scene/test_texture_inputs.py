"""Textures as inputs: any finite texture coordinate reads the texel of its wrapped value (in the
lookup kernel, the uv maps, the per-triangle means and a rendered image), coordinates that overflow
are refused, and images are checked from their header (the texel limits, one line, no decoding)
and named for what they are when they are not files."""

from __future__ import annotations

import math
import os
import time
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import lightcuts
from lightcuts.errors import LightcutsError
from lightcuts.scene.loaders import load_mesh
from lightcuts.scene.textures import TextureSet, face_texture_means, image_to_linear, read_image, texture_lookup
from scene_files import checkerboard, image_bytes, png_bytes, png_claiming, quad_obj

_SET = TextureSet()
_SET.add(np.random.default_rng(1).random((3, 5, 3)).astype(np.float32), "noise")  # 5 wide, 3 high


def _look(u, v):
    return np.array(texture_lookup(_SET.texels, _SET.table, 0, u, v))


@pytest.mark.parametrize("u, wrapped", [(3e18, 0.0), (-3e18, 0.0), (2.0 ** 51 + 0.5, 0.5), (-(2.0 ** 50) - 0.25, 0.75),
                                        (1e300, 0.0), (-1.7e308, 0.0), (7.25, 0.25), (-1e-300, 1.0)])
def test_a_huge_coordinate_reads_the_texel_of_its_wrapped_value(u, wrapped):
    np.testing.assert_array_equal(_look(u, 0.4), _look(wrapped, 0.4))
    np.testing.assert_array_equal(_look(0.4, u), _look(0.4, wrapped))


@settings(max_examples=200, deadline=None)
@given(u=st.floats(allow_nan=False, allow_infinity=False), v=st.floats(allow_nan=False, allow_infinity=False))
def test_any_finite_coordinate_reads_an_interpolation_of_texels_of_its_wrapped_value(u, v):
    got = _look(u, v)
    assert np.array_equal(got, _look(u - math.floor(u), v - math.floor(v)))
    texels = _SET.texels.astype(np.float64)
    assert np.all(got >= texels.min(axis=0) - 1e-6) and np.all(got <= texels.max(axis=0) + 1e-6)


def test_per_triangle_means_read_huge_coordinates_as_their_wrapped_values():
    """Whole periods added to a triangle's coordinates (exactly: dyadic values) change nothing,
    though the points between its corners are not representable next to the shift."""
    uv = np.array([[[0.125, 0.625], [0.375, 0.625], [0.125, 0.875]]])
    for shift in (3e18, -3e18, 2.0 ** 44):
        base = uv if shift == 2.0 ** 44 else np.zeros_like(uv)  # 3e18 + 0.125 is 3e18
        np.testing.assert_array_equal(face_texture_means(_SET, np.array([0]), base + shift),
                                      face_texture_means(_SET, np.array([0]), base))


def _render(folder, obj: str):
    (folder / "run.yaml").write_text(
        f"scene: {{meshes: [{{file: {obj}}}]}}\n"
        "camera: {position: [0, 0, 3], look_at: [0, 0, 0], up: [0, 1, 0], fov: 30, resolution: [16, 16]}\n"
        f"lights: {{sun: {{direction: [0, 0, 1], irradiance: [{math.pi}, {math.pi}, {math.pi}]}}}}\n")
    return lightcuts.render(lightcuts.load_config(folder / "run.yaml"), progress=False).image


def test_a_quad_with_coordinates_3e18_renders_as_with_their_wrapped_ones(tmp_path):
    """``vt 3e18 ...`` (or -3e18) on a textured quad: the image of ``vt 0 ...``, the checkerboard's
    first column blended with its last (u = 0 is between them), seen at albedo x irradiance / pi."""
    quad_obj(tmp_path, "newmtl m\nmap_Kd tex.png\n", checkerboard(), name="wrapped", uv=["0 0", "0 0", "0 1", "0 1"])
    expected = _render(tmp_path, "wrapped.obj")
    edge = image_to_linear(checkerboard())[:, [0, -1]].mean(axis=1)  # per row, u = 0 blends both ends
    assert 0.05 < expected.mean() < float(edge.max()) + 1e-3
    for u in ("3e18", "-3e18"):
        quad_obj(tmp_path, "newmtl m\nmap_Kd tex.png\n", name="huge", uv=[f"{u} 0", f"{u} 0", f"{u} 1", f"{u} 1"])
        np.testing.assert_array_equal(_render(tmp_path, "huge.obj"), expected)


@pytest.mark.parametrize("uv, mtl, words", [
    (["1e308 0", "-1e308 0", "0 1", "0 1"], "map_Kd tex.png", "change faster across them than float64 holds"),
    (["nan 0", "1 0", "1 1", "0 1"], "map_Kd tex.png", "NaN or infinite texture coordinates"),
    (["2 0", "1 0", "1 1", "0 1"], "map_Kd -s 1e308 1e308 1 tex.png", "moved and scaled by map_Kd -o and -s"),
])
def test_coordinates_that_overflow_are_refused_naming_the_file(tmp_path, uv, mtl, words):
    p = quad_obj(tmp_path, f"newmtl m\n{mtl}\n", checkerboard(), uv=uv)
    with pytest.raises(LightcutsError, match=words) as e:
        load_mesh(p)
    assert str(e.value).startswith(f"scene.meshes.0: {p}: a textured material ") and "\n" not in str(e.value)


def test_check_uv_refuses_coordinates_whose_differences_overflow():
    from lightcuts.scene.textures import check_uv

    check_uv(np.array([[[8e307, 0], [-8e307, 0], [0, 1]]]), "x")
    with pytest.raises(LightcutsError, match="^x: the texture coordinates of 1 triangles change faster"):
        check_uv(np.array([[[9e307, 0], [-9e307, 0], [0, 1]]]), "x")


def test_a_scale_of_1e308_within_float64_reads_wrapped_texels(tmp_path):
    """-s 1e308 on coordinates up to 1: huge but finite, so the quad loads; its uv maps are finite
    and the coordinates are whole numbers, whose texels are those of 0."""
    s = load_mesh(quad_obj(tmp_path, "newmtl m\nmap_Kd -s 1e308 1e308 1 tex.png\n", checkerboard()))
    assert s.uv.max() == 1e308 and np.all(np.isfinite(s.texture_data()[1]))


def test_a_png_claiming_16000_x_16000_is_refused_from_its_header(tmp_path):
    """One line before any decoding (its pixel data is 16 bytes), from load_mesh and from
    lightcuts.render; sizes between the limit and Pillow's own warn nothing either."""
    (tmp_path / "tex.png").write_bytes(png_claiming(16000, 16000))
    p = quad_obj(tmp_path, "newmtl m\nmap_Kd tex.png\n")
    t0 = time.perf_counter()
    with pytest.raises(LightcutsError, match=r"tex.png: its header claims more than [0-9,]+ texels, more than the "
                                             r"67,108,864 a texture may have") as e:
        load_mesh(p)
    assert time.perf_counter() - t0 < 2.0 and "\n" not in str(e.value)
    (tmp_path / "run.yaml").write_text("scene: {meshes: [{file: quad.obj}]}\n"
                                       "lights: {sun: {direction: [0, 0, 1], irradiance: [1, 1, 1]}}\n")
    with pytest.raises(LightcutsError, match="its header claims"):
        lightcuts.render(lightcuts.load_config(tmp_path / "run.yaml"), progress=False)
    for w, h in ((9000, 9000), (10000, 10000)):  # above the limit; the second, above Pillow's warning
        (tmp_path / "tex.png").write_bytes(png_claiming(w, h))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with pytest.raises(LightcutsError, match=f"tex.png: {w} x {h} texels, more than the 67,108,864"):
                load_mesh(p)


def test_the_texel_limits_per_image_and_per_scene(tmp_path, monkeypatch):
    """Per image (MAX_TEXELS) and for all a scene's images together (MAX_SCENE_TEXELS), the
    second naming the mesh whose image goes beyond."""
    import lightcuts.scene.textures as textures
    from lightcuts.scene.build import scene_from_config

    quad_obj(tmp_path, "newmtl m\nmap_Kd tex.png\n", checkerboard(4, 8))  # 32 x 32 = 1024 texels
    monkeypatch.setattr(textures, "MAX_TEXELS", 1023)
    with pytest.raises(LightcutsError, match="32 x 32 texels, more than the 1,023 a texture may have"):
        load_mesh(tmp_path / "quad.obj")
    monkeypatch.setattr(textures, "MAX_TEXELS", 1024)
    assert load_mesh(tmp_path / "quad.obj").textured
    monkeypatch.setattr(textures, "MAX_SCENE_TEXELS", 2047)
    (tmp_path / "run.yaml").write_text("scene: {meshes: [{file: quad.obj}, {file: quad.obj, translate: [3, 0, 0]}]}\n")
    with pytest.raises(LightcutsError, match=r"^scene.meshes.1: .*bring the scene's textures to 2,048, more than the "
                                             r"2,047 a scene may have"):
        scene_from_config(lightcuts.load_config(tmp_path / "run.yaml"))
    monkeypatch.setattr(textures, "MAX_SCENE_TEXELS", 2048)
    assert scene_from_config(lightcuts.load_config(tmp_path / "run.yaml")).textured


@pytest.mark.parametrize("make, problem", [(lambda p: p.mkdir(), "is a folder, not a file"),
                                           (lambda p: None, "no such file"),
                                           (lambda p: os.mkfifo(p), "not a regular file"),  # and no hang
                                           (lambda p: p.write_bytes(b""), "cannot read image")])
def test_an_image_that_is_not_an_image_file_says_what_it_is(tmp_path, make, problem):
    make(tmp_path / "x.png")
    with pytest.raises(LightcutsError, match=f"^here: {problem}"):
        read_image(tmp_path / "x.png", "here")
    with pytest.raises(LightcutsError, match="^here: not a regular file"):
        read_image("/dev/null", "here")
    assert read_image(png_bytes(checkerboard()), "here").shape == (32, 32, 3)


def test_an_image_a_decoder_gives_as_empty_is_refused(monkeypatch):
    """Pillow's PNG and PPM readers refuse a size of 0; should any decoder give one, the lookup,
    which takes texel indices modulo the size, never sees it."""
    from PIL import Image

    monkeypatch.setattr(Image, "open", lambda *a, **k: Image.new("RGB", (0, 5)))
    with pytest.raises(LightcutsError, match=r"^here: an empty image \(0 x 5 texels\)"):
        read_image(b"anything", "here")


#: Texture coordinates and option values: small, any finite, huge (NaN and infinity: tested above).
_VT = st.floats(-3, 3).map(repr) | st.floats(allow_nan=False, allow_infinity=False).map(repr) \
    | st.sampled_from(["3e18", "-3e18", "1e308", "-1e308"])


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(uv=st.lists(st.tuples(_VT, _VT), min_size=4, max_size=4), scale=st.none() | st.tuples(_VT, _VT),
       offset=st.none() | st.tuples(_VT, _VT), image=image_bytes())
def test_fuzz_obj_texture_coordinates_options_and_images(tmp_path, uv, scale, offset, image):
    """A map_Kd quad with any ``vt`` values, ``-s`` and ``-o`` options and image: it loads, with
    finite texture coordinates and uv maps, or is one LightcutsError naming the file."""
    (tmp_path / "tex.png").write_bytes(image)
    options = "".join(f"-{k} {a} {b} 1 " for k, ab in (("s", scale), ("o", offset)) if ab is not None for a, b in [ab])
    p = quad_obj(tmp_path, f"newmtl m\nmap_Kd {options}tex.png\n", uv=[f"{a} {b}" for a, b in uv])
    try:
        s = load_mesh(p)
    except LightcutsError as exc:
        assert str(exc).startswith(f"scene.meshes.0: {p}: ") and "\n" not in str(exc)
        return
    assert s.textured and np.all(np.isfinite(s.uv)) and np.all(np.isfinite(s.texture_data()[1]))
    assert np.all(np.isfinite(s.textures.texels))
