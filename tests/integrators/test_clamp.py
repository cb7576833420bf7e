"""The clamp radius of indirect VPLs (docs/math.md, "Clamping"): from the VPLs' density by default,
from the scene's diagonal when a config sets ``min_distance``, and the same at every scale."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import lightcuts
from lightcuts.integrators.forest import build_forest
from lightcuts.integrators.lightcut import Lightcuts
from lightcuts.integrators.registry import make_integrator
from lightcuts.lights.lightset import LightSet
from lightcuts.lights.spacing import vpl_spacing

ROOT = Path(__file__).resolve().parents[2]


def _bench():
    spec = importlib.util.spec_from_file_location("bench_clamp", ROOT / "benchmarks" / "bench_clamp.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class _Scene:
    diagonal = 20.0


def _lights(n: int = 3000, scale: float = 1.0) -> dict:
    rng = np.random.default_rng(5)
    p = np.column_stack([rng.uniform(0, 4, n), np.zeros(n), rng.uniform(0, 4, n)]) * scale
    indirect = np.arange(n) % 3 > 0
    return {"oriented": LightSet(p, np.tile([0.0, 1.0, 0.0], (n, 1)), np.ones((n, 3)), "oriented", indirect)}


def test_density_radius_is_sqrt_vpls_times_the_indirect_spacing():
    lights = _lights(300_000)  # 200,000 indirect: min(400, 200,000 / 250) = 400
    forest = build_forest(lights, None)
    s = vpl_spacing(lights["oriented"].position[lights["oriented"].indirect])
    assert forest.vpl_spacing == s > 0 and forest.vpl_count == 200_000
    assert Lightcuts().clamp_radius(_Scene(), forest) == pytest.approx(20.0 * s, rel=1e-12)  # vpls 400
    assert Lightcuts(clamp_vpls=100).clamp_radius(_Scene(), forest) == pytest.approx(10.0 * s, rel=1e-12)
    assert Lightcuts(clamp_vpls=100).clamp_d2(_Scene(), forest) == pytest.approx(100.0 * s * s, rel=1e-12)
    assert Lightcuts(clamp_min_distance=0.05).clamp_radius(_Scene(), forest) == pytest.approx(1.0)
    assert Lightcuts(clamp=False).clamp_radius(_Scene(), forest) == 0.0
    assert Lightcuts().reference().clamp_radius(_Scene(), forest) == Lightcuts().clamp_radius(_Scene(), forest)
    # the scene's size does not enter it, the VPLs' does
    big = build_forest(_lights(300_000, scale=100.0), None)
    assert Lightcuts().clamp_radius(_Scene(), big) == pytest.approx(100.0 * Lightcuts().clamp_radius(_Scene(), forest))


def test_few_vpls_share_the_lit_area_in_250():
    """With N < 400 * 250 VPLs the disc holds N / 250 of them: at most 1 / 250 of the lit surfaces."""
    lights = _lights(30_000)  # 20,000 indirect: 80 VPLs in the disc
    forest = build_forest(lights, None)
    s = vpl_spacing(lights["oriented"].position[lights["oriented"].indirect])
    r = Lightcuts().clamp_radius(_Scene(), forest)
    assert r == pytest.approx(np.sqrt(80.0) * s, rel=1e-12)
    assert np.pi * r * r == pytest.approx(16.0 / 250, rel=0.2)  # the 4 x 4 square's 1 / 250
    assert Lightcuts(clamp_vpls=50).clamp_radius(_Scene(), forest) == pytest.approx(np.sqrt(50.0) * s, rel=1e-12)


def test_configs_map_to_their_mode():
    cornell = ROOT / "configs" / "cornell.yaml"
    new = make_integrator(lightcuts.load_config(cornell))
    assert new.clamp_min_distance is None and new.clamp_vpls == 400
    old = make_integrator(lightcuts.load_config(cornell, **{"render.clamp.min_distance": 0.05}))  # an old config
    assert old.clamp_min_distance == 0.05
    assert make_integrator(lightcuts.load_config(cornell, **{"render.clamp.mode": "diagonal"})).clamp_min_distance == 0.05
    assert make_integrator(lightcuts.load_config(cornell, **{"render.clamp.vpls": 64})).clamp_vpls == 64
    with pytest.raises(lightcuts.LightcutsError, match="min_distance: not read in mode density"):
        lightcuts.load_config(cornell, **{"render.clamp": {"mode": "density", "min_distance": 0.1}})


@pytest.fixture(scope="module")
def spread(tmp_path_factory):
    """report.json and image of one room alone and of 3 x 3 rooms 135 m apart (about 400 m), the
    same VPLs per room, with the default clamp, the old one and none."""
    bench = _bench()
    out = {}
    for side, pitch in ((1, 0.0), (3, 135.0)):
        folder = tmp_path_factory.mktemp(f"rooms{side}")
        path = bench.spread_rooms(folder, side, pitch, 8000, 16)
        for label, over in (("default", {}), ("old", {"render.clamp.min_distance": 0.05}),
                            ("off", {"render.clamp.enabled": False})):
            r = lightcuts.render(lightcuts.load_config(path, **{"lights.direct.count": 256 * side * side, **over}))
            out[side, label] = r
    return out


def test_a_large_scene_keeps_the_radius_and_the_light_of_its_rooms(spread):
    one, large = spread[1, "default"].report, spread[3, "default"].report
    assert large["scene"]["diagonal"] > 380 and one["scene"]["diagonal"] < 25
    assert large["clamping"]["mode"] == "density" and large["clamping"]["vpls"] == 400
    # the VPLs' spacing is the same at both scales: the radii differ by the VPLs the disc holds alone
    held = {side: min(400, spread[side, "default"].report["lights_indirect"] / 250) for side in (1, 3)}
    assert held[1] < held[3] < 400
    assert large["clamping"]["radius"] == pytest.approx(one["clamping"]["radius"] * np.sqrt(held[3] / held[1]),
                                                        rel=0.1)
    lum = {k: float(r.image.mean()) for k, r in spread.items()}
    kept = {side: lum[side, "default"] / lum[side, "off"] for side in (1, 3)}
    assert kept[1] > 0.95 and kept[3] > 0.95 and large["clamping"]["clamped_energy_fraction"] < 0.05
    # the diagonal's radius (20 m, two rooms wide) takes a good part of the large scene's indirect light
    old = spread[3, "old"].report["clamping"]
    assert old["mode"] == "diagonal" and old["radius"] == pytest.approx(0.05 * large["scene"]["diagonal"])
    assert lum[3, "old"] / lum[3, "off"] < 0.9
