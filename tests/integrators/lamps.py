"""A floor under many small emitters, and the exact direct light there: the scenes of the light
samplers' tests (tests/integrators/test_path_lights.py) and demonstration
(benchmarks/bench_path_samplers.py).

The emitters lie in one plane above the floor, facing down, each in its own cell of a grid, so
nothing occludes or overlaps anything (overlapping coplanar emitters would be counted twice by
next-event estimation and once by a ray that hits them); the camera sits between the floor and the
emitters, looking down, and sees only the floor.
"""

from __future__ import annotations

import numpy as np

from lightcuts.integrators.camera import eye_rays
from lightcuts.integrators.driver import shadow_ray_offset
from lightcuts.scene.scene import Camera, Scene

#: Height of the emitters' plane above the floor (y = 0); the camera sits below it, looking down.
LAMP_HEIGHT = 1.0


def _down_triangles(corners, size):
    """(K, 3, 3) right triangles of legs ``size`` from the (K, 3) corners, facing down (normal -y)."""
    c = np.asarray(corners, float)
    return np.stack([c, c + [size, 0.0, 0.0], c + [0.0, 0.0, size]], axis=1)


def _cells(rng, n, radius, cell):
    """(n, 3) corners of distinct square cells of side ``cell`` in the plane y = LAMP_HEIGHT whose
    corner lies within ``radius`` (lo, hi) of the vertical axis: emitters drawn in them never overlap."""
    k = int(np.ceil(radius[1] / cell)) + 1
    i, j = np.meshgrid(np.arange(-k, k), np.arange(-k, k))
    corner = np.column_stack([i.ravel(), j.ravel()]) * cell
    r = np.hypot(corner[:, 0], corner[:, 1])
    pick = rng.choice(np.flatnonzero((r >= radius[0]) & (r <= radius[1])), n, replace=False)
    return np.column_stack([corner[pick, 0], np.full(n, LAMP_HEIGHT), corner[pick, 1]])


def lamp_scene(n_far=2000, n_near=6, far_power=10.0, far_radius=(80.0, 120.0), near_radius=(0.0, 1.0), size=0.2,
               seed=0, specular=0.0, exponent=0.0, width=16, height=16):
    """A floor (y = 0, albedo 0.5, optionally glossy) under small emitters in the plane y =
    LAMP_HEIGHT, all facing down, each a right triangle of legs ``0.9 * size`` in its own cell of
    side ``size``: ``n_near`` within ``near_radius`` of the axis (over the patch the camera sees)
    and ``n_far`` within ``far_radius`` (by default about 100 times farther), whose total power is
    ``far_power`` times the near ones'. Nothing occludes or overlaps anything (one emitter plane),
    and the camera, below the emitters, sees only the floor."""
    rng = np.random.default_rng(seed)
    lamps = _down_triangles(np.concatenate([_cells(rng, n_near, near_radius, size),
                                            _cells(rng, n_far, far_radius, size)]), 0.9 * size)
    le = rng.uniform(5.0, 15.0, (n_near + n_far, 3))
    if n_far:
        le[n_near:] *= far_power * le[:n_near].sum() / le[n_near:].sum()
    half = 150.0
    floor = np.array([[[-half, 0, -half], [-half, 0, half], [half, 0, half]],
                      [[-half, 0, -half], [half, 0, half], [half, 0, -half]]], float)
    tris = np.concatenate([lamps, floor])
    emission = np.zeros((len(tris), 3))
    emission[:len(lamps)] = le
    albedo = np.zeros((len(tris), 3))
    albedo[len(lamps):] = 0.5
    spec = np.zeros((len(tris), 3))
    spec[len(lamps):] = specular
    camera = Camera([0.0, 0.5, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 60.0, width, height)
    return Scene(tris.reshape(-1, 3), np.arange(3 * len(tris)).reshape(-1, 3), albedo=albedo, specular=spec,
                 exponent=exponent, emission=emission, camera=camera, name="lamps")


def form_factors(points, tri):
    """(P, K) point-to-triangle form factors (Lambert's formula, exact) from points on the floor
    (normal +y) to the (K, 3, 3) triangles above them."""
    total = np.zeros((len(points), len(tri)))
    unit = [None] * 3
    for i in range(3):
        v = tri[None, :, i, :] - points[:, None, :]
        unit[i] = v / np.sqrt(np.einsum("pkc,pkc->pk", v, v))[..., None]
    for i in range(3):
        a, b = unit[i], unit[(i + 1) % 3]
        g = np.cross(a, b)
        s = np.sqrt(np.einsum("pkc,pkc->pk", g, g))
        gy = g[..., 1]
        theta = np.arctan2(s, np.einsum("pkc,pkc->pk", a, b))
        total += theta * gy / np.maximum(s, 1e-300)
    return np.abs(total) / (2.0 * np.pi)


def direct_reference(scene, spp, seed):
    """(H, W, 3) the exact expectation of a max_depth 1 image of :func:`lamp_scene` given its eye
    rays: per eye ray the floor point it hits, the shading point above it (the shadow-ray offset)
    and the emitters' light reflected there, ``albedo * sum_t Le_t F_t``."""
    o, d = eye_rays(scene.camera, spp, seed)
    t = -o[..., 1] / d[..., 1]
    p = o + t[..., None] * d
    p[..., 1] += shadow_ray_offset(scene)
    lamps = scene.emitters
    f = form_factors(p.reshape(-1, 3), scene.triangles[lamps])
    rgb = 0.5 * f @ scene.emission[lamps]
    return rgb.reshape(*p.shape[:3], 3).mean(axis=2)
