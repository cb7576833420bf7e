"""The caster contract, over every registered caster (RAY_CASTERS.names(), so a new caster is covered
by registering it): closest hit and occlusion against brute force, ``with`` blocks and ``close()``,
and for kernel-callable casters a render through the kernels equal to Embree's; casters registered
at run time from outside; malformed kernel casters."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from lightcuts.accel import RAY_CASTERS, make_caster, register_caster
from lightcuts.accel.base import KernelCaster, RayCaster, kernel_caster_of
from lightcuts.accel.kernel_api import DeviceFunctions, register_device
from lightcuts.accel.packets import mark_lane_occluded, packet_get_ray
from lightcuts.accel.triangles import ray_frame, watertight_t
from lightcuts.errors import LightcutsError

from brute import brute

CASTERS = RAY_CASTERS.names()
KERNEL_CASTERS = [n for n in CASTERS if RAY_CASTERS.entry(n).trait("kernel_callable", False)]
CONFIG = "scene: {builtin: cornell}\nlights: {direct: {count: 16}}\ncamera: {resolution: [8, 8]}\n"


def _brute_force(vertices, faces, org, dirs):
    """Closest t (inf on a miss) and triangle (-1) over every triangle, Moeller-Trumbore in float64."""
    v0, v1, v2 = (vertices[faces[:, k]] for k in range(3))
    e1, e2 = v1 - v0, v2 - v0
    t_best = np.full(len(org), np.inf)
    prim = np.full(len(org), -1)
    for i in range(len(org)):
        p = np.cross(dirs[i], e2)
        det = np.einsum("ij,ij->i", e1, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = org[i] - v0
            u = np.einsum("ij,ij->i", s, p) * inv
            q = np.cross(s, e1)
            v = (q @ dirs[i]) * inv
            t = np.einsum("ij,ij->i", e2, q) * inv
        ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        if ok.any():
            j = np.flatnonzero(ok)[np.argmin(t[ok])]
            t_best[i], prim[i] = t[j], j
    return t_best, prim


@pytest.mark.parametrize("name", CASTERS)
def test_hits_and_occlusion_equal_brute_force(name):
    """Every caster: closest hit and occlusion equal a brute-force test over all triangles."""
    rng = np.random.default_rng(5)
    centres = rng.random((300, 1, 3))
    vertices = (centres + 0.1 * rng.standard_normal((300, 3, 3))).reshape(-1, 3).astype(np.float32).astype(float)
    faces = np.arange(900).reshape(300, 3)
    org = (rng.random((2000, 3)) * 1.4 - 0.2).astype(np.float32).astype(float)
    dirs = rng.standard_normal((2000, 3)).astype(np.float32).astype(float)
    entry = RAY_CASTERS.entry(name)
    caster = make_caster((vertices, faces), entry)
    t, prim = caster.intersect(org, dirs, 0.0, np.inf)
    t_ref, prim_ref = _brute_force(vertices, faces, org, dirs)
    # Rays whose two nearest hits are within float32 rounding may name either triangle.
    same = prim == prim_ref
    assert same.mean() > 0.995
    np.testing.assert_allclose(t[same & (prim >= 0)], t_ref[same & (prim >= 0)], rtol=1e-5)
    np.testing.assert_array_equal(np.isinf(t), prim_ref < 0)
    occluded = caster.occluded(org, dirs, 0.0, np.where(np.isfinite(t_ref), 0.5 * t_ref, 1.0))
    assert not occluded[np.isfinite(t_ref)].any()
    np.testing.assert_array_equal(caster.occluded(org, dirs, 0.0, np.inf), prim_ref >= 0)
    if entry.trait("kernel_callable"):
        assert kernel_caster_of(caster) is not None


# An outside kernel caster: brute force over every triangle with the watertight test, registered at
# run time. The render kernel's cache holds its specialisation under the kernel name below (edit its
# device functions: delete lightcuts/integrators/__pycache__/*.nb[ic]).

@njit(cache=True, error_model="numpy")
def _brute_hit(data, ox, oy, oz, dx, dy, dz, tnear, tfar, any_hit):
    tri = data[1]
    kx, ky, kz, sx, sy, sz = ray_frame(dx, dy, dz)
    best_t, best = tfar, np.int64(-1)
    if not tfar >= tnear:
        return np.inf, best
    for f in range(tri.shape[0]):
        t = watertight_t(tri, f, ox, oy, oz, kx, ky, kz, sx, sy, sz)
        if t != np.inf and tnear <= t <= best_t and (best < 0 or t < best_t):
            best_t, best = t, np.int64(f)
            if any_hit:
                break
    return (best_t, best) if best >= 0 else (np.inf, best)


@njit(cache=True)
def _brute_intersect(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar):
    return _brute_hit(data, ox, oy, oz, dx, dy, dz, tnear, tfar, False)


@njit(cache=True)
def _brute_occluded(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar):
    return _brute_hit(data, ox, oy, oz, dx, dy, dz, tnear, tfar, True)[1] >= 0


@njit(cache=True)
def _brute_packet(data, scratch, pk, width, n):
    for lane in range(n):
        ox, oy, oz, dx, dy, dz, tnear, tfar = packet_get_ray(pk, width, lane)
        if _brute_hit(data, ox, oy, oz, dx, dy, dz, tnear, tfar, True)[1] >= 0:
            mark_lane_occluded(pk, width, lane)


@njit(cache=True)
def _brute_scratch(data):
    return np.empty(0)


#: The outside caster's device functions (kernel name ``tests.brute_force``).
_BRUTE_DEVICE = DeviceFunctions("tests.brute_force", _brute_intersect, _brute_occluded, _brute_packet, _brute_scratch)


class _BruteCaster:
    """Kernel-callable only through lightcuts.accel.kernel_api: no Embree, no BVH."""

    def __init__(self, vertices, faces):
        v = np.asarray(vertices, np.float32).astype(np.float64)
        tri = np.ascontiguousarray(v[np.asarray(faces)].reshape(-1, 9))
        self.kernel_caster = KernelCaster((_BRUTE_DEVICE.tag, tri), 3)


def test_a_caster_registered_at_run_time_renders(tmp_path, scratch_registries):
    """Registered from outside, it renders the image the bvh-sah caster renders (the same watertight
    test in float64), and the plan step accepts it for rendering."""
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.config import load_config
    from lightcuts.lights.direct import direct_lights
    from lightcuts.integrators.lightcut import render_image
    from lightcuts.scene.cornell import cornell_box
    from lightcuts.scene.scene import Camera

    register_caster("brute-force", _BruteCaster, device=_BRUTE_DEVICE)
    scene = cornell_box()
    c = scene.camera
    camera = Camera(c.position, c.look_at, c.up, c.fov, 12, 12)
    lights = {"oriented": direct_lights(scene, 32, seed=1)}
    outside = render_image(scene, make_caster(scene, "brute-force"), lights, {}, camera=camera, reference=True)
    bvh = render_image(scene, make_caster(scene, "bvh-sah"), lights, {}, camera=camera, reference=True)
    assert outside.image.max() > 0 and outside.shadow_rays > 0
    assert outside.image.tobytes() == bvh.image.tobytes()
    (tmp_path / "run.yaml").write_text(CONFIG)
    cfg = load_config(tmp_path / "run.yaml", ["render.ray_caster=brute-force"])
    assert plan_run(cfg, render=True).caster.name == "brute-force"


@pytest.mark.parametrize("kernel_caster, message", [
    (((np.zeros(3),), 8), "data must be a tuple starting with a tag"),
    (((np.zeros(0, np.dtype([("no.such.caster", np.uint8)])),), 8), "data must be a tuple starting with a tag"),
    ("not a tuple", "is not a KernelCaster"),
])
def test_a_malformed_kernel_caster_is_one_line_error(kernel_caster, message):
    from lightcuts.integrators.lightcut import render_image
    from lightcuts.scene.cornell import cornell_box

    class Bad:
        pass

    bad = Bad()
    bad.kernel_caster = kernel_caster
    with pytest.raises(LightcutsError, match=f"^render.ray_caster: Bad.kernel_caster.*{message}"):
        render_image(cornell_box(), bad, {}, {}, crop=(0, 0, 1, 1))
    register_device(_BRUTE_DEVICE)
    tag = _BRUTE_DEVICE.tag
    bad.kernel_caster = ((tag, np.zeros((0, 9))), 9)
    with pytest.raises(LightcutsError, match="width 9 must be an integer from 1 to 8"):
        render_image(cornell_box(), bad, {}, {}, crop=(0, 0, 1, 1))


def _mesh():
    rng = np.random.default_rng(6)
    centres = rng.random((200, 1, 3))
    v = (centres + 0.1 * rng.standard_normal((200, 3, 3))).reshape(-1, 3).astype(np.float32).astype(float)
    return v, np.arange(600).reshape(200, 3)


@pytest.mark.parametrize("name", CASTERS)
def test_with_block_and_close(name):
    """Every caster is a RayCaster that works in a ``with`` block (which returns it and closes it on
    leaving, also after an exception) and whose close() may be called again."""
    v, f = _mesh()
    org, dirs = np.full((50, 3), 0.5), np.random.default_rng(1).standard_normal((50, 3))
    caster = make_caster((v, f), name)
    assert isinstance(caster, RayCaster)
    expected = caster.intersect(org, dirs)
    closed = []
    original_close = caster.close
    caster.close = lambda: (closed.append(True), original_close())[1]
    with caster as c:
        assert c is caster
        t, p = c.intersect(org, dirs)
        assert np.array_equal(p, expected[1]) and (p >= 0).any()
    assert closed == [True]
    caster.close()
    caster.close()
    with pytest.raises(RuntimeError, match="inside"):
        with make_caster((v, f), name) as c:
            raise RuntimeError("inside")


@pytest.fixture(scope="module")
def cornell():
    """The Cornell box at 24 x 24 with the same lights and tree for every caster, and Embree's image."""
    from lightcuts.lights.direct import direct_lights
    from lightcuts.lights.indirect import indirect_lights
    from lightcuts.lights.lightset import LightSet
    from lightcuts.integrators.lightcut import render_image
    from lightcuts.scene.cornell import cornell_box
    from lightcuts.scene.scene import Camera
    from lightcuts.trees.build import build_tree

    scene = cornell_box()
    c = scene.camera
    camera = Camera(c.position, c.look_at, c.up, c.fov, 24, 24)
    with make_caster(scene, "embree") as embree:
        lights = LightSet.concatenate([direct_lights(scene, 64, seed=1), indirect_lights(scene, embree, 300, seed=2)])
        lights, trees = {"oriented": lights}, {"oriented": build_tree(lights, "divisive-6d", seed=3)}

        def render(name):
            with make_caster(scene, name) as caster:
                return render_image(scene, caster, lights, trees, camera=camera)

        return scene, render, render("embree"), render("bvh-sah")


@pytest.mark.parametrize("name", KERNEL_CASTERS)
def test_render_through_the_kernels_equals_embree(name, cornell):
    """The Cornell box, 24 x 24, the same lights and tree. Embree's float32 t leaves a hit point off
    its surface by rounding, the float64 watertight test does not: a receiver coplanar with lights
    (VPLs on the same wall) then sees them at a cosine of exactly 0 or of +-rounding, which can turn
    a node's bound from zero to tiny and change the cut's size (measured for bvh-sah: 21 of 576
    pixels). Elsewhere the images agree to rounding (3.7e-6 relative at most, measured). Both are
    bounded. A caster whose hits equal the watertight brute force bit for bit (the BVHs, the grids)
    renders bvh-sah's image bit for bit."""
    scene, render, a, bvh = cornell
    b = render(name)
    cut_differs = a.cut_size != b.cut_size
    assert cut_differs.mean() < 0.05
    rel = np.abs(a.image - b.image).max(axis=2) / np.maximum(a.image.max(axis=2), 1e-6)
    assert (rel[~cut_differs] > 1e-4).mean() < 0.01
    assert abs(float(a.cut_size.mean()) - float(b.cut_size.mean())) < 0.02 * float(a.cut_size.mean())
    assert abs(float(a.image.mean()) - float(b.image.mean())) < 1e-3 * float(a.image.mean())
    rng = np.random.default_rng(7)
    org = scene.camera.position + 0.01 * rng.standard_normal((2000, 3))
    dirs = rng.standard_normal((2000, 3))
    with make_caster(scene, name) as caster:
        t = caster.intersect(org, dirs)[0]
    if np.array_equal(t, brute(scene.vertices, scene.faces, org, dirs)[0]):
        assert b.image.tobytes() == bvh.image.tobytes() and np.array_equal(b.cut_size, bvh.cut_size)


def test_the_exact_casters_are_the_numba_ones(cornell):
    """The bit-for-bit branch above is taken: the BVH and grid casters hit as brute force does."""
    scene = cornell[0]
    rng = np.random.default_rng(7)
    org = scene.camera.position + 0.01 * rng.standard_normal((2000, 3))
    dirs = rng.standard_normal((2000, 3))
    t_ref = brute(scene.vertices, scene.faces, org, dirs)[0]
    exact = []
    for name in KERNEL_CASTERS:
        with make_caster(scene, name) as caster:
            if np.array_equal(caster.intersect(org, dirs)[0], t_ref):
                exact.append(name)
    assert {"bvh-sah", "grid", "hug", "octree", "recursive-grid"} <= set(exact) and "embree" not in exact
