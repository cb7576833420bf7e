"""Multidimensional lightcuts: pair bounds, gather trees, the product cut against the lightcut and
the brute-force sum over the same gather points, determinism and the thin lens.

A small glossy Cornell box (24 x 24 pixels, about 360 direct and indirect lights).
"""

import numpy as np
import pytest

from lightcuts.accel import make_caster
from lightcuts.errors import LightcutsError
from lightcuts.lights.direct import direct_lights
from lightcuts.lights.indirect import indirect_lights
from lightcuts.lights.lightset import LUMINANCE, LightSet
from lightcuts.integrators.bounds import DIRECTIONAL, ORIENTED
from lightcuts.integrators.camera import camera_params, eye_ray, lens_ray, strata
from lightcuts.integrators.forest import LF_POS, NK_LEFT, NK_REP, NK_RIGHT, build_forest
from lightcuts.integrators.lightcut import render_image
from lightcuts.integrators.multidim import render_multidimensional, render_multidimensional_reference
from lightcuts.integrators.multidim.gather import (GP_EXP, GP_NRM, GP_POS, GP_RD, GP_REFL, GP_RS, GP_W, GP_WIDTH)
from lightcuts.integrators.multidim.gather_tree import (GK_LEFT, GK_REP, GK_RIGHT, GN_EMAX, GN_EMIN, GN_HI, GN_LO,
                                                   GN_NAX, GN_NCOS, GN_RAX, GN_RCOS, GN_RD, GN_RS, GN_MIXED, GN_W,
                                                   GN_WIDTH, GK_FIRST, GK_LAST, GK_WIDTH,
                                                   build_gather_tree, gather_representatives)
from lightcuts.integrators.multidim.pair_bounds import pair_bound
from lightcuts.integrators.multidim.product_cut import light_representatives, sibling_column
from lightcuts.integrators.shading import unshadowed_contribution
from lightcuts.scene.cornell import cornell_box
from lightcuts.scene.scene import Camera
from lightcuts.trees.build import build_tree
from tests.conftest import random_lights, unit

SIZE = 24


@pytest.fixture(scope="module")
def cornell():
    scene = cornell_box({"floor": {"specular": [0.3, 0.3, 0.3], "exponent": 40.0}})
    c = scene.camera
    camera = Camera(c.position, c.look_at, c.up, c.fov, SIZE, SIZE)
    caster = make_caster(scene, "embree")
    lights = LightSet.concatenate([direct_lights(scene, 64, seed=1), indirect_lights(scene, caster, 300, seed=2)])
    tree = build_tree(lights, "divisive-6d", seed=3)
    yield scene, caster, camera, {"oriented": lights}, {"oriented": tree}
    caster.close()


def luminance(image):
    return image.astype(np.float64) @ LUMINANCE


def random_gather_points(n, rng, spread=0.3):
    """n gather points around the origin: random normals, mirror directions and (glossy) materials."""
    gp = np.zeros((n, GP_WIDTH))
    gp[:, GP_POS:GP_POS + 3] = rng.random((n, 3)) * spread - spread / 2
    base = unit(rng.normal(size=3))
    gp[:, GP_NRM:GP_NRM + 3] = unit(base + rng.normal(size=(n, 3)) * rng.choice([0.05, 1.0]))
    gp[:, GP_REFL:GP_REFL + 3] = unit(rng.normal(size=(n, 3)) * 0.3 + base)
    gp[:, GP_RD:GP_RD + 3] = rng.random((n, 3))
    gp[:, GP_RS:GP_RS + 3] = rng.random((n, 3)) * (rng.random((n, 1)) < 0.5)
    gp[:, GP_EXP] = rng.choice([0.0, 1.0, 10.0, 80.0], n)
    gp[:, GP_W] = rng.random(n) + 0.1
    return gp


def build(gp, seed=0):
    n = len(gp)
    gn = np.zeros((2 * n, GN_WIDTH))
    gk = np.zeros((2 * n, GK_WIDTH), np.int64)
    idx = np.zeros(n, np.int64)
    root = build_gather_tree(gp, n, gn, gk, idx, np.zeros((2 * n, 3), np.int64), seed, 5)
    return gn, gk, root, idx


def subtree(children, k):
    """Ids of the leaves below node k; children(k) -> (left, right) or None at a leaf."""
    out, stack = [], [k]
    while stack:
        k = stack.pop()
        c = children(k)
        if c is None:
            out.append(k)
        else:
            stack.extend(c)
    return out


@pytest.mark.parametrize("light_type", ["oriented", "omni", "directional"])
@pytest.mark.parametrize("seed", range(4))
def test_pair_bound_holds_for_every_pair_it_covers(light_type, seed):
    rng = np.random.default_rng(seed)
    ls = random_lights(24, light_type, seed=seed)
    ls = LightSet(ls.position + (0.0 if light_type == "directional" else 0.4), ls.normal, ls.intensity, light_type,
                  indirect=rng.random(24) < 0.7)
    forest = build_forest({light_type: ls}, {light_type: build_tree(ls, "divisive-6d", seed=seed)})
    nk = forest.node_k
    gp = random_gather_points(12, rng)
    gn, gk, root, _ = build(gp, seed)
    clamp_d2 = 0.01 if seed % 2 else 0.0
    typ = {"oriented": ORIENTED, "omni": 0, "directional": DIRECTIONAL}[light_type]
    checked = 0
    for g in range(2 * len(gp) - 1):
        points = subtree(lambda k: None if gk[k, GK_LEFT] < 0 else (gk[k, GK_LEFT], gk[k, GK_RIGHT]), g)
        for k in range(len(nk)):
            leaves = subtree(lambda k: None if nk[k, NK_LEFT] < 0 else (nk[k, NK_LEFT], nk[k, NK_RIGHT]), k)
            if len(points) == 1 and len(leaves) == 1:
                continue  # an exact pair: bound 0
            b = np.array(pair_bound(gp, gn, gk, g, forest.node_b, forest.node_bi, k, nk[k, NK_LEFT] < 0, clamp_d2))
            total = np.zeros(3)
            for i in points:
                for leaf in leaves:
                    j = nk[leaf, NK_REP]
                    c2 = clamp_d2 if ls.indirect[j] else 0.0
                    p, nl = forest.light_f[j, LF_POS:LF_POS + 3], forest.light_f[j, 3:6]
                    total += gp[i, GP_W] * np.array(unshadowed_contribution(
                        typ, *p, *nl, *forest.light_i[j], *gp[i, GP_POS:GP_POS + 3], *gp[i, GP_NRM:GP_NRM + 3],
                        *gp[i, GP_REFL:GP_REFL + 3], *gp[i, GP_RD:GP_RD + 3], *gp[i, GP_RS:GP_RS + 3], gp[i, GP_EXP],
                        c2))
            # The summed contribution (hence every single one) is below the bound; float32 rounding of
            # the node's intensity (relative 6e-8) is the only slack allowed.
            assert np.all(total <= b * (1 + 1e-6) + 1e-300), (g, k, total, b)
            checked += total.sum() > 0
    assert checked > 50


@pytest.mark.parametrize("n", [1, 2, 3, 7, 16, 33])
def test_gather_trees_are_valid(n):
    rng = np.random.default_rng(n)
    gp = random_gather_points(n, rng)
    if n > 3:
        gp[1, :] = gp[0, :]  # two points on one spot
    gn, gk, root, idx = build(gp)
    greps = np.full((2 * n, 16), -1, np.int64)
    gather_representatives(gn, gk, idx, n, 0, 5, greps)
    assert np.array_equal(greps[:n], np.repeat(np.arange(n)[:, None], 16, 1))
    # Stratified: the root's columns hold each of its points 16 / n times (rounded either way),
    # starting from its own representative.
    counts = np.bincount(greps[root], minlength=n)
    assert counts.max() - counts.min() <= 1 and greps[root, 0] == gk[root, GK_REP]
    assert root == (0 if n == 1 else n)
    children = lambda k: None if gk[k, GK_LEFT] < 0 else (gk[k, GK_LEFT], gk[k, GK_RIGHT])  # noqa: E731
    assert sorted(subtree(children, root)) == list(range(n))  # every point exactly once
    for k in range(n, 2 * n - 1):
        pts = subtree(children, k)
        a, b = children(k)
        for c in (a, b):
            assert np.all(gn[k, GN_LO:GN_LO + 3] <= gn[c, GN_LO:GN_LO + 3])
            assert np.all(gn[k, GN_HI:GN_HI + 3] >= gn[c, GN_HI:GN_HI + 3])
            assert np.all(gn[k, GN_RD:GN_RD + 3] >= gn[c, GN_RD:GN_RD + 3])
            assert np.all(gn[k, GN_RS:GN_RS + 3] >= gn[c, GN_RS:GN_RS + 3])
        assert np.isclose(gn[k, GN_W], gn[a, GN_W] + gn[b, GN_W])
        assert np.isclose(gn[k, GN_W], gp[pts, GP_W].sum())
        assert gn[k, GN_EMIN] == gp[pts, GP_EXP].min() and gn[k, GN_EMAX] == gp[pts, GP_EXP].max()
        assert gk[k, GK_REP] in pts and gk[k, GK_REP] in (gk[a, GK_REP], gk[b, GK_REP])
        same = gp[pts][:, [GP_NRM, GP_NRM + 1, GP_NRM + 2, GP_RD, GP_RD + 1, GP_RD + 2]]
        assert (gn[k, GN_MIXED] == 0.0) == bool(np.all(same == same[0]))
        # The range of idx that lists the node's points (the pair estimate sums their materials).
        assert sorted(idx[gk[k, GK_FIRST]:gk[k, GK_LAST]]) == sorted(pts)
        # Gather representatives: each column a point of the node that one child also has in that
        # column (they nest), and every point of the node in some column while there are enough.
        for r in range(16):
            assert greps[k, r] in pts and greps[k, r] in (greps[a, r], greps[b, r])
        if n <= 16:
            assert set(greps[k]) == set(pts)
        # The cones hold every normal and every mirror direction below them.
        for ax, cs, col in ((GN_NAX, GN_NCOS, GP_NRM), (GN_RAX, GN_RCOS, GP_REFL)):
            cos = gp[pts, col:col + 3] @ gn[k, ax:ax + 3]
            assert np.all(cos >= gn[k, cs] - 1e-12), (cos.min(), gn[k, cs])


def test_light_representatives_are_lights_of_their_node_and_nest(cornell):
    _, _, _, lights, trees = cornell
    forest = build_forest(lights, trees)
    nk = forest.node_k
    lreps = np.zeros((len(nk), 4), np.int64)
    light_representatives(forest.node_f, nk, 4, 0, lreps)
    assert np.array_equal(lreps[:, 0], nk[:, NK_REP])
    assert len(np.unique(lreps[0])) > 1  # the root's columns differ
    for k in range(0, len(nk), 7):
        if nk[k, NK_LEFT] >= 0:
            leaves = subtree(lambda k: None if nk[k, NK_LEFT] < 0 else (nk[k, NK_LEFT], nk[k, NK_RIGHT]), k)
            assert set(lreps[k]) <= set(nk[leaves, NK_REP])
            assert all(lreps[k, r] in (lreps[nk[k, NK_LEFT], r], lreps[nk[k, NK_RIGHT], r]) for r in range(4))


def test_one_gather_point_is_the_lightcut(cornell):
    scene, caster, camera, lights, trees = cornell
    one = render_image(scene, caster, lights, trees, camera=camera, eps=0.02)
    md = render_multidimensional(scene, caster, lights, trees, camera=camera, spp=1, eps=0.02)
    a, b = luminance(md.image), luminance(one.image)
    assert np.all(np.abs(a - b) <= 0.02 * b + 1e-12)
    # In fact the same cut: one gather point leaves only the light side to refine.
    np.testing.assert_allclose(md.image, one.image, rtol=1e-6)
    np.testing.assert_array_equal(md.cut_size, one.cut_size)


@pytest.mark.parametrize("gather_reps", [1, 4])
def test_refining_everything_gives_the_brute_force_sum(cornell, gather_reps):
    scene, caster, camera, lights, trees = cornell
    ref = render_multidimensional_reference(scene, caster, lights, camera=camera, spp=4, seed=3)
    full = render_multidimensional(scene, caster, lights, trees, camera=camera, spp=4, seed=3, eps=0.0,
                                   max_cut=10 ** 5, gather_representatives=gather_reps)
    n = len(lights["oriented"])
    assert ref.cut_size.max() == 4 * n and full.cut_size.max() > n
    np.testing.assert_allclose(full.image, ref.image, rtol=1e-5, atol=1e-6 * ref.image.max())
    # With a coarse eps the cut is far smaller and still close.
    md = render_multidimensional(scene, caster, lights, trees, camera=camera, spp=4, seed=3, eps=0.02,
                                 gather_representatives=gather_reps)
    a, b = luminance(md.image), luminance(ref.image)
    keep = b > 1e-3 * b.max()
    assert np.median(np.abs(a - b)[keep] / b[keep]) < 0.03
    assert md.cut_size.mean() < 0.2 * 4 * n


def test_gather_clusters_of_unlike_albedo_estimate_their_mean():
    # A floor of stripes far narrower than a pixel, albedo 0.9 and 0.05 in turn, under lights
    # above it: every gather cluster mixes both albedos, and the pair estimate uses the cluster's
    # mean albedo, so a coarse cut is close to the sum over all pairs. (With the representative
    # point's own albedo the image is 0.05 / 0.475 or 0.9 / 0.475 of it, pixel by pixel.)
    from lightcuts.scene.scene import Scene

    k = 400
    x = np.linspace(-1.0, 1.0, k + 1)
    v = np.concatenate([np.stack([x, np.zeros_like(x), np.full_like(x, -1.0)], 1),
                        np.stack([x, np.zeros_like(x), np.full_like(x, 1.0)], 1)])
    faces = np.concatenate([[[i, k + 1 + i, i + 1], [i + 1, k + 1 + i, k + 2 + i]] for i in range(k)])
    albedo = np.repeat(np.where(np.arange(k) % 2 == 0, 0.9, 0.05), 2)[:, None].repeat(3, 1)
    zero = np.zeros((len(faces), 3))
    camera = Camera([0.0, 2.0, 0.01], [0.0, 0.0, 0.0], [0, 0, -1], 40.0, 12, 12)
    scene = Scene(v, faces.astype(np.int32), albedo, zero, np.zeros(len(faces)), zero, camera)
    rng = np.random.default_rng(0)
    pos = np.stack([rng.uniform(-1, 1, 300), rng.uniform(0.5, 1.5, 300), rng.uniform(-1, 1, 300)], 1)
    lights = LightSet(pos, np.tile([0.0, -1.0, 0.0], (300, 1)), rng.random((300, 3)) + 0.5, "oriented")
    trees = {"oriented": build_tree(lights, "divisive-6d", seed=1)}
    with make_caster(scene, "embree") as caster:
        ref = render_multidimensional_reference(scene, caster, {"oriented": lights}, spp=16, clamp=False)
        md = render_multidimensional(scene, caster, {"oriented": lights}, trees, spp=16, eps=0.02, clamp=False)
    a, b = luminance(md.image), luminance(ref.image)
    assert md.cut_size.mean() < 0.1 * 16 * 300
    assert np.max(np.abs(a - b) / b) < 0.05


class _OneRayPackets:
    """A caster whose shadow-ray packets hold one ray: the product cut then casts each ray as its
    pair enters the cut, before anything else happens (no ray ever waits)."""

    def __init__(self, caster):
        self.kernel_caster = caster.kernel_caster._replace(width=1)


@pytest.mark.parametrize("gather_reps", [1, 16])
def test_deferred_visibility_gives_the_cut_of_rays_cast_at_once(cornell, gather_reps):
    """Shadow rays wait in packets (docs/math.md, "Deferred visibility"), and the cut, its estimate
    and the shadow rays are those of casting each ray at once (packets of one)."""
    scene, caster, camera, lights, trees = cornell
    kwargs = dict(camera=camera, spp=4, seed=3, gather_representatives=gather_reps, aperture=20.0,
                  focus_distance=800.0)
    with make_caster(scene, "bvh-sah") as bvh:
        assert bvh.kernel_caster.width == 8
        packets = render_multidimensional(scene, bvh, lights, trees, **kwargs)
        at_once = render_multidimensional(scene, _OneRayPackets(bvh), lights, trees, **kwargs)
    np.testing.assert_array_equal(packets.cut_size, at_once.cut_size)
    a, b = luminance(packets.image), luminance(at_once.image)
    assert np.all(np.abs(a - b) <= 0.02 * b + 1e-12)  # within eps, and in fact to rounding
    np.testing.assert_allclose(packets.image, at_once.image, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(packets.shadow_rays_image, at_once.shadow_rays_image)
    # Shadowed pairs exist, so the packets' answers mattered.
    unshadowed = render_multidimensional(scene, caster, lights, trees, visibility=False, **kwargs)
    assert luminance(unshadowed.image).sum() > 1.05 * a.sum()


def _fins_scene(k=200, height=0.01):
    """A 2 x 2 m floor (y = 0) with k - 1 fins across it, 1 cm high and 1 cm apart (planes x = const),
    seen from 2 m above: a pixel spans about 12 gaps."""
    from lightcuts.scene.scene import Scene

    v = [[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]]
    f = [[0, 2, 1], [0, 3, 2]]
    for x in np.linspace(-1.0, 1.0, k + 1)[1:-1]:
        b = len(v)
        v += [[x, 0.0, -1.0], [x, 0.0, 1.0], [x, height, 1.0], [x, height, -1.0]]
        f += [[b, b + 1, b + 2], [b, b + 2, b + 3]]
    n = len(f)
    camera = Camera([0.0, 2.0, 0.01], [0.0, 0.0, 0.0], [0, 0, -1], 40.0, 12, 12)
    return Scene(np.array(v), np.array(f, np.int32), np.full((n, 3), 0.6), np.zeros((n, 3)), np.zeros(n),
                 np.zeros((n, 3)), camera)


def test_gather_nodes_whose_points_see_the_lights_differently_are_split():
    # Lights 63 degrees up on the +x side: each fin shades half of the gap behind it, so about half of
    # every pixel's gather points see none of the lights, the other half all of them, and every pair
    # that shades a gather cluster with one point's visibility is wrong by the same sign. The
    # cluster's points taken in turn (stratified columns) and the check that splits a cluster whose
    # points disagree bring the pixels to the brute-force sum (without the check: median 2.8%, max
    # 15%; with columns drawn at random and no check: 6.7%, 29%).
    scene = _fins_scene()
    rng = np.random.default_rng(0)
    up = np.arctan(2.0)
    pos = np.stack([3 * np.cos(up) + rng.uniform(-0.05, 0.05, 64), np.full(64, 3 * np.sin(up)),
                    rng.uniform(-1.0, 1.0, 64)], 1)
    lights = {"oriented": LightSet(pos, -unit(pos), rng.random((64, 3)) + 0.5, "oriented")}
    trees = {"oriented": build_tree(lights["oriented"], "divisive-6d", seed=1)}
    with make_caster(scene, "embree") as caster:
        ref = render_multidimensional_reference(scene, caster, lights, spp=16, clamp=False)
        unshadowed = render_multidimensional_reference(scene, caster, lights, spp=16, clamp=False, visibility=False)
        md = render_multidimensional(scene, caster, lights, trees, spp=16, eps=0.02, clamp=False)
    a, b = luminance(md.image), luminance(ref.image)
    assert 0.3 < 1 - b.sum() / luminance(unshadowed.image).sum() < 0.6  # about half the light is shadowed
    err = np.abs(a - b) / b
    assert np.median(err) < 0.015 and err.max() < 0.1


def test_sibling_columns_cover_every_column_below_a_pair():
    # Refining a pair b levels on the light side, the child that keeps the representative light keeps
    # the column and the other takes the sibling column: the 2^b pairs below use each column once.
    for g_count, bits in ((16, 4), (4, 2), (6, 2), (1, 0)):
        for col in range(g_count):
            for depth in range(3):
                cols = [col]
                for d in range(depth, depth + bits):
                    cols = cols + [sibling_column(c, d, g_count) for c in cols]
                expected = sorted({col ^ m for m in range(2 ** bits)})
                if max(expected) < g_count:
                    assert sorted(cols) == expected
                assert all(0 <= c < g_count for c in cols)


def test_max_cut_counts_pairs_per_gather_point(cornell):
    # render.max_cut is the budget per eye ray for both integrators: a pixel of G gather points may
    # hold max_cut * G pairs.
    scene, caster, camera, lights, trees = cornell
    md = render_multidimensional(scene, caster, lights, trees, camera=camera, spp=4, eps=0.0, max_cut=5)
    assert md.cut_size.max() == 20


@pytest.mark.parametrize("gather_reps", [1, 4])
def test_same_image_on_any_thread_count_and_for_listed_pixels(cornell, thread_counts, gather_reps):
    scene, caster, camera, lights, trees = cornell
    (n1, n2), num_threads = thread_counts
    kwargs = dict(camera=camera, spp=4, seed=7, aperture=20.0, focus_distance=800.0,
                  gather_representatives=gather_reps)
    with num_threads(n1):
        one = render_multidimensional(scene, caster, lights, trees, **kwargs)
    with num_threads(n2):
        two = render_multidimensional(scene, caster, lights, trees, **kwargs)
    assert one.image.tobytes() == two.image.tobytes() and one.cut_size.tobytes() == two.cut_size.tobytes()
    pix = np.array([[23, 0], [3, 9], [20, 13]])
    some = render_multidimensional(scene, caster, lights, trees, pixels=pix, **kwargs)
    assert some.image[:, 0].tobytes() == np.ascontiguousarray(one.image[pix[:, 1], pix[:, 0]]).tobytes()
    other = render_multidimensional(scene, caster, lights, trees, **dict(kwargs, seed=8))
    assert other.image.tobytes() != one.image.tobytes()


def test_aperture_zero_is_the_pinhole_and_lens_rays_meet_in_the_plane_of_focus(cornell):
    scene, caster, camera, lights, trees = cornell
    cam = camera_params(camera)
    sx, sy = strata(16)
    focus = 700.0
    fwd = cam[9:12]
    for px, py, s in [(0, 0, 0), (5, 17, 3), (23, 23, 15)]:
        d = eye_ray(cam, 4, px, py, s, sx, sy)
        assert lens_ray(cam, 4, px, py, s, sx, sy, 0.0, focus) == (*cam[0:3], *d)
        o2 = np.array(lens_ray(cam, 4, px, py, s, sx, sy, 30.0, focus))
        assert not np.allclose(o2[:3], cam[0:3])
        pin = cam[0:3] + np.array(d) * focus / np.dot(d, fwd)
        hit = o2[:3] + o2[3:] * (focus - np.dot(o2[:3] - cam[0:3], fwd)) / np.dot(o2[3:], fwd)
        np.testing.assert_allclose(hit, pin, atol=1e-6)
    pinhole = render_multidimensional(scene, caster, lights, trees, camera=camera, spp=4)
    zero = render_multidimensional(scene, caster, lights, trees, camera=camera, spp=4, aperture=0.0,
                                   focus_distance=123.0)
    blurred = render_multidimensional(scene, caster, lights, trees, camera=camera, spp=4, aperture=40.0,
                                      focus_distance=123.0)
    assert zero.image.tobytes() == pinhole.image.tobytes()
    assert not np.allclose(blurred.image, pinhole.image)


def test_bad_inputs_raise_one_line_errors(cornell):
    from lightcuts.errors import LightcutsError

    scene, caster, camera, lights, trees = cornell
    for kwargs, key in [(dict(aperture=-1.0), "camera.aperture"), (dict(focus_distance=0.0), "camera.focus_distance"),
                        (dict(representatives=0), "render.integrator.representatives"), (dict(spp=0), "render.spp")]:
        with pytest.raises(LightcutsError, match=key) as e:
            render_multidimensional(scene, caster, lights, trees, camera=camera, **kwargs)
        assert "\n" not in str(e.value)


def test_plan_refuses_an_aperture_for_a_pinhole_integrator(tmp_path):
    """camera.aperture > 0 needs an integrator with a thin lens: one line naming the key, before any work."""
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.config import load_config

    (tmp_path / "run.yaml").write_text("scene: {builtin: cornell}\ncamera: {aperture: 0.1}\n")
    with pytest.raises(LightcutsError, match=r"^camera\.aperture: integrator 'lightcuts'"):
        plan_run(load_config(tmp_path / "run.yaml"), render=True)
    (tmp_path / "run.yaml").write_text("scene: {builtin: cornell}\ncamera: {aperture: 0.1}\n"
                                       "render: {integrator: {type: multidimensional, representatives: 2}}\n")
    plan = plan_run(load_config(tmp_path / "run.yaml"), render=True)
    assert plan.record()["integrator"] == {"type": "multidimensional", "representatives": 2,
                                           "gather_representatives": 16}


def test_warm_kernels_compiles_the_specialisation_renders_use(cornell):
    # The commands compile the integrator's render kernel in a child process through its ``kernels``
    # module's warm_kernels (no lights, another scene): the real renders must find that specialisation.
    from lightcuts.pipeline.warmup import is_cached
    from lightcuts.integrators.registry import INTEGRATORS
    from lightcuts.integrators.multidim import render as md_render

    assert INTEGRATORS.entry("multidimensional").trait("kernels") == md_render.__name__
    scene, caster, camera, lights, trees = cornell
    md_render.warm_kernels()
    n = len(md_render._render_band.signatures)
    render_multidimensional(scene, caster, lights, trees, camera=camera, spp=4, crop=(0, 0, 2, 2))
    render_multidimensional_reference(scene, caster, lights, camera=camera, spp=2, crop=(0, 0, 2, 2))
    assert len(md_render._render_band.signatures) == n
    assert sum("lightcuts.embree" in str(sig[0]) for sig in md_render._render_band.signatures) == 1
    assert is_cached(md_render._render_band)
