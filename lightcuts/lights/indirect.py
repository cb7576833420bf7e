"""Indirect VPLs by particle tracing from the emitters (instant radiosity, Keller 1997).

A path starts at a point on an emissive triangle chosen in proportion to its power (triangle by
``A_t * luminance(Le_t)``, point uniform on it) with a cosine-distributed direction about the
emitter's normal. Its starting power is the emitted power divided by the sampling density and by
the number of paths N: ``Phi_0 = pi * Le_t * A_t / (N * p_t)`` (RGB). At every surface hit
(bounce b >= 1), with the surface's diffuse albedo ``rho`` (RGB, its texture's at the hit):

1. a VPL is stored at the hit: ``oriented``, its normal the geometric normal turned towards the
   side the particle came from (surfaces reflect on both sides), intensity ``Phi * rho / pi``
   (a cosine emitter of power ``Phi * rho``), ``indirect = True``;
2. the path ends after ``max_bounces`` hits; otherwise ``Phi *= rho``, and from bounce ``rr_start``
   on, Russian roulette: survive with probability ``q = min(1, max(rho))`` and ``Phi /= q``;
3. it continues with a cosine-distributed direction about the VPL's normal.

A path also ends when it escapes or hits the back of an emitter: emitters are one-sided and their
back absorbs (it emits nothing and reflects nothing; the renderer must shade it black too). The
front of an emitter reflects with its albedo like any surface.

Glossy surfaces: VPLs are diffuse emitters, made from the diffuse part ``rho_d`` only. By default
only that part scatters particles too, and the specular lobe's share of the energy is dropped (the
standard limitation of instant radiosity; Lightcuts 2005 also uses diffuse VPLs). With ``glossy``
(``render.compensation``) a path goes on through either lobe: the Phong lobe with probability
``max(rho_s) / (max(rho_d) + max(rho_s))``, its direction sampled about the mirror direction
(lightcuts.sampling), and Russian roulette uses ``max(rho_d) + max(rho_s)``; a VPL then carries all
light arriving at its point, and the light that glossy surfaces reflect towards a receiver is left
to the eye-path continuation (docs/math.md, "Converging images"). The final gather from VPLs to the
camera uses the full BRDF.

Expectation: the VPLs of bounce k carry, in total, the power that leaves surfaces after exactly k
diffuse reflections, so rendering them is an unbiased estimate of all (diffuse-path) indirect light
up to ``max_bounces`` bounces; Russian roulette adds variance, not bias.

Reaching about ``count`` VPLs without bias: the number of paths N must not depend on the paths
whose power it normalises (stopping when the count is reached would correlate N with the paths'
lengths, hence their power). So a pilot of ``min(4096, max(256, count))`` paths, traced with an
independent random stream and then discarded, measures the mean number of VPLs per path m; the
run then traces ``N = ceil(count / m)`` whole paths (at most ``64 * count``; ``count`` if the pilot
found no VPL at all) and keeps all their VPLs. The result holds ``count`` VPLs up to the pilot's and the run's sampling noise (about 1-2%).

Randomness is a counter-based hash of (seed, stream, path index, bounce, dimension), so every path
is the same whatever the thread count or batch split: same scene, counts and seed -> bit-identical
lights. The kernels avoid fastmath for the same reason.

Two routes trace the same paths with the same per-hit code (:func:`_scatter`) and, given the same
hits from the caster, identical VPLs in (path, bounce) order: where the caster is kernel-callable
(``kernel_caster``: ``embree``, the BVH casters), one numba kernel traces whole paths with per-ray
caster calls (one parallel region per 32K-path chunk, no compaction); otherwise a wavefront over
the caster's batch ``intersect``, one batch per bounce with the per-path arithmetic in numba ``prange`` kernels. Ray origins leave surfaces along
the normal by ``ray_offset(scene)`` (tnear 0), so no ray hits the surface it starts on.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from lightcuts.accel.base import kernel_caster_of
from lightcuts.accel.kernel_api import intersect, new_scratch
from lightcuts.hashing import mix64 as _mix64
from lightcuts.lights.lightset import LUMINANCE, LightSet
from lightcuts.parallel import next_task, on_counter
from lightcuts.sampling import cosine_direction, phong_direction, reflect
from lightcuts.scene.textures import albedo_at

# Stream tags for the counter-based hash: the pilot's paths are independent of the run's.
_STREAM_RUN = 0x52554E
_STREAM_PILOT = 0x50494C4F54
# Paths per wavefront: bounds memory (about 0.4 KB a path) whatever the count.
_CHUNK = 1 << 17
# VPL slots (max_bounces per path) per call of the fused kernel: 72 B a slot, about 38 MB.
_SLOT_ROWS = 1 << 19
# Paths a thread of the fused kernel takes at a time.
_FUSED_CHUNK = 64
_MAX_PATHS_PER_VPL = 64
_DIMS = 8  # random dimensions per bounce (the hash's counter is bounce * _DIMS + dimension)


@njit(cache=True, inline="always")
def _uniform(key, path, bounce, dim):
    """A uniform float64 in [0, 1) that depends only on (key, path, bounce, dim)."""
    h = _mix64(key ^ _mix64(np.uint64(path) + np.uint64(0x9E3779B97F4A7C15)))
    h = _mix64(h ^ np.uint64(bounce * _DIMS + dim))
    return np.float64(h >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _start(key, path, cdf, p0, e1, e2, normal, power, eps):
    """Bounce 0 of ``path``: a point on an emitter chosen by power, a cosine direction about its normal.

    cdf : (E,) cumulative triangle weights (last = total); p0, e1, e2 : (E, 3) corner 0 and the edges
    p1 - p0, p2 - p0; normal : (E, 3); power : (E, 3) starting power of a path from each triangle.
    Returns the ray origin (offset by eps along the normal), direction and power, 9 floats.
    """
    last = len(cdf) - 1
    t = min(np.searchsorted(cdf, _uniform(key, path, 0, 0) * cdf[last], side="right"), last)
    u = _uniform(key, path, 0, 1)
    v = _uniform(key, path, 0, 2)
    # Heitz's area-preserving square-to-triangle map
    if u < v:
        b0 = 0.5 * u
        b1 = v - b0
    else:
        b1 = 0.5 * v
        b0 = u - b1
    nx, ny, nz = normal[t, 0], normal[t, 1], normal[t, 2]
    dx, dy, dz = cosine_direction(nx, ny, nz, _uniform(key, path, 0, 3), _uniform(key, path, 0, 4))
    ox = p0[t, 0] + b0 * e1[t, 0] + b1 * e2[t, 0] + eps * nx
    oy = p0[t, 1] + b0 * e1[t, 1] + b1 * e2[t, 1] + eps * ny
    oz = p0[t, 2] + b0 * e1[t, 2] + b1 * e2[t, 2] + eps * nz
    return ox, oy, oz, dx, dy, dz, power[t, 0], power[t, 1], power[t, 2]


@njit(cache=True)
def _scatter(key, bounce, path, ox, oy, oz, dx, dy, dz, pr, pg, pb, thit, f, face_normal, face_p0, albedo,
             tex, specular, exponent, emitter, max_bounces, rr_start, glossy):
    """One hit of a path: its VPL, and whether and how the path goes on.

    (ox, oy, oz) + thit (dx, dy, dz) is the hit on triangle f (-1: a miss); (pr, pg, pb) the power the
    particle carries. Returns ``status`` (0: ended, no VPL; 1: VPL, then ended; 2: VPL and the path
    goes on; 3: no VPL, the path goes on), the VPL's position, normal and intensity, and the next segment's unit direction and
    power: 19 values (the VPL's and next segment's fields are meaningless where status says so).
    The next origin is the VPL position offset by eps along the VPL normal. ``glossy``: the path
    goes on through the Phong lobe too (see the module docstring); the VPL stays diffuse.
    """
    if f < 0:
        return (0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    nx, ny, nz = face_normal[f, 0], face_normal[f, 1], face_normal[f, 2]
    if dx * nx + dy * ny + dz * nz > 0.0:
        if emitter[f]:  # the back of an emitter absorbs
            return (0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        nx, ny, nz = -nx, -ny, -nz
    x = ox + thit * dx
    y = oy + thit * dy
    z = oz + thit * dz
    # onto the triangle's plane: Embree's float32 t leaves the point slightly off it
    off = (x - face_p0[f, 0]) * nx + (y - face_p0[f, 1]) * ny + (z - face_p0[f, 2]) * nz
    x -= off * nx
    y -= off * ny
    z -= off * nz
    r, g, b = albedo_at(albedo, tex, f, x, y, z)
    qd = max(r, g, b)
    qs = max(specular[f, 0], specular[f, 1], specular[f, 2]) if glossy else 0.0
    q = qd + qs
    if q <= 0.0:
        return (0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    ir, ig, ib = pr * r / math.pi, pg * g / math.pi, pb * b / math.pi
    status = 2
    scale = 1.0
    if bounce >= max_bounces:
        status = 1
    elif bounce >= rr_start and q < 1.0:
        if _uniform(key, path, bounce, 2) >= q:
            status = 1
        scale = 1.0 / q
    if qd <= 0.0:  # a purely glossy surface stores no VPL (status 0 or 3)
        status = 0 if status == 1 else 3
    ndx, ndy, ndz = 0.0, 0.0, 0.0
    if status >= 2 and qs > 0.0 and _uniform(key, path, bounce, 3) * q >= qd:
        # The Phong lobe, chosen with probability qs / q: f_s cos / pdf = rho_s (n + 2) / (n + 1) cos
        # (lightcuts.sampling.sample_brdf).
        e = exponent[f]
        rx, ry, rz = reflect(-dx, -dy, -dz, nx, ny, nz)
        ndx, ndy, ndz, cos_i = phong_direction(rx, ry, rz, nx, ny, nz, e, _uniform(key, path, bounce, 0),
                                               _uniform(key, path, bounce, 1))
        if cos_i <= 0.0:
            return (status - 2, x, y, z, nx, ny, nz, ir, ig, ib, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        w = scale * q / qs * (e + 2.0) / (e + 1.0) * cos_i
        return (status, x, y, z, nx, ny, nz, ir, ig, ib, ndx, ndy, ndz,
                pr * specular[f, 0] * w, pg * specular[f, 1] * w, pb * specular[f, 2] * w, 0.0, 0.0, 0.0)
    if status == 2:
        ndx, ndy, ndz = cosine_direction(nx, ny, nz, _uniform(key, path, bounce, 0),
                                          _uniform(key, path, bounce, 1))
        if qs > 0.0:
            scale *= q / qd
    return (status, x, y, z, nx, ny, nz, ir, ig, ib, ndx, ndy, ndz,
            pr * r * scale, pg * g * scale, pb * b * scale, 0.0, 0.0, 0.0)


@njit(parallel=True, cache=True)
def _emit_wave(key, path0, cdf, p0, e1, e2, normal, power, eps, org, dirs, pw):
    """Wavefront: start paths path0 .. path0 + len(org) - 1; writes org, dirs, pw (n, 3)."""
    for i in prange(org.shape[0]):
        (org[i, 0], org[i, 1], org[i, 2], dirs[i, 0], dirs[i, 1], dirs[i, 2],
         pw[i, 0], pw[i, 1], pw[i, 2]) = _start(key, path0 + i, cdf, p0, e1, e2, normal, power, eps)


@njit(parallel=True, cache=True)
def _scatter_wave(key, bounce, path, org, dirs, pw, thit, prim, face_normal, face_p0, albedo, tex, specular,
                  exponent, emitter, max_bounces, rr_start, glossy, eps, vpos, vnrm, vint, has_vpl, alive):
    """Wavefront: one bounce of every live path (:func:`_scatter`); org, dirs, pw (n, 3) are updated
    in place to the next segment; writes vpos, vnrm, vint (n, 3) and has_vpl, alive (n,) bool."""
    for i in prange(path.shape[0]):
        res = _scatter(key, bounce, path[i], org[i, 0], org[i, 1], org[i, 2], dirs[i, 0], dirs[i, 1], dirs[i, 2],
                       pw[i, 0], pw[i, 1], pw[i, 2], thit[i], prim[i], face_normal, face_p0, albedo, tex,
                       specular, exponent, emitter, max_bounces, rr_start, glossy)
        status = res[0]
        has_vpl[i] = status == 1 or status == 2
        alive[i] = status >= 2
        if has_vpl[i]:
            vpos[i, 0], vpos[i, 1], vpos[i, 2] = res[1], res[2], res[3]
            vnrm[i, 0], vnrm[i, 1], vnrm[i, 2] = res[4], res[5], res[6]
            vint[i, 0], vint[i, 1], vint[i, 2] = res[7], res[8], res[9]
        if status >= 2:
            org[i, 0], org[i, 1], org[i, 2] = res[1] + eps * res[4], res[2] + eps * res[5], res[3] + eps * res[6]
            dirs[i, 0], dirs[i, 1], dirs[i, 2] = res[10], res[11], res[12]
            pw[i, 0], pw[i, 1], pw[i, 2] = res[13], res[14], res[15]


@njit(cache=True, nogil=True, error_model="numpy")  # kernel_api's flags
def _trace_fused(cdata, key, path0, n, cdf, p0, e1, e2, normal, power, eps, face_normal,
                 face_p0, albedo, tex, specular, exponent, emitter, max_bounces, rr_start, glossy, slots, counts, vpos,
                 vnrm, vint, tasks):
    """Whole paths path0 .. path0 + n - 1 with per-ray calls of the caster (its data ``cdata``,
    lightcuts.accel.kernel_api): one thread's share, chunks of _FUSED_CHUNK paths taken from the
    counter ``tasks`` (int64 (1,), zero at the start; lightcuts.parallel.next_task). A ``nogil``
    kernel on lightcuts.parallel's threads rather than a ``parallel=True`` one, which compiles
    longer (docs/performance.md).

    counts (n,) int64: VPLs of each path. With slots > 0, path i writes its VPLs to rows
    i * slots .. i * slots + counts[i] - 1 of vpos, vnrm, vint ((n * slots, 3); slots = max_bounces);
    with slots = 0 only counts are written (the pilot).
    """
    buf = new_scratch(cdata)
    while True:
        c = next_task(tasks)
        if c * _FUSED_CHUNK >= n:
            break
        for i in range(c * _FUSED_CHUNK, min(n, (c + 1) * _FUSED_CHUNK)):
            path = path0 + i
            ox, oy, oz, dx, dy, dz, pr, pg, pb = _start(key, path, cdf, p0, e1, e2, normal, power, eps)
            k = 0
            for bounce in range(1, max_bounces + 1):
                thit, f = intersect(cdata, buf, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
                res = _scatter(key, bounce, path, ox, oy, oz, dx, dy, dz, pr, pg, pb, thit, f, face_normal, face_p0,
                               albedo, tex, specular, exponent, emitter, max_bounces, rr_start, glossy)
                status = res[0]
                if status == 0:
                    break
                if status < 3:
                    if slots > 0:
                        row = i * slots + k
                        vpos[row, 0], vpos[row, 1], vpos[row, 2] = res[1], res[2], res[3]
                        vnrm[row, 0], vnrm[row, 1], vnrm[row, 2] = res[4], res[5], res[6]
                        vint[row, 0], vint[row, 1], vint[row, 2] = res[7], res[8], res[9]
                    k += 1
                if status == 1:
                    break
                ox, oy, oz = res[1] + eps * res[4], res[2] + eps * res[5], res[3] + eps * res[6]
                dx, dy, dz = res[10], res[11], res[12]
                pr, pg, pb = res[13], res[14], res[15]
            counts[i] = k


def _mix64_py(x: int) -> int:
    """:func:`lightcuts.hashing.mix64` in Python (no kernel dispatch for two numbers)."""
    m = 0xFFFFFFFFFFFFFFFF
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & m
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & m
    return x ^ (x >> 31)


def _stream_key(seed: int, stream: int) -> np.uint64:
    """The hash key of one random stream of one seed (a uint64, so numba does not type it as int64)."""
    return np.uint64(_mix64_py((seed & 0xFFFFFFFFFFFFFFFF) ^ _mix64_py(stream)))


class Emitters:
    """Emitter triangles of non-zero power with their sampling CDF, as arrays for the kernels: tri
    (E,) int64 triangle ids, cdf (E,) the running sum of ``area * luminance(Le)`` (a triangle is
    drawn in proportion to its power), p0, e1, e2 (E, 3) a corner and the two edges from it
    (a point ``p0 + b1 e1 + b2 e2``), normal (E, 3), unit_power (E, 3). Shared by the particle
    tracer and the path tracer (lightcuts.integrators.path)."""

    def __init__(self, scene):
        tri = scene.emitters
        area = scene.face_areas[tri]
        le = scene.emission[tri]
        weight = area * (le @ LUMINANCE)
        keep = weight > 0
        tri, le, weight = tri[keep], le[keep], weight[keep]
        corners = scene.triangles[tri]
        self.tri = np.ascontiguousarray(tri, np.int64)
        self.n = len(tri)
        self.cdf = np.cumsum(weight)
        self.p0 = np.ascontiguousarray(corners[:, 0])
        self.e1 = np.ascontiguousarray(corners[:, 1] - corners[:, 0])
        self.e2 = np.ascontiguousarray(corners[:, 2] - corners[:, 0])
        self.normal = np.ascontiguousarray(scene.face_normals[tri])
        # pi * Le * A / p_t with p_t = w_t / sum(w): the power of one path when N = 1
        self.unit_power = np.ascontiguousarray(
            np.pi * le * (self.cdf[-1] / (le @ LUMINANCE))[:, None] if self.n else np.zeros((0, 3)))


def _trace(scene, caster, emitters, key, n_paths, max_bounces, rr_start, glossy, eps, count_only=False):
    """Trace paths 0 .. n_paths - 1; (position, normal, intensity) of their VPLs in (path, bounce)
    order, or only their number. Per-ray calls inside one kernel where the caster offers a
    ``kernel_caster``, else a wavefront over the batch API; both give the same VPLs."""
    power = emitters.unit_power / n_paths
    geometry = (np.ascontiguousarray(scene.face_normals), np.ascontiguousarray(scene.triangles[:, 0]),
                np.ascontiguousarray(scene.albedo), scene.texture_data(), np.ascontiguousarray(scene.specular, np.float64),
                np.ascontiguousarray(scene.exponent, np.float64), np.ascontiguousarray(scene.emission.max(axis=1) > 0))
    handles = kernel_caster_of(caster, "lights.indirect")
    route = _trace_chunk_fused if handles is not None else _trace_chunk_wavefront
    chunk = _CHUNK if handles is None else max(1, _SLOT_ROWS // max_bounces)
    parts, n_vpl = [], 0
    for path0 in range(0, n_paths, chunk):
        n = min(chunk, n_paths - path0)
        part = route(caster, handles, emitters, geometry, key, path0, n, power, eps, (max_bounces, rr_start, glossy),
                     count_only)
        if count_only:
            n_vpl += part
        else:
            parts.append(part)
    if count_only:
        return n_vpl
    if not parts:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3))
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(3))


def _trace_chunk_fused(caster, handles, emitters, geometry, key, path0, n, power, eps, rules, count_only):
    slots = 0 if count_only else rules[0]
    counts = np.empty(n, np.int64)
    vpos, vnrm, vint = (np.empty((n * slots, 3)) for _ in range(3))
    args = (handles.data, key, path0, n, emitters.cdf, emitters.p0, emitters.e1, emitters.e2, emitters.normal,
            power, eps, *geometry, *rules, slots, counts, vpos, vnrm, vint)
    on_counter(_trace_fused, n, 2 * _FUSED_CHUNK, *args)
    if count_only:
        return int(counts.sum())
    used = (np.arange(slots)[None, :] < counts[:, None]).ravel()
    return vpos[used], vnrm[used], vint[used]


def _trace_chunk_wavefront(caster, handles, emitters, geometry, key, path0, n, power, eps, rules, count_only):
    max_bounces = rules[0]
    org, dirs, pw = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    _emit_wave(key, path0, emitters.cdf, emitters.p0, emitters.e1, emitters.e2, emitters.normal, power, eps,
               org, dirs, pw)
    path = np.arange(path0, path0 + n, dtype=np.int64)
    out, n_vpl = [], 0
    for bounce in range(1, max_bounces + 1):
        m = len(path)
        thit, prim = caster.intersect(org, dirs, np.zeros(m), np.full(m, np.inf))
        vpos, vnrm, vint = np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3))
        has_vpl, alive = np.empty(m, bool), np.empty(m, bool)
        _scatter_wave(key, bounce, path, org, dirs, pw, np.ascontiguousarray(thit, np.float64),
                      np.ascontiguousarray(prim, np.int32), *geometry, *rules, eps,
                      vpos, vnrm, vint, has_vpl, alive)
        n_vpl += int(np.count_nonzero(has_vpl))
        if not count_only:
            out.append((path[has_vpl], vpos[has_vpl], vnrm[has_vpl], vint[has_vpl]))
        if not alive.any():
            break
        path, org, dirs, pw = path[alive], org[alive], dirs[alive], pw[alive]
    if count_only:
        return n_vpl
    # bounce-major -> (path, bounce) order, the fused route's: a stable sort keeps bounces in order
    order = np.argsort(np.concatenate([o[0] for o in out]), kind="stable")
    return tuple(np.concatenate([o[k] for o in out])[order] for k in range(1, 4))


def ray_offset(scene) -> float:
    """Distance by which ray origins leave a surface: 1e-5 of the larger of the scene's size and its
    distance from the origin (float32 positions in Embree lose precision with both)."""
    lo, hi = scene.bounds
    return 1e-5 * max(float(np.linalg.norm(hi - lo)), float(np.abs(np.concatenate([lo, hi])).max()), 1e-30)


def indirect_lights(scene, caster, count: int, seed: int, max_bounces: int = 16, rr_start: int = 1,
                    glossy: bool = False) -> LightSet:
    """About ``count`` indirect VPLs by particle tracing (see the module docstring for the rules).

    scene : Scene (emitters, albedo, geometry)
    caster : RayCaster over the scene's triangles (``lightcuts.accel.make_caster``); None builds
        the default one
    count : wanted number of VPLs (> 0); the result holds about that many
    seed : int; the result depends only on (scene, count, seed, max_bounces, rr_start, glossy)
    max_bounces : VPLs are stored at hits 1 .. max_bounces
    rr_start : Russian roulette decides at every hit b >= rr_start (0 and 1 are the same)
    glossy : paths go on through the Phong lobe too (``render.compensation``: the eye-path
        continuation carries the light that glossy surfaces reflect, docs/math.md "Converging images")

    Returns an ``oriented`` LightSet with ``indirect`` all True; ``meta`` holds ``indirect_paths``
    (N, the normaliser) and ``indirect_pilot_paths``. Empty when no particle reaches a surface.
    """
    count = int(count)
    emitters = Emitters(scene)
    empty = LightSet(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), "oriented", np.zeros(0, bool))
    if count <= 0 or emitters.n == 0:
        return empty
    if caster is None:
        from lightcuts.accel import make_caster

        caster = make_caster(scene)
    eps = ray_offset(scene)
    max_bounces, rr_start = int(max_bounces), int(rr_start)
    n_pilot = min(4096, max(256, count))
    pilot_vpls = _trace(scene, caster, emitters, _stream_key(seed, _STREAM_PILOT), n_pilot, max_bounces, rr_start,
                        bool(glossy), eps, count_only=True)
    if pilot_vpls == 0:
        n_paths = count
    else:
        n_paths = min(math.ceil(count * n_pilot / pilot_vpls), _MAX_PATHS_PER_VPL * count)
    pos, nrm, inten = _trace(scene, caster, emitters, _stream_key(seed, _STREAM_RUN), n_paths, max_bounces,
                             rr_start, bool(glossy), eps)
    meta = {"indirect_paths": n_paths, "indirect_pilot_paths": n_pilot}
    return LightSet(pos, nrm, inten, "oriented", np.ones(len(pos), bool), meta)
