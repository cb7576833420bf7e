"""The eye-ray start every integrator shares (lightcuts.integrators.eye): an emitter's front shows its
emitted radiance, its back and a miss (without an environment map) are black, exactly, whatever
the integrator."""

from __future__ import annotations

import numpy as np
import pytest

from lightcuts.accel import make_caster
from lightcuts.integrators.camera import eye_rays
from lightcuts.integrators.registry import INTEGRATORS
from lightcuts.scene.scene import Camera, Scene

LE = 2.0


def emitter_quad(facing_camera: bool) -> Scene:
    """A black emitting square (|x|, |y| <= 1 at z = 0, radiance LE) seen from z = 3: its front
    faces the camera or away from it; rays past its edges miss."""
    vertices = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    faces = np.array([[0, 1, 2], [0, 2, 3]]) if facing_camera else np.array([[0, 2, 1], [0, 3, 2]])
    camera = Camera([0.0, 0.0, 3.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 50.0, 16, 12)
    return Scene(vertices, faces, albedo=0.0, specular=0.0, exponent=0.0, emission=np.full((2, 3), LE),
                 camera=camera)


@pytest.mark.parametrize("name", INTEGRATORS.names())
def test_every_integrator_sees_an_emitters_front_and_black_behind_it(name):
    """Per eye ray (one per pixel): LE where it hits the square's front, 0 where it hits its back
    or misses, as the ray caster finds the hits of the renderer's own eye rays."""
    for facing in (True, False):
        scene = emitter_quad(facing)
        integ = INTEGRATORS.get(name)(spp=1)
        with make_caster(scene, "embree") as caster:
            result = integ.render(scene, caster, {}, {}, seed=5)
            o, d = eye_rays(scene.camera, spp=1, seed=5)
            _, prim = caster.intersect(o.reshape(-1, 3), d.reshape(-1, 3), 0.0, np.inf)
        hit = (prim >= 0).reshape(12, 16)
        assert 0 < hit.sum() < hit.size
        expected = np.where(hit[..., None] & facing, LE, 0.0).repeat(3, axis=2).astype(np.float32)
        assert result.image.tobytes() == expected.tobytes(), (name, facing)
