"""The many-emitter scene types (city, office): the emitting-triangle count asked for, deterministic
from the seed, emitters one-sided facing the side they light, windows on the facades, solids
closed, the city's camera in a street that hides most emitters, shipped configs build."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from lightcuts.accel.base import check_mesh
from lightcuts.config.schema import load_config
from lightcuts.scene import city, office
from lightcuts.scene.build import image_size, scene_from_config
from lightcuts.scene.loaders import DEGENERATE_RELATIVE_AREA
from lightcuts.scene.registry import make_scene

ROOT = Path(__file__).parents[2]
SMALL = 3000


def _materials(parts) -> np.ndarray:
    """(F,) the material name of every face of ``parts.to_scene``'s scene."""
    return np.repeat(parts.materials, [len(f) for f in parts.faces])


@pytest.mark.parametrize("kind", ["city", "office"])
@pytest.mark.parametrize("emitters", [1000, 1237, 9_999, 31_623, 100_000])
def test_emitter_count_within_one_percent(kind, emitters):
    scene = make_scene(dict(type=kind, emitters=emitters))
    assert abs(len(scene.emitters) - emitters) <= 0.01 * emitters, len(scene.emitters)


@pytest.mark.parametrize("kind", ["city", "office"])
def test_a_million_emitters_in_seconds_with_modest_other_geometry(kind):
    t = time.perf_counter()
    scene = make_scene(dict(type=kind, emitters=1_000_000))
    seconds = time.perf_counter() - t
    n = len(scene.emitters)
    assert abs(n - 1_000_000) <= 10_000 and scene.n_faces - n <= 200_000
    assert seconds < 10, seconds


def test_the_city_grows_its_lights_the_office_its_floor_then_its_tiles():
    """More emitters: more lit windows, lamps and bulbs in the same city; a larger office floor up
    to MAX_PANELS panels, then finer panels."""
    made = [city.city_parts(e, 0) for e in (1000, 10_000, 100_000)]
    assert np.array_equal(made[0].buildings.hi, made[2].buildings.hi)  # the same buildings
    counts = [m.plan for m in made]
    assert counts[0]["windows"] < counts[1]["windows"] and counts[0]["lamps"] < counts[1]["lamps"]
    assert counts[0]["bulbs"] < counts[1]["bulbs"] < counts[2]["bulbs"]
    grids = [office.grid(e) for e in (1000, 10_000, 100_000, 1_000_000)]
    assert grids[0][4] < grids[1][4] < grids[2][4] == grids[3][4] <= office.MAX_PANELS
    assert grids[2][2] * grids[2][3] < grids[3][2] * grids[3][3]
    for nx, nz, _, _, panels in grids:
        assert panels <= nx * nz < panels + nz and 1.0 <= nx / nz <= 2.0


@pytest.mark.parametrize("kind", ["city", "office"])
def test_same_seed_same_bytes_other_seed_differs(kind, tmp_path):
    def saved(seed, name):
        return make_scene(dict(type=kind, emitters=SMALL, seed=seed)).save(tmp_path / f"{name}.npz").read_bytes()

    assert saved(5, "a") == saved(5, "b")
    assert saved(5, "a") != saved(6, "c")


def test_city_emitters_face_their_side():
    """Lamp heads face down, under their housing; bulbs face away from their centres; windows
    face horizontally (their facade's outward normal: test_windows_lie_on_the_facades)."""
    parts = city.city_parts(20_000, 1).parts
    scene = parts.to_scene(city.PALETTE)
    mats = _materials(parts)
    normals = scene.face_normals
    lamps = np.isin(mats, ["lamp_sodium", "lamp_white"])
    assert lamps.sum() > 100 and np.allclose(normals[lamps], [0, -1, 0])
    assert np.allclose(scene.triangles[lamps][:, :, 1], city.POLE_H - 0.252)
    bulbs = np.flatnonzero(mats == "bulb")
    tri = scene.triangles[bulbs].reshape(-1, 8, 3, 3)
    centre = tri.reshape(-1, 24, 3).mean(axis=1)
    outward = tri.mean(axis=2) - centre[:, None, :]
    assert len(tri) > 100 and np.all(np.einsum("bfk,bfk->bf", normals[bulbs].reshape(-1, 8, 3), outward) > 0)
    windows = np.isin(mats, city.WINDOW_COLOURS)
    assert windows.sum() > 1000 and np.allclose(normals[windows][:, 1], 0)
    emitting = scene.emission.max(axis=1) > 0
    assert np.array_equal(emitting, lamps | windows | (mats == "bulb"))


def test_windows_lie_on_the_facades():
    """Every window triangle (lit or dark), all three corners, lies 2 cm in front of one face of a
    building mass, inside that face, and faces away from it; just in front of it is open air."""
    parts, bld, _ = city.city_parts(10_000, 2)
    scene = parts.to_scene(city.PALETTE)
    windows = np.flatnonzero(np.isin(_materials(parts), (*city.WINDOW_COLOURS, "glass")))
    assert len(windows) > 10_000
    tri, n = scene.triangles[windows], scene.face_normals[windows]
    centre, half = 0.5 * (bld.lo + bld.hi), 0.5 * (bld.hi - bld.lo)
    tangent = np.abs(n)[:, None, :] < 0.5
    on = np.zeros(len(tri), bool)
    mid = tri.mean(axis=1)
    for c, h in zip(centre, half):
        near = np.flatnonzero(np.all(np.abs(mid - c) <= h + 0.1, axis=1))
        rel = tri[near] - c  # (T, 3 corners, 3)
        depth = np.einsum("tkj,tj->tk", rel, n[near]) - (np.abs(n[near]) @ h)[:, None]  # in front, along n
        inside = np.all((np.abs(rel) <= h + 1e-9) | ~tangent[near], axis=2)
        on[near] |= np.all(np.isclose(depth, city.WINDOW_OFF, rtol=0, atol=1e-9) & inside, axis=1)
    assert np.all(on), np.flatnonzero(~on)[:5]
    outside = tri.mean(axis=1) + 0.01 * n
    for c, h in zip(centre, half):
        assert not np.any(np.all(np.abs(outside - c) < h, axis=1))


def test_office_panels_face_down_from_the_ceiling_cells():
    parts = office.office_parts(5000, 3)
    scene = parts.to_scene(office.PALETTE)
    e = scene.emitters
    nx, nz, ku, kv, panels = office.grid(5000)
    assert len(e) == 2 * ku * kv * panels
    assert np.allclose(scene.face_normals[e], [0, -1, 0])
    tri = scene.triangles[e]
    assert np.allclose(tri[:, :, 1], office.H - office.PANEL_DROP)
    # each tile inside one 0.6 m panel centred in its ceiling cell
    cell = np.floor(tri.mean(axis=1)[:, [0, 2]] / office.PANEL_PITCH)
    centre = (cell + 0.5) * office.PANEL_PITCH
    assert np.all(np.abs(tri[:, :, [0, 2]] - centre[:, None, :]) <= 0.5 * office.PANEL + 1e-9)
    assert np.all((cell >= 0) & (cell < [nx, nz]))
    assert len(np.unique(cell, axis=0)) == panels


@pytest.mark.parametrize("kind", ["city", "office"])
def test_scene_passes_the_checks(kind):
    """Emission within the light limits, a mesh the casters take, no degenerate triangle, every
    solid closed with outward normals, emitters only on open parts, the camera inside the scene."""
    parts, palette = ((city.city_parts(SMALL, 4).parts, city.PALETTE) if kind == "city"
                      else (office.office_parts(SMALL, 4), office.PALETTE))
    scene = make_scene(dict(type=kind, emitters=SMALL, seed=4))
    scene.check_emission(kind)
    check_mesh(scene.vertices, scene.faces)
    assert scene.face_areas.min() > DEGENERATE_RELATIVE_AREA * scene.diagonal ** 2
    for v, f, closed, mat in zip(parts.vertices, parts.faces, parts.closed, parts.materials):
        if closed:
            m = trimesh.Trimesh(v, f, process=False)
            assert m.is_watertight and m.is_winding_consistent and m.volume > 0, mat
            assert max(palette[mat].emission) == 0, mat
    lo, hi = scene.bounds
    assert np.all(scene.camera.position > lo) and np.all(scene.camera.position < hi)


def test_city_street_hides_most_emitters_over_a_thousandfold_range_of_distance():
    """From the camera most emitting triangles are hidden; from the points it sees, the emitters are
    between centimetres and hundreds of metres away."""
    from lightcuts.accel.registry import make_caster
    from lightcuts.integrators.camera import eye_rays

    scene = make_scene(dict(type="city", emitters=10_000))
    e = scene.emitters
    centre, normal = scene.triangles[e].mean(axis=1), scene.face_normals[e]
    cam = scene.camera.position
    to = centre - cam
    with make_caster(scene) as caster:
        hidden = caster.occluded(np.broadcast_to(cam, to.shape).copy(), to, 1e-6, 1 - 1e-6)
        facing = np.einsum("ij,ij->i", normal, -to) > 0
        assert np.mean(hidden | ~facing) > 0.8
        org, d = eye_rays(scene.camera)
        org, d = org.reshape(-1, 3)[::13], d.reshape(-1, 3)[::13]
        t, prim = caster.intersect(org, d, 0.0, np.inf)
    points = (org + t[:, None] * d)[prim >= 0]
    dist = np.linalg.norm(points[:, None, :] - centre[None, ::5, :], axis=2)
    assert dist.max() / dist.min() > 1000 and dist.max() > 300


@pytest.mark.parametrize("name", ["city-10k", "city-100k", "city-1m", "office-10k", "office-100k", "office-1m"])
def test_shipped_config_builds(name):
    cfg = load_config(ROOT / "configs" / f"{name}.yaml")
    if name.endswith("1m"):  # the count is the config's; the scene at 10^6 is built above
        assert cfg.scene.procedural["emitters"] == 1_000_000
        return
    scene = scene_from_config(cfg)
    assert (scene.camera.width, scene.camera.height) == image_size(cfg) == (192, 128)
    assert abs(len(scene.emitters) - cfg.scene.procedural["emitters"]) <= 0.01 * cfg.scene.procedural["emitters"]


def _luminance(rgb) -> np.ndarray:
    return np.asarray(rgb, np.float64) @ [0.2126, 0.7152, 0.0722]


@pytest.mark.parametrize("emitters", [10_000, 1_000_000])
def test_an_emitters_power_does_not_depend_on_its_split(emitters):
    """A lamp head emits its area times its material's radiance whatever its tiles; the median
    window and the median ceiling panel likewise (their own factors are lognormal around 1 and
    normal around 1)."""
    parts, _, plan = city.city_parts(emitters, 0)
    scene = parts.to_scene(city.PALETTE)
    mats = _materials(parts)
    power = scene.face_areas * _luminance(scene.emission)
    for name in ("lamp_white", "lamp_sodium"):
        per = power[mats == name].reshape(-1, 2 * np.prod(plan["lamp_tiles"])).sum(axis=1)
        assert np.allclose(per, city.HEAD[0] * city.HEAD[1] * _luminance(city.PALETTE[name].emission), rtol=1e-9)
    ratios = []
    for name in city.WINDOW_COLOURS:
        per = power[mats == name].reshape(-1, 2 * np.prod(plan["panes"])).sum(axis=1)
        ratios.append(per / (city.WINDOW_W * city.WINDOW_H * _luminance(city.PALETTE[name].emission)))
    assert abs(np.median(np.concatenate(ratios)) - 1.0) < 0.03
    o = office.office_parts(emitters, 0)
    scene = o.to_scene(office.PALETTE)
    _, _, ku, kv, panels = office.grid(emitters)
    per = (scene.face_areas * _luminance(scene.emission))[scene.emitters].reshape(panels, -1).sum(axis=1)
    assert abs(np.median(per / (office.PANEL ** 2 * _luminance(office.PALETTE["panel"].emission))) - 1.0) < 0.03


def _boxes(parts, names=None) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) (B, 3) of the closed parts' boxes (8 corners each; turned ones: their bounding box)."""
    v = [pv.reshape(-1, 8, 3) for pv, c, m in zip(parts.vertices, parts.closed, parts.materials)
         if c and (names is None or m in names)]
    v = np.concatenate(v)
    return v.min(axis=1), v.max(axis=1)


@pytest.mark.parametrize("kind", ["city", "office"])
def test_no_emitter_inside_a_solid(kind):
    parts = city.city_parts(10_000, 5).parts if kind == "city" else office.office_parts(10_000, 5)
    scene = parts.to_scene(city.PALETTE if kind == "city" else office.PALETTE)
    mid = scene.triangles[scene.emitters].mean(axis=1)
    for lo, hi in zip(*_boxes(parts)):
        assert not np.any(np.all((mid > lo + 1e-9) & (mid < hi - 1e-9), axis=1)), (lo, hi)


def test_lamps_stand_on_the_sidewalks_with_their_heads_over_the_road():
    parts = city.city_parts(10_000, 6).parts
    scene = parts.to_scene(city.PALETTE)
    plinth_lo, plinth_hi = _boxes(parts, ["sidewalk"])
    lo, hi = _boxes(parts, ["metal"])
    poles = hi[:, 1] - lo[:, 1] > 5
    foot = 0.5 * (lo + hi)[poles]
    assert poles.sum() == 288 and np.allclose(lo[poles, 1], city.KERB)

    def on_plinth(p):
        return np.any(np.all((p[:, None, [0, 2]] > plinth_lo[None, :, [0, 2]])
                             & (p[:, None, [0, 2]] < plinth_hi[None, :, [0, 2]]), axis=2), axis=1)

    assert np.all(on_plinth(foot))
    mats = _materials(parts)
    heads = scene.triangles[np.isin(mats, ["lamp_white", "lamp_sodium"])].mean(axis=1)
    assert len(heads) and not np.any(on_plinth(heads))
    # over the road, within the arm's reach of the kerb
    kerb = np.min([np.abs(heads[:, None, a] - np.stack([plinth_lo[:, a], plinth_hi[:, a]], 1).ravel()[None]).min(axis=1)
                   for a in (0, 2)], axis=0)
    assert np.all(kerb < city.ARM)


@pytest.mark.parametrize("integrator", ["lightcuts", "path"])
@pytest.mark.parametrize("name", ["city-10k", "office-10k"])
def test_shipped_config_renders(name, integrator):
    """The default integrator and the path tracer render the configs end to end (small, few
    samples): a finite image, lit."""
    import lightcuts

    cfg = lightcuts.load_config(ROOT / "configs" / f"{name}.yaml", **{
        "camera.resolution": [48, 32], "render.integrator": integrator, "render.spp": 2,
        "lights.indirect.count": 1000})
    image = lightcuts.render(cfg, progress=False).image
    assert np.all(np.isfinite(image)) and np.all(image >= 0) and np.mean(image > 0) > 0.2


def test_material_overrides_keep_each_emitters_own_factor():
    """``scene.materials`` replaces a palette entry by name; every emitter of it keeps its factor."""
    base = make_scene(dict(type="city", emitters=SMALL))
    over = make_scene(dict(type="city", emitters=SMALL), {"window_warm": {"emission": [12.0, 7.4, 3.6]}})
    changed = np.any(base.emission != over.emission, axis=1)
    assert changed.sum() > 100
    np.testing.assert_allclose(over.emission[changed], 2 * base.emission[changed], rtol=1e-12)
    assert np.unique(np.round(over.emission[changed, 0], 9)).size > 10  # the windows' own radiances
    np.testing.assert_array_equal(base.albedo, over.albedo)
