"""The mask of pixels that see an emitter directly: the renderer's own camera rays, and every
triangle tested by brute force."""

import sys
from pathlib import Path

import numpy as np
import pytest

from lightcuts.accel import make_caster
from lightcuts.integrators.camera import eye_rays, hash_uniform
from lightcuts.integrators.primary import emitter_mask, film_directions
from lightcuts.scene.cornell import cornell_box
from lightcuts.scene.scene import Camera

sys.path.insert(0, str(Path(__file__).parents[1] / "accel"))
from brute import brute  # noqa: E402


@pytest.fixture(scope="module")
def scene():
    s = cornell_box()
    s.camera = Camera(s.camera.position, s.camera.look_at, s.camera.up, s.camera.fov, 40, 30)
    return s


def test_film_directions_are_the_renderers_eye_rays(scene):
    _, dirs = eye_rays(scene.camera, spp=1, seed=7)
    h, w = dirs.shape[:2]
    py, px = np.mgrid[0:h, 0:w]
    u = np.vectorize(lambda p: hash_uniform(7, p, 0, 0))(py * w + px)
    v = np.vectorize(lambda p: hash_uniform(7, p, 0, 1))(py * w + px)
    np.testing.assert_allclose(film_directions(scene.camera, px + u, py + v), dirs[:, :, 0], rtol=0, atol=1e-12)


def _brute_sees(scene, fx, fy, environment):
    d = film_directions(scene.camera, fx, fy).reshape(-1, 3)
    _, prim, _ = brute(scene.vertices, scene.faces, np.broadcast_to(scene.camera.position, d.shape), d)
    emits = scene.emission.max(axis=1) > 0
    return np.array([emits[p] if p >= 0 else environment for p in prim]).reshape(fx.shape)


def _expected(scene, window, environment):
    x0, y0, x1, y1 = window
    fy, fx = np.mgrid[y0:y1, x0:x1].astype(np.float64)
    out = np.zeros(fx.shape, bool)
    for dx, dy in ((0.5, 0.5), (0, 0), (1, 0), (0, 1), (1, 1)):
        out |= _brute_sees(scene, fx + dx, fy + dy, environment)
    return out


@pytest.mark.parametrize("crop", [None, (5, 0, 31, 12)])
def test_mask_is_any_of_the_centre_and_corner_rays_on_an_emitter(scene, crop):
    window = crop or (0, 0, 40, 30)
    with make_caster(scene) as caster:
        mask = emitter_mask(scene, caster, crop)
        sky = emitter_mask(scene, caster, crop, environment=True)
    expected = _expected(scene, window, False)
    assert mask.shape == expected.shape and (mask == expected).all()
    assert 0 < mask.sum() < mask.size // 10  # the light quad, and its edges
    # with an environment, the rays that leave the box (past its open front, at this 4:3 size) count too
    assert (sky == _expected(scene, window, True)).all() and (sky >= mask).all() and sky.sum() > mask.sum()


def test_environment_seen_through_an_open_box_is_masked(scene):
    import dataclasses

    keep = scene.vertices[scene.faces].min(axis=1)[:, 1] < 500  # drop the ceiling (and the light on it)
    open_box = dataclasses.replace(scene, faces=scene.faces[keep], albedo=scene.albedo[keep],
                                   specular=scene.specular[keep], exponent=scene.exponent[keep],
                                   emission=scene.emission[keep], _cache={})
    with make_caster(open_box) as caster:
        mask = emitter_mask(open_box, caster, environment=True)
        dark = emitter_mask(open_box, caster, environment=False)
    assert not dark.any()  # no emitter left
    assert (mask == _expected(open_box, (0, 0, 40, 30), True)).all()
    assert mask[0].all() and not mask[15, 10:30].any()  # the top row looks out, the middle sees the back wall


def test_an_emitter_smaller_than_a_pixel_on_its_centre_ray(scene):
    """A pixel whose centre ray alone meets an emitter (a speck a tenth of a pixel wide) is masked,
    its neighbours are not."""
    import dataclasses

    right, up, _ = scene.camera.frame()
    centre = scene.camera.position + 500.0 * film_directions(scene.camera, np.array(20.5), np.array(15.5))
    pixel = 500.0 * 2 * np.tan(np.radians(scene.camera.fov) / 2) / 30  # one pixel's width at that distance
    speck = np.array([centre - 0.05 * pixel * (right + up), centre + 0.05 * pixel * right,
                      centre + 0.05 * pixel * up])
    n = len(scene.vertices)
    with_speck = dataclasses.replace(
        scene, vertices=np.vstack([scene.vertices, speck]), faces=np.vstack([scene.faces, [[n, n + 1, n + 2]]]),
        albedo=np.vstack([scene.albedo, [[0, 0, 0]]]), specular=np.vstack([scene.specular, [[0, 0, 0]]]),
        exponent=np.append(scene.exponent, 0.0), emission=np.vstack([scene.emission, [[5, 5, 5]]]), _cache={})
    with make_caster(with_speck) as caster, make_caster(scene) as plain:
        mask = emitter_mask(with_speck, caster) & ~emitter_mask(scene, plain)
    assert mask[15, 20] and mask.sum() == 1
