"""Mitsuba 3 XML scenes (``scene.mitsuba``, lightcuts.scene.mitsuba_xml): the scenes are written by
the tests; geometry and transforms, every mapped BSDF, the sensor, the sun, one-line errors, and
lightcuts' converging direct light against Mitsuba rendering the file itself. Skipped only where
Mitsuba cannot be imported."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from lightcuts.errors import LightcutsError

pytest.importorskip("mitsuba")

from lightcuts.scene.mitsuba_xml import MAX_PBR_EXPONENT, load_mitsuba_xml  # noqa: E402

SENSOR = """<sensor type="perspective"><float name="fov" value="{fov}"/><string name="fov_axis" value="{axis}"/>
  <transform name="to_world"><lookat origin="0,1,3.2" target="0,1,0" up="0,1,0"/></transform>
  <film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="{h}"/></film></sensor>"""


def _xml(tmp_path: Path, body: str, name: str = "s.xml", fov=50, axis="x", w=48, h=40) -> Path:
    p = tmp_path / name
    p.write_text(f'<scene version="3.0.0">{SENSOR.format(fov=fov, axis=axis, w=w, h=h)}{body}</scene>')
    return p


def _rect(bsdf: str, transform: str = "", emitter: str = "") -> str:
    return f'<shape type="rectangle"><transform name="to_world">{transform}</transform>{bsdf}{emitter}</shape>'


def test_rectangle_transform_and_diffuse_are_read_exactly(tmp_path):
    p = _xml(tmp_path, _rect('<bsdf type="diffuse"><rgb name="reflectance" value="0.7,0.2,0.1"/></bsdf>',
                             '<scale x="2" y="0.5"/><rotate x="1" angle="-90"/><translate value="1,2,3"/>'))
    scene, sun = load_mitsuba_xml(p)
    assert sun is None and scene.n_faces == 2
    assert scene.face_areas.sum() == pytest.approx(4 * 2 * 0.5)  # the unit square [-1, 1]^2 scaled
    np.testing.assert_allclose(scene.face_normals, [[0, 1, 0]] * 2, atol=1e-12)  # rotated to face +y
    np.testing.assert_allclose(scene.bounds, [[-1, 2, 2.5], [3, 2, 3.5]], atol=1e-6)
    np.testing.assert_allclose(scene.albedo, [[0.7, 0.2, 0.1]] * 2, rtol=1e-6)
    assert not scene.specular.any() and not scene.emission.any()


def test_analytic_shapes_keep_their_area_and_emitters_their_radiance(tmp_path):
    body = ('<shape type="sphere"><point name="center" value="1,0,0"/><float name="radius" value="0.5"/></shape>'
            '<shape type="disk"><transform name="to_world"><scale value="0.3"/><rotate x="1" angle="90"/>'
            '<translate value="0,2,0"/></transform><emitter type="area"><rgb name="radiance" value="4,5,6"/>'
            '</emitter></shape><shape type="cube"><transform name="to_world"><scale value="0.25"/></transform></shape>')
    scene, _ = load_mitsuba_xml(_xml(tmp_path, body))
    lit = scene.emitters
    assert scene.face_areas[lit].sum() == pytest.approx(math.pi * 0.09, rel=0.01)
    np.testing.assert_allclose(scene.emission[lit], [[4, 5, 6]] * len(lit))
    np.testing.assert_allclose(scene.face_normals[lit], [[0, -1, 0]] * len(lit), atol=1e-9)  # disk's +z, rotated
    sphere = np.flatnonzero(np.linalg.norm(scene.triangles.mean(axis=1) - [1, 0, 0], axis=1) < 0.6)
    assert scene.face_areas[sphere].sum() == pytest.approx(math.pi, rel=0.01)  # 4 pi r^2
    outward = np.einsum("ij,ij->i", scene.face_normals[sphere], scene.triangles[sphere].mean(axis=1) - [1, 0, 0])
    assert (outward > 0).all()
    assert len(scene.faces) - len(lit) - len(sphere) == 12  # the cube
    assert scene.albedo[sphere] == pytest.approx(0.5)  # no BSDF: Mitsuba's default diffuse 0.5


@pytest.mark.parametrize("bsdf, rho_d, rho_s, n", [
    ('<bsdf type="plastic"><rgb name="diffuse_reflectance" value="0.5,0.4,0.3"/></bsdf>',
     None, 0.04, MAX_PBR_EXPONENT),
    ('<bsdf type="roughplastic"><rgb name="diffuse_reflectance" value="0.5,0.4,0.3"/><float name="alpha" value="0.1"/>'
     '</bsdf>', None, 0.04, 2 / 0.01 - 2),
    ('<bsdf type="conductor"><string name="material" value="none"/></bsdf>', [0, 0, 0], 1.0, MAX_PBR_EXPONENT),
    ('<bsdf type="roughconductor"><string name="material" value="none"/><float name="alpha" value="0.2"/>'
     '<rgb name="specular_reflectance" value="0.5,0.5,0.5"/></bsdf>', [0, 0, 0], 0.5, 2 / 0.04 - 2),
    ('<bsdf type="twosided"><bsdf type="roughconductor"><string name="material" value="none"/>'
     '<float name="alpha" value="0.2"/></bsdf></bsdf>', [0, 0, 0], 1.0, 2 / 0.04 - 2),
])
def test_each_mapped_bsdf(tmp_path, bsdf, rho_d, rho_s, n):
    scene, _ = load_mitsuba_xml(_xml(tmp_path, _rect(bsdf)))
    assert scene.exponent[0] == pytest.approx(n, rel=1e-5)
    if rho_d is None:  # plastic: ior 1.49 (Mitsuba's polypropylene), F0 = ((eta - 1) / (eta + 1))^2
        f0 = ((1.49 - 1) / (1.49 + 1)) ** 2
        assert scene.specular[0] == pytest.approx(f0, rel=0.01)
        ratio = scene.albedo[0] / [0.5, 0.4, 0.3]
        assert ratio == pytest.approx(ratio[0]) and 0.8 < ratio[0] < 1.1  # one scale for all channels
    else:
        np.testing.assert_allclose(scene.albedo[0], rho_d)
        assert scene.specular[0] == pytest.approx(rho_s, rel=1e-5)


def test_gold_conductor_reflects_more_red_than_blue(tmp_path):
    scene, _ = load_mitsuba_xml(_xml(tmp_path, _rect('<bsdf type="conductor"><string name="material" value="Au"/>'
                                                     '</bsdf>')))
    r, g, b = scene.specular[0]
    assert 0.8 < r <= 1 and r > g > b and scene.albedo[0].max() == 0


def test_sensor_gives_the_camera_with_the_vertical_fov(tmp_path):
    scene, _ = load_mitsuba_xml(_xml(tmp_path, _rect(""), fov=60, axis="x", w=80, h=40))
    cam = scene.camera
    assert (cam.width, cam.height) == (80, 40)
    assert math.tan(math.radians(cam.fov) / 2) == pytest.approx(math.tan(math.radians(30)) / 2)
    np.testing.assert_allclose(cam.position, [0, 1, 3.2], atol=1e-6)
    np.testing.assert_allclose(cam.look_at - cam.position, [0, 0, -1], atol=1e-6)
    np.testing.assert_allclose(cam.up, [0, 1, 0], atol=1e-6)
    tall, _ = load_mitsuba_xml(_xml(tmp_path, _rect(""), name="t.xml", fov=60, axis="y", w=80, h=40))
    assert tall.camera.fov == pytest.approx(60)


def test_directional_emitter_is_the_sun(tmp_path):
    body = _rect("") + ('<emitter type="directional"><vector name="direction" value="0,-1,-1"/>'
                        '<rgb name="irradiance" value="2,3,4"/></emitter>')
    _, (direction, irradiance) = load_mitsuba_xml(_xml(tmp_path, body))
    np.testing.assert_allclose(direction, np.array([0, 1, 1]) / math.sqrt(2), atol=1e-6)  # towards the sun
    np.testing.assert_allclose(irradiance, [2, 3, 4])


@pytest.mark.parametrize("body, message", [
    (_rect('<bsdf type="dielectric"/>'), "BSDF 'SmoothDielectric' has no Lambert + Phong mapping"),
    (_rect("") + '<emitter type="spot"><transform name="to_world"><lookat origin="0,1,0" target="0,0,0"/>'
     '</transform></emitter>', "emitter 'SpotLight' is not read"),
    (_rect("") + '<emitter type="constant"/>', "emitter 'ConstantBackgroundEmitter' is not read"),
    ("<shape type='rectangle'>", "Mitsuba cannot load it"),
])
def test_what_is_not_read_is_one_line(tmp_path, body, message):
    with pytest.raises(LightcutsError) as exc:
        load_mitsuba_xml(_xml(tmp_path, body))
    text = str(exc.value)
    assert text.startswith("scene.mitsuba: ") and message in text and "\n" not in text


def test_missing_file_is_one_line_before_any_work(tmp_path, capsys):
    from lightcuts.cli import main

    cfg = tmp_path / "c.yaml"
    cfg.write_text("scene: {mitsuba: nowhere.xml}\n")
    assert main(["render", str(cfg)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "scene.mitsuba" in err and "nowhere.xml" in err


BOX = """<bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.7,0.7,0.7"/></bsdf>
<bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.7,0.1,0.1"/></bsdf>
{floor}{back}{left}
<shape type="cube"><transform name="to_world"><scale value="0.3"/><rotate y="1" angle="20"/>
  <translate value="0.3,0.3,0"/></transform><ref id="white"/></shape>
<shape type="rectangle"><transform name="to_world"><scale value="0.25"/><rotate x="1" angle="90"/>
  <translate value="0,1.9,0"/></transform>
  <emitter type="area"><rgb name="radiance" value="10,10,10"/></emitter></shape>"""


def test_diffuse_scene_matches_mitsuba_rendering_the_file(tmp_path, monkeypatch):
    """lightcuts' converging direct light against Mitsuba's ``direct`` integrator on the XML file itself,
    the emitter out of view (its edges are what a few lightcuts passes resolve worst), clamping off
    (it adds about 0.9% here, lightcuts' own bias, not the file's)."""
    import lightcuts.mitsuba.render as mitsuba_render
    from lightcuts.cli import main

    def no_export(*args, **kwargs):
        raise AssertionError("the XML file goes to Mitsuba as it is, not through lightcuts' export")

    monkeypatch.setattr(mitsuba_render, "scene_dict", no_export)
    walls = dict(floor=_rect('<ref id="white"/>', '<rotate x="1" angle="-90"/>'),
                 back=_rect('<ref id="white"/>', '<translate value="0,1,-1"/>'),
                 left=_rect('<ref id="red"/>', '<rotate y="1" angle="90"/><translate value="-1,1,0"/>'))
    _xml(tmp_path, BOX.format(**walls), name="box.xml", fov=40, w=40, h=32)
    cfg = tmp_path / "box.yaml"
    cfg.write_text("name: box\nscene: {mitsuba: box.xml}\ncamera: {look_at: [0, 0.6, 0]}\n"
                   "lights: {direct: {count: 4096}}\n"
                   "render: {compensation: true, representatives: stochastic, passes: 16, clamp: {enabled: false}}\n")
    assert main(["reference", str(cfg), "--integrator", "direct", "--spp", "256", "--out", str(tmp_path / "r"),
                 "--no-progress"]) == 0
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    assert report["comparison"]["energy_ratio"] == pytest.approx(1.0, abs=0.01)
    assert report["comparison"]["block8"]["median"] < 0.01
    assert list(report["mitsuba_xml"]["bsdfs"]) == ["diffuse"]
    assert report["mitsuba_xml"]["bsdfs"]["diffuse"]["mapping"] == "exact (Lambert)"  # Mitsuba merges shapes


@pytest.mark.parametrize("to_uv", ["", '<transform name="to_uv"><scale x="2" y="3"/></transform>'])
def test_bitmap_texture_is_looked_up_where_mitsuba_looks(tmp_path, to_uv):
    """lightcuts' albedo at points of a textured rectangle equals Mitsuba's own diffuse reflectance
    at the same points (sRGB decoding, v orientation, ``to_uv``)."""
    from PIL import Image

    from lightcuts.scene.mitsuba_xml import load_xml
    from lightcuts.scene.textures import texture_lookup

    rgb = np.array([[[255, 0, 0], [0, 255, 0], [40, 90, 200]], [[0, 0, 255], [128, 128, 128], [250, 200, 10]]],
                   np.uint8)
    Image.fromarray(rgb).save(tmp_path / "t.png")
    p = _xml(tmp_path, _rect(f'<bsdf type="diffuse"><texture type="bitmap" name="reflectance">'
                             f'<string name="filename" value="t.png"/>'
                             f'{to_uv}</texture></bsdf>'))
    scene, _ = load_mitsuba_xml(p)
    mi, xml = load_xml(p)
    bsdf = xml.shapes()[0].bsdf()
    tex = scene.textures
    for x, y in [(-0.8, -0.7), (0.1, -0.6), (0.7, 0.6), (-0.5, 0.4), (0.35, 0.05)]:
        si = xml.ray_intersect(mi.Ray3f(mi.Point3f(x, y, 1.0), mi.Vector3f(0, 0, -1)))
        want = np.array(bsdf.eval_diffuse_reflectance(si), np.float64).reshape(3)
        f = next(i for i in range(scene.n_faces) if _inside(scene.triangles[i], (x, y)))
        w = _barycentric(scene.triangles[f], (x, y))
        u, v = w @ scene.uv[f]
        got = np.array(texture_lookup(tex.texels, tex.table, int(scene.texture[f]), u, v))
        np.testing.assert_allclose(got, want, atol=0.02, err_msg=f"at {(x, y)}")


def _barycentric(t, xy):
    a = np.array([[t[0, 0], t[1, 0], t[2, 0]], [t[0, 1], t[1, 1], t[2, 1]], [1, 1, 1]])
    return np.linalg.solve(a, [xy[0], xy[1], 1.0])


def _inside(t, xy):
    return bool((_barycentric(t, xy) >= -1e-9).all())


def test_point_emitter_is_an_omni_light_matching_mitsuba(tmp_path):
    """A point emitter becomes one omni light of its intensity: lightcuts' direct light (16 samples
    per pixel, clamping off) against Mitsuba rendering the file."""
    from lightcuts.cli import main

    body = ('<bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.7,0.7,0.7"/></bsdf>'
            + _rect('<ref id="white"/>', '<rotate x="1" angle="-90"/>')
            + _rect('<ref id="white"/>', '<translate value="0,1,-1"/>')
            + '<shape type="cube"><transform name="to_world"><scale value="0.3"/><translate value="0.3,0.3,0"/>'
              '</transform><ref id="white"/></shape>'
            '<emitter type="point"><point name="position" value="-0.3,1.5,0.4"/><rgb name="intensity" value="3,2,1"/>'
            '</emitter>')
    _xml(tmp_path, body, name="pt.xml", fov=40, w=40, h=32)
    cfg = tmp_path / "pt.yaml"
    cfg.write_text("name: pt\nscene: {mitsuba: pt.xml}\ncamera: {look_at: [0, 0.6, 0]}\n"
                   "render: {spp: 16, clamp: {enabled: false}}\n")
    assert main(["reference", str(cfg), "--integrator", "direct", "--spp", "256", "--out", str(tmp_path / "r"),
                 "--no-progress"]) == 0
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    assert report["lightcuts"]["lights"] == {"omni": 1}
    assert report["comparison"]["energy_ratio"] == pytest.approx(1.0, abs=0.01)
    assert report["comparison"]["block8"]["median"] < 0.01


def test_without_mitsuba_a_mitsuba_scene_is_one_line_naming_the_extra(tmp_path):
    import os
    import subprocess
    import sys

    _xml(tmp_path, _rect(""), name="s.xml")
    (tmp_path / "c.yaml").write_text("scene: {mitsuba: s.xml}\n")
    code = ("import sys; sys.modules['mitsuba'] = None\nfrom lightcuts.cli import main\n"
            f"sys.exit(main(['render', {str(tmp_path / 'c.yaml')!r}, '--out', {str(tmp_path / 'out')!r}]))\n")
    root = Path(__file__).resolve().parents[2]
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       env=dict(os.environ, PYTHONPATH=str(root)))
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert lines[0].startswith("error: scene.mitsuba: needs Mitsuba 3") and lines[0].endswith("lightcuts[mitsuba]'")
    assert not (tmp_path / "out").exists()
