r"""Kernel-side helpers every kernel-callable caster shares: the shadow-ray packet and raw accessors.

A packet holds up to 8 rays in the SoA layout of Embree's RTCRay4 / RTCRay8 (float32): field f of
lane r in slot ``f * K + r`` (K = the packet width, 4 or 8), fields in the order org x, y, z, tnear,
dir x, y, z, time, tfar, mask, id, flags (the last three uint32), then K int32 valid flags. Kernels
fill lanes with :func:`packet_set_ray`, hand the packet to their caster's ``packet_occluded`` and
read :func:`lane_occluded`; a caster answers "occluded" by setting the lane's tfar to -inf (what
Embree's ``rtcOccluded4/8`` do), and a caster without packets reads the lanes back with
:func:`packet_get_ray` and casts them one by one (:func:`mark_lane_occluded`).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

#: uint32 meaning "no hit" / "all geometries" in Embree's id and mask fields.
INVALID_ID = 0xFFFFFFFF
#: Lanes per packet call of the casters that cast a packet's rays one by one (the BVHs, the grids).
PACKET_WIDTH = 8


def _check_buffer(buf) -> bool:
    return isinstance(buf, types.Array) and buf.dtype == types.float32 and buf.layout == "C"


# Per-ray accessors as intrinsics: ``buf.view(np.uint32)`` and ``buf.ctypes.data`` inside a device
# function that is not inlined into its caller cost NRT reference counting on every ray
# (docs/performance.md, "Packet accessors").

@intrinsic
def _address(typingctx, buf):
    """Data pointer of a C-contiguous float32 array, as uintp (no reference counting)."""
    if not _check_buffer(buf):
        return None

    def codegen(context, builder, sig, args):
        a = context.make_array(sig.args[0])(context, builder, args[0])
        return builder.ptrtoint(a.data, context.get_value_type(types.uintp))

    return types.uintp(buf), codegen


def _u32_slot(context, builder, sig, args):
    a = context.make_array(sig.args[0])(context, builder, args[0])
    slot = context.cast(builder, args[1], sig.args[1], types.intp)
    return builder.bitcast(builder.gep(a.data, [slot]), ir.IntType(32).as_pointer())


@intrinsic
def _load_u32(typingctx, buf, slot):
    """The uint32 stored in float32 slot ``slot`` of ``buf`` (an id field of the RTCRayHit)."""
    if not (_check_buffer(buf) and isinstance(slot, types.Integer)):
        return None

    def codegen(context, builder, sig, args):
        return builder.load(_u32_slot(context, builder, sig, args))

    return types.uint32(buf, slot), codegen


@intrinsic
def _store_u32(typingctx, buf, slot, value):
    """Store ``value`` as uint32 bits into float32 slot ``slot`` of ``buf``."""
    if not (_check_buffer(buf) and isinstance(slot, types.Integer) and isinstance(value, types.Integer)):
        return None

    def codegen(context, builder, sig, args):
        v = context.cast(builder, args[2], sig.args[2], types.uint32)
        builder.store(v, _u32_slot(context, builder, sig, args))
        return context.get_dummy_value()

    return types.void(buf, slot, value), codegen


#: Fields of RTCRayN in order: org x, y, z, tnear, dir x, y, z, time, tfar, mask, id, flags.
PACKET_FIELDS = 12
#: Slots reserved for the widest packet used (8) and its valid mask.
PACKET_FLOATS = (PACKET_FIELDS + 1) * 8
#: Embree requires an RTCRay8 to be 32-byte aligned (16 for RTCRay4).
PACKET_ALIGN = 32


@njit(cache=True)
def new_ray_packet():
    """(PACKET_FLOATS,) float32 scratch for one ray packet of up to 8 rays and its valid mask,
    32-byte aligned, zeroed. Fill lanes with :func:`packet_set_ray`, cast with the caster's ``packet_occluded``."""
    spare = PACKET_ALIGN // 4 - 1
    raw = np.zeros(PACKET_FLOATS + spare, np.float32)
    skip = ((PACKET_ALIGN - raw.ctypes.data % PACKET_ALIGN) % PACKET_ALIGN) // 4
    return raw[skip:skip + PACKET_FLOATS]


@njit(cache=True, forceinline=True)
def packet_set_ray(pk, width, lane, ox, oy, oz, dx, dy, dz, tnear, tfar):
    """Write a ray into lane ``lane`` of the packet pk (width 4 or 8; arguments as
    a caster's ``occluded``). The caller keeps ``tnear <= tfar`` (an empty segment is not tested here)."""
    pk[lane] = ox
    pk[width + lane] = oy
    pk[2 * width + lane] = oz
    pk[3 * width + lane] = max(tnear, 0.0)
    pk[4 * width + lane] = dx
    pk[5 * width + lane] = dy
    pk[6 * width + lane] = dz
    pk[7 * width + lane] = 0.0
    pk[8 * width + lane] = tfar
    _store_u32(pk, 9 * width + lane, INVALID_ID)   # mask: all geometries
    _store_u32(pk, 10 * width + lane, 0)           # id
    _store_u32(pk, 11 * width + lane, 0)           # flags


@njit(cache=True, forceinline=True)
def lane_occluded(pk, width, lane):
    """True if lane ``lane`` of the packet cast last hit something (its caster set the lane's tfar to -inf)."""
    return pk[8 * width + lane] < 0.0


@njit(cache=True, forceinline=True)
def packet_get_ray(pk, width, lane):
    """Lane ``lane`` of the packet as float64 ``(ox, oy, oz, dx, dy, dz, tnear, tfar)``."""
    return (np.float64(pk[lane]), np.float64(pk[width + lane]), np.float64(pk[2 * width + lane]),
            np.float64(pk[4 * width + lane]), np.float64(pk[5 * width + lane]), np.float64(pk[6 * width + lane]),
            np.float64(pk[3 * width + lane]), np.float64(pk[8 * width + lane]))


@njit(cache=True, forceinline=True)
def mark_lane_occluded(pk, width, lane):
    """Record that lane ``lane`` is occluded (its tfar becomes -inf, as Embree does)."""
    pk[8 * width + lane] = -np.inf
