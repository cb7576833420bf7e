"""Ray casters: analytic hits, tnear/tfar semantics, agreement with embreex, per-ray kernel calls, bad input."""

from __future__ import annotations

import ctypes
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numba
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numba import njit, prange

import lightcuts
from lightcuts.accel import RAY_CASTERS, make_caster
from lightcuts.accel.embree.embree_kernels import (PACKET_FLOATS, lane_occluded, new_ray_buffer, new_ray_packet,
                                           packet_occluded, packet_set_ray, ray_intersect, ray_occluded)
from lightcuts.errors import LightcutsError

CASTERS = ["embree", "embreex", "bvh-sah", "bvh-agglomerative", "bvh-agglomerative-heap"]

# Two parallel unit right triangles: prim 0 in the plane z = 0, prim 1 in z = 2, same (x, y) footprint.
TWO_TRIANGLES = (
    np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 2], [1, 0, 2], [0, 1, 2]], np.float64),
    np.array([[0, 1, 2], [3, 4, 5]], np.int32),
)


@pytest.fixture(scope="module", params=CASTERS)
def caster(request):
    return make_caster(TWO_TRIANGLES, request.param)


@pytest.fixture(scope="module")
def embree_caster():
    return make_caster(TWO_TRIANGLES, "embree")


def random_triangles(n, seed):
    """(3n, 3) vertices, (n, 3) faces: small random triangles in the unit box."""
    rng = np.random.default_rng(seed)
    centres = rng.random((n, 1, 3))
    corners = centres + 0.08 * rng.standard_normal((n, 3, 3))
    return corners.reshape(-1, 3), np.arange(3 * n, dtype=np.int32).reshape(n, 3)


def random_rays(n, seed):
    """Origins in a box around the unit cube, isotropic non-unit directions, both float32-exact."""
    rng = np.random.default_rng(seed)
    org = (rng.random((n, 3)) * 1.4 - 0.2).astype(np.float32).astype(np.float64)
    dirs = (rng.standard_normal((n, 3)) * rng.uniform(0.5, 2.0, (n, 1))).astype(np.float32).astype(np.float64)
    return org, dirs


def test_registry_lists_both_casters():
    assert {"embree", "embreex"} <= set(RAY_CASTERS.names())


def test_known_triangle_analytic_t_and_prim(caster):
    """Rays aimed at interior points of either triangle hit it at t = 1 / |scale| with its prim id."""
    rng = np.random.default_rng(1)
    n = 400
    uv = rng.uniform(0.05, 0.45, (n, 2))                       # u + v <= 0.9: well inside
    which = rng.integers(0, 2, n)                              # target prim 0 (z = 0) or prim 1 (z = 2)
    target = np.column_stack([uv, 2.0 * which])
    # From below prim 0 aim up at it; from above prim 1 aim down at it: the target is the closest hit.
    org = target + np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)),
                                    np.where(which == 0, -rng.uniform(0.5, 3, n), rng.uniform(0.5, 3, n))])
    scale = rng.uniform(0.25, 4.0, n)
    dirs = (target - org) * scale[:, None]
    t, prim = caster.intersect(org, dirs, 0.0, np.inf)
    assert t.dtype == np.float64 and prim.dtype == np.int32 and t.shape == prim.shape == (n,)
    np.testing.assert_array_equal(prim, which)
    np.testing.assert_allclose(t, 1.0 / scale, rtol=2e-6)
    assert caster.occluded(org, dirs, 0.0, np.inf).all()


def test_misses_report_inf_and_minus_one(caster):
    # Straight up through (x, y) outside both footprints, and a zero direction (never hits).
    org = np.array([[0.8, 0.8, -1.0], [-0.1, 0.5, -1.0], [2.0, 2.0, 5.0], [0.2, 0.2, -1.0]])
    dirs = np.array([[0, 0, 1.0], [0, 0, 1.0], [0, 0, -1.0], [0, 0, 0.0]])
    t, prim = caster.intersect(org, dirs, 0.0, np.inf)
    assert np.isposinf(t).all() and (prim == -1).all()
    assert not caster.occluded(org, dirs, 0.0, np.inf).any()


def test_tnear_tfar_skip_hits_outside_the_segment(caster):
    """Up from z = -1: prim 0 at t = 1, prim 1 at t = 3."""
    n = 6
    org = np.tile([0.25, 0.25, -1.0], (n, 1))
    dirs = np.tile([0.0, 0.0, 1.0], (n, 1))
    tnear = np.array([0.0, 0.5, 1.5, 3.5, 0.0, 1.5])
    tfar = np.array([np.inf, np.inf, np.inf, np.inf, 0.5, 2.5])
    t, prim = caster.intersect(org, dirs, tnear, tfar)
    np.testing.assert_array_equal(prim, [0, 0, 1, -1, -1, -1])
    np.testing.assert_allclose(t, [1, 1, 3, np.inf, np.inf, np.inf], rtol=1e-6)
    np.testing.assert_array_equal(caster.occluded(org, dirs, tnear, tfar), [1, 1, 1, 0, 0, 0])
    # An empty segment (tfar < tnear) around a hit still hits nothing.
    t, prim = caster.intersect(org[:1], dirs[:1], 1.2, 0.8)
    assert prim[0] == -1 and np.isposinf(t[0])
    assert not caster.occluded(org[:1], dirs[:1], 1.2, 0.8)[0]


@settings(max_examples=60, deadline=None)
@given(tnear=st.floats(0.0, 7.0), length=st.floats(-1.0, 7.0), t_hit=st.floats(0.1, 4.0))
def test_hit_counts_iff_inside_segment(caster, tnear, length, t_hit):
    """Up the z axis, prim 0 at t_hit and prim 1 at t_hit + 2: the closest one in [tnear, tfar] is hit."""
    tfar = tnear + length
    for t_prim in (t_hit, t_hit + 2.0):                                   # away from float32 rounding
        assume(min(abs(t_prim - tnear), abs(t_prim - tfar)) > 1e-4 * t_prim)
    org = np.array([[0.25, 0.25, -t_hit]])
    dirs = np.array([[0.0, 0.0, 1.0]])
    inside = [tnear <= t_prim <= tfar for t_prim in (t_hit, t_hit + 2.0)]
    expected = 0 if inside[0] else 1 if inside[1] else -1
    t, prim = caster.intersect(org, dirs, tnear, tfar)
    assert prim[0] == expected
    if expected >= 0:
        assert t[0] == pytest.approx(t_hit + 2.0 * expected, rel=1e-6)
    assert caster.occluded(org, dirs, tnear, tfar)[0] == (expected >= 0)


def test_embree_matches_embreex_scene_run():
    """The ctypes/numba route and embreex's own scene.run agree ray for ray (guards the RTCRayHit layout)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    vertices, faces = random_triangles(1500, seed=2)
    org, dirs = random_rays(4000, seed=3)
    ref = rtcore_scene.EmbreeScene()
    TriangleMesh(ref, vertices.astype(np.float32), faces)
    o32, d32 = org.astype(np.float32), dirs.astype(np.float32)
    res = ref.run(o32, d32, output=1)
    ref_prim = np.asarray(res["primID"])
    ref_t = np.asarray(res["tfar"], np.float64)

    caster = make_caster((vertices, faces), "embree")
    t, prim = caster.intersect(org, dirs, 0.0, np.inf)
    assert 0.2 < (prim >= 0).mean() < 0.95          # the comparison covers both hits and misses
    np.testing.assert_array_equal(prim >= 0, ref_prim >= 0)
    both = (prim >= 0) & (ref_prim >= 0)
    np.testing.assert_array_equal(prim[both], ref_prim[both])
    np.testing.assert_allclose(t[both], ref_t[both], rtol=1e-6)

    tfar = np.random.default_rng(4).uniform(0.0, 1.0, len(org)).astype(np.float32)
    ref_occ = np.asarray(ref.run(o32, d32, dists=tfar.copy(), query="OCCLUDED")) == 0
    occ = caster.occluded(org, dirs, 0.0, tfar.astype(np.float64))
    assert 0.1 < occ.mean() < 0.9
    np.testing.assert_array_equal(occ, ref_occ)


def test_results_do_not_depend_on_thread_count():
    vertices, faces = random_triangles(300, seed=5)
    org, dirs = random_rays(3000, seed=6)
    caster = make_caster((vertices, faces), "embree")
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = caster.intersect(org, dirs, 0.01, 1.5), caster.occluded(org, dirs, 0.01, 1.5)
    finally:
        numba.set_num_threads(before)
    all_threads = caster.intersect(org, dirs, 0.01, 1.5), caster.occluded(org, dirs, 0.01, 1.5)
    for a, b in zip(one[0] + (one[1],), all_threads[0] + (all_threads[1],)):
        np.testing.assert_array_equal(a, b)


@njit(parallel=True, cache=True)
def _per_ray(intersect1, occluded1, scene, org, dirs, tnear, tfar, t_out, prim_out, occ_out, aligned):
    n = org.shape[0]
    for c in prange((n + 31) // 32):
        buf = new_ray_buffer()
        aligned[c] = buf.ctypes.data % 16 == 0 and buf.shape[0] == 24
        for i in range(c * 32, min(n, c * 32 + 32)):
            t, p = ray_intersect(intersect1, scene, buf, org[i, 0], org[i, 1], org[i, 2],
                                 dirs[i, 0], dirs[i, 1], dirs[i, 2], tnear[i], tfar[i])
            t_out[i] = t
            prim_out[i] = p
            occ_out[i] = ray_occluded(occluded1, scene, buf, org[i, 0], org[i, 1], org[i, 2],
                                      dirs[i, 0], dirs[i, 1], dirs[i, 2], tnear[i], tfar[i])


def test_device_functions_match_batch_api():
    vertices, faces = random_triangles(500, seed=7)
    org, dirs = random_rays(2000, seed=8)
    rng = np.random.default_rng(9)
    tnear = rng.uniform(0.0, 0.3, len(org))
    tfar = tnear + rng.uniform(-0.1, 1.5, len(org))            # some empty segments
    caster = make_caster((vertices, faces), "embree")
    t = np.empty(len(org))
    prim = np.empty(len(org), np.int64)
    occ = np.empty(len(org), np.bool_)
    aligned = np.zeros((len(org) + 31) // 32, np.bool_)
    _per_ray(*caster.kernel_handles, org, dirs, tnear, tfar, t, prim, occ, aligned)
    assert aligned.all()
    t_ref, prim_ref = caster.intersect(org, dirs, tnear, tfar)
    np.testing.assert_array_equal(t, t_ref)
    np.testing.assert_array_equal(prim, prim_ref)
    np.testing.assert_array_equal(occ, caster.occluded(org, dirs, tnear, tfar))
    assert (prim >= 0).any() and (prim < 0).any()


@njit(cache=True)
def _packets(occluded_n, width, scene, org, dirs, tnear, tfar, sizes, occ_out, untouched):
    """Rays in packets of sizes[b] rays; lanes past the size hold a stale ray that must stay as it is."""
    pk = new_ray_packet()
    i = 0
    for b in range(sizes.shape[0]):
        n = sizes[b]
        for lane in range(width):
            r = min(i + lane, org.shape[0] - 1)
            packet_set_ray(pk, width, lane, org[r, 0], org[r, 1], org[r, 2], dirs[r, 0], dirs[r, 1], dirs[r, 2],
                           tnear[r], tfar[r])
        packet_occluded(occluded_n, width, scene, pk, n)
        for lane in range(width):
            if lane < n:
                occ_out[i + lane] = lane_occluded(pk, width, lane)
            else:
                untouched[b] &= pk[8 * width + lane] == np.float32(tfar[min(i + lane, org.shape[0] - 1)])
        i += n


@pytest.mark.parametrize("width", [4, 8])
def test_ray_packets_match_single_rays(width):
    vertices, faces = random_triangles(500, seed=17)
    org, dirs = random_rays(3000, seed=18)
    rng = np.random.default_rng(19)
    tnear = rng.uniform(0.0, 0.3, len(org))
    tfar = tnear + rng.uniform(0.0, 1.5, len(org))
    sizes = rng.integers(1, width + 1, len(org))
    sizes = sizes[:np.searchsorted(np.cumsum(sizes), len(org), side="right")]
    n = int(sizes.sum())
    caster = make_caster((vertices, faces), "embree")
    occluded_n, native_width, scene = caster.packet_handles
    assert native_width in (4, 8)
    if width != native_width:
        if width == 8:
            pytest.skip("this processor has no native 8-wide packets")
        occluded_n = ctypes.CFUNCTYPE(None, *[ctypes.c_uint64] * 4)(("rtcOccluded4", caster._lib.lib))
    occ = np.zeros(n, np.bool_)
    untouched = np.ones(len(sizes), np.bool_)
    _packets(occluded_n, width, scene, org, dirs, tnear, tfar, sizes, occ, untouched)
    np.testing.assert_array_equal(occ, caster.occluded(org[:n], dirs[:n], tnear[:n], tfar[:n]))
    assert occ.any() and not occ.all() and untouched.all()


def test_new_ray_packet_is_aligned():
    for _ in range(8):
        pk = new_ray_packet()
        assert pk.ctypes.data % 32 == 0 and pk.shape == (PACKET_FLOATS,) and pk.dtype == np.float32


def test_new_ray_buffer_is_aligned_from_python():
    for _ in range(8):
        buf = new_ray_buffer()
        assert buf.ctypes.data % 16 == 0 and buf.shape == (24,) and buf.dtype == np.float32


_EXTERNAL_MODULE = '''
import numpy as np
from numba import njit, prange
from lightcuts.accel.embree.embree_kernels import new_ray_buffer, ray_intersect, ray_occluded

@njit(parallel=True, cache=True)
def hits(intersect1, occluded1, scene, org, dirs, prim_out, occ_out):
    n = org.shape[0]
    for c in prange((n + 63) // 64):
        buf = new_ray_buffer()
        for i in range(c * 64, min(n, c * 64 + 64)):
            t, p = ray_intersect(intersect1, scene, buf, org[i, 0], org[i, 1], org[i, 2],
                                 dirs[i, 0], dirs[i, 1], dirs[i, 2], 0.0, np.inf)
            prim_out[i] = p
            occ_out[i] = ray_occluded(occluded1, scene, buf, org[i, 0], org[i, 1], org[i, 2],
                                      dirs[i, 0], dirs[i, 1], dirs[i, 2], 0.0, 0.5 * t)
'''

_RUNNER = '''
import json, sys
import numpy as np
import ext_kernel
from lightcuts.accel import make_caster
v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
caster = make_caster((v, np.array([[0, 1, 2]])), "embree")
org = np.tile([0.2, 0.2, -1.0], (100, 1)); dirs = np.tile([0.0, 0.0, 1.0], (100, 1))
prim = np.empty(100, np.int64); occ = np.empty(100, np.bool_)
ext_kernel.hits(*caster.kernel_handles, org, dirs, prim, occ)
stats = ext_kernel.hits.stats
print(json.dumps({"hits": sum(stats.cache_hits.values()), "misses": sum(stats.cache_misses.values()),
                  "prim": prim.tolist(), "occ": occ.tolist()}))
'''


def test_kernel_in_another_module_is_cached(tmp_path):
    """A kernel elsewhere that takes kernel_handles as arguments is loaded from cache by a new process."""
    (tmp_path / "ext_kernel.py").write_text(textwrap.dedent(_EXTERNAL_MODULE))
    root = Path(lightcuts.__file__).resolve().parent.parent
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba_cache"),
               PYTHONPATH=os.pathsep.join([str(tmp_path), str(root), os.environ.get("PYTHONPATH", "")]))
    runs = []
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", _RUNNER], env=env, cwd=tmp_path, capture_output=True,
                             text=True, timeout=300)
        assert out.returncode == 0, out.stderr
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    first, second = runs
    assert first["misses"] == 1 and first["hits"] == 0
    assert second["misses"] == 0 and second["hits"] == 1       # no recompilation in the second process
    assert second["prim"] == [0] * 100 and second["occ"] == [False] * 100


@pytest.mark.parametrize("bad", [
    dict(org=np.zeros((4, 2))),
    dict(org=np.zeros(3)),
    dict(dirs=np.ones((5, 3))),
    dict(tnear=np.zeros(5)),
    dict(tfar=np.ones((4, 1))),
    dict(org=np.array([[0, 0, np.nan]] * 4)),
    dict(dirs=np.array([[0, 0, np.inf]] * 4)),
    dict(org=np.full((4, 3), 1e39)),
    dict(tnear=np.array([0.0, np.nan, 0.0, 0.0])),
    dict(tfar=np.nan),
    dict(tnear=-0.5),
    dict(tnear=np.inf),
    dict(org=[["a", "b", "c"]] * 4),
], ids=lambda d: next(iter(d)) + ":" + repr(np.asarray(next(iter(d.values()))).shape))
@pytest.mark.parametrize("query", ["intersect", "occluded"])
def test_bad_rays_raise_lightcuts_error(caster, bad, query):
    args = dict(org=np.zeros((4, 3)), dirs=np.tile([0, 0, 1.0], (4, 1)), tnear=0.0, tfar=np.inf)
    args.update(bad)
    with pytest.raises(LightcutsError, match="^ray caster: "):
        getattr(caster, query)(**args)


@pytest.mark.parametrize("name", CASTERS)
@pytest.mark.parametrize("vertices, faces", [
    (np.zeros((3, 3)), np.array([[0, 1, 3]])),
    (np.zeros((3, 3)), np.array([[0, -1, 2]])),
    (np.zeros((3, 3)), np.array([[0.0, 1.0, 2.0]])),
    (np.zeros((3, 2)), np.array([[0, 1, 2]])),
    (np.array([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]]), np.array([[0, 1, 2]])),
    (np.zeros((3, 3)), np.array([0, 1, 2])),
])
def test_bad_mesh_raises_lightcuts_error(name, vertices, faces):
    with pytest.raises(LightcutsError, match="^ray caster: "):
        make_caster((vertices, faces), name)


@pytest.mark.parametrize("name", CASTERS)
def test_empty_scene_and_empty_batch(name):
    c = make_caster((np.zeros((0, 3)), np.zeros((0, 3), np.int32)), name)
    t, prim = c.intersect(np.zeros((3, 3)), np.tile([0, 0, 1.0], (3, 1)), 0.0, np.inf)
    assert np.isposinf(t).all() and (prim == -1).all()
    assert not c.occluded(np.zeros((3, 3)), np.tile([0, 0, 1.0], (3, 1)), 0.0, np.inf).any()
    t, prim = make_caster(TWO_TRIANGLES, name).intersect(np.zeros((0, 3)), np.zeros((0, 3)), 0.0, np.inf)
    assert t.shape == prim.shape == (0,)


def test_closed_caster_refuses_work():
    c = make_caster(TWO_TRIANGLES, "embree")
    with c:
        assert c.kernel_handles[2] != 0
    assert c.closed
    c.close()                                                  # idempotent
    with pytest.raises(LightcutsError, match="after close"):
        c.occluded(np.zeros((1, 3)), np.array([[0, 0, 1.0]]), 0.0, 1.0)
    with pytest.raises(LightcutsError, match="after close"):
        c.kernel_handles
