r"""numba kernels that call Embree 4 (``rtcIntersect1`` / ``rtcOccluded1``) per ray, and
``rtcOccluded4`` / ``rtcOccluded8`` per packet of shadow rays.

The project's kernels (the cut evaluator, the reference, the particle tracer) reach these through
lightcuts.accel.kernel_api: the device functions at the bottom are the ``device`` of the ``embree``
registry entry, kernel name ``lightcuts.embree`` (data ``(EMBREE_TAG, intersect1, occluded1, occluded_n, scene)`` from
``EmbreeCaster.kernel_caster``). The raw per-ray functions below also serve kernels written against
Embree alone, with the handles; the batch kernels are what
:class:`lightcuts.accel.embree.embree.EmbreeCaster` runs for its ``intersect`` / ``occluded``.

Handles
-------
``caster.kernel_handles`` is ``(intersect1, occluded1, scene)``: two ctypes functions (pointer
arguments declared ``uint64``) and the scene handle as a Python ``int``. Pass all three into the
kernel as ARGUMENTS: a ctypes function referenced as a module global makes numba refuse to cache
the kernel ("dynamic globals"), costing seconds of JIT in every process. The caster must stay alive
(not closed) while a kernel uses its handles. ``caster.packet_handles`` is ``(occluded_n, width,
scene)`` for :func:`packet_occluded`: ``rtcOccluded8`` (width 8) where Embree reports native 8-wide
packets on this processor, else ``rtcOccluded4`` (width 4).

Rays
----
Origin ``o`` and direction ``d`` in world units; ``d`` need not be unit length, and ``t`` is in
units of ``|d|`` (the hit point is ``o + t d``). Embree works in float32: inputs are rounded to
float32 and a returned ``t`` carries float32 precision. A hit counts when
``tnear <= t <= tfar`` (Embree's test; whether exactly ``t == tnear`` counts is not something to
rely on). ``tnear`` must be >= 0 (a negative value is treated as 0); ``tfar`` may be ``inf``; a
segment with ``tfar < tnear`` (or a NaN bound) is empty: no hit, not occluded.

Scratch buffer
--------------
One RTCRayHit (ray 48 bytes + hit; 96 bytes reserved, enough for Embree 4.x with one instance
level and ``instPrimID``), 16-byte aligned as Embree requires. Allocate it with
:func:`new_ray_buffer` once per chunk of rays (per ``prange`` iteration), never once per ray.
Layout, in float32 slots (uint32 where marked):

====== =========================================================================
0-2    org x, y, z
3      tnear
4-6    dir x, y, z
7      time (0)
8      tfar: in, the segment end; out of rtcOccluded1, -inf when occluded;
       out of rtcIntersect1, the hit t
9      mask (uint32, all ones); 10 id (uint32); 11 flags (uint32, 0)
12-14  Ng x, y, z (geometric normal of the hit, unnormalised)
15-16  u, v (barycentrics of the hit)
17     primID (uint32); 18 geomID (uint32, 0xFFFFFFFF = miss); 19 instID[0]
====== =========================================================================

Example: a kernel in another module
-----------------------------------
::

    import numpy as np
    from numba import njit, prange

    from lightcuts.accel.embree.embree_kernels import new_ray_buffer, ray_intersect, ray_occluded

    CHUNK = 64

    @njit(parallel=True, cache=True)
    def visible_hits(intersect1, occluded1, scene, org, dirs, light, t_out, prim_out, lit_out):
        # Closest hit of each camera ray, then whether that hit point sees the point light.
        n = org.shape[0]
        for c in prange((n + CHUNK - 1) // CHUNK):
            buf = new_ray_buffer()              # one aligned scratch RTCRayHit per chunk
            for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
                t, prim = ray_intersect(intersect1, scene, buf, org[i, 0], org[i, 1], org[i, 2],
                                        dirs[i, 0], dirs[i, 1], dirs[i, 2], 0.0, np.inf)
                t_out[i] = t
                prim_out[i] = prim
                lit_out[i] = False
                if prim >= 0:
                    px = org[i, 0] + t * dirs[i, 0]
                    py = org[i, 1] + t * dirs[i, 1]
                    pz = org[i, 2] + t * dirs[i, 2]
                    # Shadow ray from the hit towards the light: d = light - p, so t = 1 is the light;
                    # tnear / tfar keep it off the surface it starts on and short of the light.
                    lit_out[i] = not ray_occluded(occluded1, scene, buf, px, py, pz,
                                                  light[0] - px, light[1] - py, light[2] - pz,
                                                  1e-4, 1.0 - 1e-4)

    # The caller (plain Python): org, dirs (n, 3) float64; light (3,) float64; outputs preallocated.
    from lightcuts.accel import make_caster

    caster = make_caster(scene, "embree")
    intersect1, occluded1, handle = caster.kernel_handles
    t, prim, lit = np.empty(n), np.empty(n, np.int64), np.empty(n, np.bool_)
    visible_hits(intersect1, occluded1, handle, org, dirs, light, t, prim, lit)

Such a kernel caches like any other: a second process loads it from numba's cache without
recompiling (``tests/accel/test_accel.py::test_kernel_in_another_module_is_cached`` checks this).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from lightcuts.accel.kernel_api import DeviceFunctions
from lightcuts.accel.packets import (INVALID_ID, PACKET_FIELDS, PACKET_FLOATS, lane_occluded,  # noqa: F401
                                     new_ray_packet, packet_set_ray, _address, _load_u32, _store_u32)

#: float32 slots reserved for one RTCRayHit (80 bytes in Embree 4.4; 96 if built with instance arrays).
RAYHIT_FLOATS = 24
#: Embree requires RTCRayHit / RTCRay to be 16-byte aligned.
RAYHIT_ALIGN = 16
#: Rays per prange iteration of the batch kernels (one scratch buffer each).
CHUNK = 64


@njit(cache=True)
def new_ray_buffer():
    """(RAYHIT_FLOATS,) float32 scratch for one RTCRayHit, 16-byte aligned, zeroed.

    numba happens to align array data to 32 bytes today; the alignment is made explicit here
    (over-allocate by 3 floats, start at the first 16-byte boundary) so nothing rests on that.
    """
    spare = RAYHIT_ALIGN // 4 - 1
    raw = np.zeros(RAYHIT_FLOATS + spare, np.float32)
    # float32 data is at least 4-byte aligned, so the gap to the boundary is a whole number of floats.
    skip = ((RAYHIT_ALIGN - raw.ctypes.data % RAYHIT_ALIGN) % RAYHIT_ALIGN) // 4
    return raw[skip:skip + RAYHIT_FLOATS]


@njit(cache=True)
def _load_ray(buf, ox, oy, oz, dx, dy, dz, tnear, tfar):
    """Write one ray into the scratch RTCRayHit and reset the hit ids to 'miss'."""
    buf[0] = ox
    buf[1] = oy
    buf[2] = oz
    buf[3] = max(tnear, 0.0)
    buf[4] = dx
    buf[5] = dy
    buf[6] = dz
    buf[7] = 0.0
    buf[8] = tfar
    _store_u32(buf, 9, INVALID_ID)      # mask: all geometries
    _store_u32(buf, 10, 0)              # id
    _store_u32(buf, 11, 0)              # flags
    _store_u32(buf, 17, INVALID_ID)     # primID
    _store_u32(buf, 18, INVALID_ID)     # geomID
    _store_u32(buf, 19, INVALID_ID)     # instID[0]


@njit(cache=True)
def ray_occluded(occluded1, scene, buf, ox, oy, oz, dx, dy, dz, tnear, tfar):
    """True if any triangle is hit with tnear <= t <= tfar (any hit, Embree's ``rtcOccluded1``).

    occluded1 : ctypes ``rtcOccluded1`` from ``caster.kernel_handles``
    scene : int, scene handle from ``caster.kernel_handles``
    buf : scratch from :func:`new_ray_buffer`
    ox, oy, oz, dx, dy, dz : origin and direction (world units; t in units of |d|)
    tnear, tfar : segment along the ray; empty (False) when ``not tfar >= tnear``
    """
    if not tfar >= tnear:
        return False
    _load_ray(buf, ox, oy, oz, dx, dy, dz, tnear, tfar)
    occluded1(scene, _address(buf), 0)
    return buf[8] < 0.0


@njit(cache=True)
def ray_intersect(intersect1, scene, buf, ox, oy, oz, dx, dy, dz, tnear, tfar):
    """Closest hit with tnear <= t <= tfar (Embree's ``rtcIntersect1``).

    Arguments as :func:`ray_occluded`, with ``intersect1`` from ``caster.kernel_handles``.
    Returns ``(t, prim)``: float64 hit distance in units of |d| (inf on a miss) and int64 triangle
    id (-1 on a miss). The barycentrics and geometric normal of the hit stay in ``buf`` (slots
    15-16 and 12-14) until the next call.
    """
    if not tfar >= tnear:
        return np.inf, np.int64(-1)
    _load_ray(buf, ox, oy, oz, dx, dy, dz, tnear, tfar)
    intersect1(scene, _address(buf), 0)
    if _load_u32(buf, 18) == INVALID_ID:
        return np.inf, np.int64(-1)
    return np.float64(buf[8]), np.int64(_load_u32(buf, 17))


@njit(cache=True)
def packet_occluded(occluded_n, width, scene, pk, n):
    """Cast lanes 0..n-1 of the packet pk with Embree's ``rtcOccluded4`` / ``rtcOccluded8``
    (occluded_n, of that width, from ``caster.packet_handles``); then :func:`lane_occluded` tells
    each lane's answer. Lanes n..width-1 are inactive (their data is ignored)."""
    for lane in range(width):
        _store_u32(pk, PACKET_FIELDS * width + lane, INVALID_ID if lane < n else 0)  # -1: active
    base = _address(pk)
    occluded_n(base + 4 * PACKET_FIELDS * width, scene, base, 0)


@njit(parallel=True, cache=True)
def intersect_rays(intersect1, scene, org, dirs, tnear, tfar, t_out, prim_out):
    """Closest hit of each ray: org, dirs (n, 3) float64; tnear, tfar (n,) float64;
    writes t_out (n,) float64 (inf on a miss) and prim_out (n,) int32 (-1 on a miss)."""
    n = org.shape[0]
    for c in prange((n + CHUNK - 1) // CHUNK):
        buf = new_ray_buffer()
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            t, prim = ray_intersect(intersect1, scene, buf, org[i, 0], org[i, 1], org[i, 2],
                                    dirs[i, 0], dirs[i, 1], dirs[i, 2], tnear[i], tfar[i])
            t_out[i] = t
            prim_out[i] = prim


@njit(parallel=True, cache=True)
def occluded_rays(occluded1, scene, org, dirs, tnear, tfar, out):
    """Any hit of each ray segment: arrays as :func:`intersect_rays`; writes out (n,) bool."""
    n = org.shape[0]
    for c in prange((n + CHUNK - 1) // CHUNK):
        buf = new_ray_buffer()
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            out[i] = ray_occluded(occluded1, scene, buf, org[i, 0], org[i, 1], org[i, 2],
                                  dirs[i, 0], dirs[i, 1], dirs[i, 2], tnear[i], tfar[i])


# Device functions of the kernel caster "lightcuts.embree" (lightcuts.accel.kernel_api):
# data = (EMBREE_TAG, intersect1, occluded1, occluded_n, scene) from EmbreeCaster.kernel_caster.

@njit(cache=True)
def embree_new_scratch(data):
    """Per-thread scratch: one aligned RTCRayHit (:func:`new_ray_buffer`)."""
    return new_ray_buffer()


@njit(cache=True, forceinline=True)
def embree_intersect(data, buf, ox, oy, oz, dx, dy, dz, tnear, tfar):
    """KernelCaster.intersect: :func:`ray_intersect` with ``rtcIntersect1``."""
    return ray_intersect(data[1], data[4], buf, ox, oy, oz, dx, dy, dz, tnear, tfar)


@njit(cache=True, forceinline=True)
def embree_occluded(data, buf, ox, oy, oz, dx, dy, dz, tnear, tfar):
    """KernelCaster.occluded: :func:`ray_occluded` with ``rtcOccluded1``."""
    return ray_occluded(data[2], data[4], buf, ox, oy, oz, dx, dy, dz, tnear, tfar)


@njit(cache=True, forceinline=True)
def embree_packet_occluded(data, buf, pk, width, n):
    """KernelCaster.packet_occluded: :func:`packet_occluded` with ``rtcOccluded8`` / ``rtcOccluded4``."""
    packet_occluded(data[3], width, data[4], pk, n)


#: The Embree caster's device functions (its registry entry declares them) and the first element of its data.
EMBREE_DEVICE = DeviceFunctions("lightcuts.embree", embree_intersect, embree_occluded, embree_packet_occluded,
                                embree_new_scratch)
EMBREE_TAG = EMBREE_DEVICE.tag
