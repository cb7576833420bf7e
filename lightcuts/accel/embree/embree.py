"""Embree ray casters: ``embree`` (numba kernels over libembree4 via ctypes) and ``embreex``.

``embree`` loads the libembree4 that the embreex wheel ships, builds the scene through Embree's C
API (ROBUST flag) and casts rays in ``@njit(parallel=True)`` kernels calling ``rtcIntersect1`` /
``rtcOccluded1`` (lightcuts/accel/embree/embree_kernels.py): all cores, a real per-ray tnear, and per-ray
calls usable from other kernels through ``kernel_handles`` (and ``rtcOccluded8`` packets through
``packet_handles``). This relies on Embree 4's C ABI and
RTCRayHit layout; tests/accel/test_accel.py compares it against embreex's own ``scene.run`` so a layout
change fails loudly.

``embreex`` is embreex's batch ``scene.run``: one core, tnear emulated by moving the origin along
the ray. It is the independent reference for ``embree``.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import glob
import importlib.util
import os
from dataclasses import dataclass

import numpy as np

from lightcuts.accel.base import KernelCaster, RayCaster, check_mesh, check_rays
from lightcuts.accel.embree.embree_kernels import EMBREE_DEVICE, EMBREE_TAG
from lightcuts.accel.registry import register_caster
from lightcuts.errors import LightcutsError

# Embree 4 C API constants (rtcore_common.h, rtcore_geometry.h, rtcore_scene.h, rtcore_device.h).
RTC_GEOMETRY_TYPE_TRIANGLE = 0
RTC_BUFFER_TYPE_INDEX = 0
RTC_BUFFER_TYPE_VERTEX = 1
RTC_FORMAT_UINT3 = 0x5003
RTC_FORMAT_FLOAT3 = 0x9003
RTC_SCENE_FLAG_ROBUST = 1 << 2
RTC_DEVICE_PROPERTY_VERSION = 0
RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED = 33
_EMBREE_MAJOR = 4


@dataclass(frozen=True)
class _EmbreeLib:
    """libembree4 with the C functions the caster uses declared for ctypes."""

    path: str
    version: int          # e.g. 40400 for 4.4.0
    lib: ctypes.CDLL
    # Pointer arguments declared uint64 so numba kernels can pass plain integers.
    intersect1: ctypes._CFuncPtr
    occluded1: ctypes._CFuncPtr
    # rtcOccluded8 where the processor runs 8-wide packets natively, else rtcOccluded4, and its width.
    occluded_n: ctypes._CFuncPtr
    packet_width: int


def _find_libembree4() -> str:
    """Path of libembree4: the copy bundled in the embreex wheel, else a system one."""
    spec = importlib.util.find_spec("embreex")
    candidates = []
    if spec is not None and spec.submodule_search_locations:
        pkg = list(spec.submodule_search_locations)[0]
        site = os.path.dirname(pkg)
        # Linux wheels (auditwheel), macOS wheels (delocate), Windows wheels (delvewheel / in-package).
        for pattern in ("embreex.libs/libembree4*.so*", "embreex/.dylibs/libembree4*.dylib",
                        "embreex.libs/embree4*.dll", "embreex/embree4*.dll", "embreex/libembree4*"):
            candidates += sorted(glob.glob(os.path.join(site, pattern)))
    if candidates:
        return candidates[0]
    system = ctypes.util.find_library("embree4")
    if system:
        return system
    raise LightcutsError("ray caster 'embree': libembree4 not found (install embreex>=4.3, which bundles it, "
                         "or use ray_caster: embreex)")


@functools.cache
def _embree_lib() -> _EmbreeLib:
    path = _find_libembree4()
    try:
        lib = ctypes.CDLL(path)
    except OSError as exc:
        raise LightcutsError(f"ray caster 'embree': cannot load {path} ({exc})") from None
    vp, u32, i32, sz = ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_size_t
    signatures = {
        "rtcNewDevice": (vp, [ctypes.c_char_p]),
        "rtcGetDeviceProperty": (ctypes.c_ssize_t, [vp, i32]),
        "rtcGetDeviceError": (i32, [vp]),
        "rtcGetDeviceLastErrorMessage": (ctypes.c_char_p, [vp]),
        "rtcReleaseDevice": (None, [vp]),
        "rtcNewScene": (vp, [vp]),
        "rtcSetSceneFlags": (None, [vp, i32]),
        "rtcCommitScene": (None, [vp]),
        "rtcReleaseScene": (None, [vp]),
        "rtcNewGeometry": (vp, [vp, i32]),
        "rtcSetNewGeometryBuffer": (vp, [vp, i32, u32, i32, sz, sz]),
        "rtcCommitGeometry": (None, [vp]),
        "rtcAttachGeometry": (u32, [vp, vp]),
        "rtcReleaseGeometry": (None, [vp]),
    }
    for name, (restype, argtypes) in signatures.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    # Separate function objects (not lib's cached attributes) so their uint64 signatures are ours alone.
    intersect1 = ctypes.CFUNCTYPE(None, ctypes.c_uint64, ctypes.c_uint64, ctypes.c_uint64)(("rtcIntersect1", lib))
    occluded1 = ctypes.CFUNCTYPE(None, ctypes.c_uint64, ctypes.c_uint64, ctypes.c_uint64)(("rtcOccluded1", lib))

    probe = lib.rtcNewDevice(None)
    if not probe:
        raise LightcutsError(f"ray caster 'embree': rtcNewDevice failed ({path})")
    version = int(lib.rtcGetDeviceProperty(probe, RTC_DEVICE_PROPERTY_VERSION))
    width = 8 if lib.rtcGetDeviceProperty(probe, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED) == 1 else 4
    lib.rtcReleaseDevice(probe)
    occluded_n = ctypes.CFUNCTYPE(None, *[ctypes.c_uint64] * 4)((f"rtcOccluded{width}", lib))
    if version // 10000 != _EMBREE_MAJOR:
        raise LightcutsError(f"ray caster 'embree': {path} is Embree {version}; the RTCRayHit layout used "
                             f"here is Embree {_EMBREE_MAJOR}.x's")
    return _EmbreeLib(path, version, lib, intersect1, occluded1, occluded_n, width)


def embree_version() -> str:
    """The loaded libembree4's version, e.g. ``"4.4.0"``."""
    v = _embree_lib().version
    return f"{v // 10000}.{v // 100 % 100}.{v % 100}"


@register_caster("embree", device=EMBREE_DEVICE, warm_render_kernel=True)
class EmbreeCaster(RayCaster):
    """Embree 4 through ctypes, rays cast by numba kernels on all cores.

    Owns an Embree device and scene (triangles in float32, ROBUST flag) and releases them on
    :meth:`close` (also called by ``__del__`` and on leaving a ``with`` block).

    Parameters
    ----------
    vertices : (V, 3) float, world units
    faces : (F, 3) int, vertex indices; triangle i has Embree primID i
    """

    def __init__(self, vertices, faces):
        vertices, faces = check_mesh(vertices, faces)
        self._lib = _embree_lib()
        self._device = None
        self._scene = None
        lib = self._lib.lib
        self._device = lib.rtcNewDevice(None)
        if not self._device:
            raise LightcutsError("ray caster 'embree': rtcNewDevice failed")
        try:
            self._scene = lib.rtcNewScene(self._device)
            self._check("rtcNewScene")
            lib.rtcSetSceneFlags(self._scene, RTC_SCENE_FLAG_ROBUST)
            if len(faces):
                self._attach_triangles(vertices, faces)
            lib.rtcCommitScene(self._scene)
            self._check("rtcCommitScene")
        except BaseException:
            self.close()
            raise
        self.n_faces = len(faces)

    def _check(self, what: str) -> None:
        lib = self._lib.lib
        code = lib.rtcGetDeviceError(self._device)
        if code != 0:
            msg = lib.rtcGetDeviceLastErrorMessage(self._device)
            raise LightcutsError(f"ray caster 'embree': {what} failed: Embree error {code} "
                                 f"({msg.decode(errors='replace') if msg else 'no message'})")

    def _attach_triangles(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        lib = self._lib.lib
        geom = lib.rtcNewGeometry(self._device, RTC_GEOMETRY_TYPE_TRIANGLE)
        self._check("rtcNewGeometry")
        if not geom:
            raise LightcutsError("ray caster 'embree': rtcNewGeometry returned no geometry")
        try:
            # Embree allocates (and pads, for its SIMD loads) the buffers; we copy into them.
            for buftype, fmt, array in ((RTC_BUFFER_TYPE_VERTEX, RTC_FORMAT_FLOAT3, vertices),
                                        (RTC_BUFFER_TYPE_INDEX, RTC_FORMAT_UINT3, faces)):
                ptr = lib.rtcSetNewGeometryBuffer(geom, buftype, 0, fmt, 12, len(array))
                self._check("rtcSetNewGeometryBuffer")
                if not ptr:
                    raise LightcutsError("ray caster 'embree': rtcSetNewGeometryBuffer returned no buffer")
                ctypes.memmove(ptr, array.ctypes.data, array.nbytes)
            lib.rtcCommitGeometry(geom)
            self._check("rtcCommitGeometry")
            lib.rtcAttachGeometry(self._scene, geom)
            self._check("rtcAttachGeometry")
        finally:
            lib.rtcReleaseGeometry(geom)   # the scene holds its own reference

    @property
    def closed(self) -> bool:
        return self._scene is None

    def close(self) -> None:
        """Release the Embree scene and device (idempotent). Kernel handles become invalid."""
        lib = self._lib.lib
        if self._scene is not None:
            lib.rtcReleaseScene(self._scene)
            self._scene = None
        if self._device is not None:
            lib.rtcReleaseDevice(self._device)
            self._device = None

    def __del__(self):
        if getattr(self, "_lib", None) is not None:
            self.close()

    def _scene_handle(self) -> int:
        if self._scene is None:
            raise LightcutsError("ray caster 'embree': used after close()")
        return int(self._scene)

    @property
    def kernel_handles(self) -> tuple:
        """``(intersect1, occluded1, scene)`` for lightcuts.accel.embree.embree_kernels.ray_intersect /
        ray_occluded: ctypes functions and the scene handle (int). Valid until :meth:`close`."""
        return self._lib.intersect1, self._lib.occluded1, self._scene_handle()

    @property
    def packet_handles(self) -> tuple:
        """``(occluded_n, width, scene)`` for lightcuts.accel.embree.embree_kernels.packet_occluded:
        ``rtcOccluded8`` (width 8) or, where the processor lacks native 8-wide packets,
        ``rtcOccluded4`` (width 4). Valid until :meth:`close`."""
        return self._lib.occluded_n, self._lib.packet_width, self._scene_handle()

    @property
    def kernel_caster(self) -> KernelCaster:
        """The :class:`~lightcuts.accel.base.KernelCaster` over Embree: per-ray ``rtcIntersect1`` /
        ``rtcOccluded1``, packets through ``rtcOccluded8`` (or 4). Valid until :meth:`close`."""
        lib = self._lib
        return KernelCaster((EMBREE_TAG, lib.intersect1, lib.occluded1, lib.occluded_n, self._scene_handle()),
                            lib.packet_width)

    def intersect(self, org, dirs, tnear=0.0, tfar=np.inf):
        from lightcuts.accel.embree.embree_kernels import intersect_rays

        org, dirs, tnear, tfar = check_rays(org, dirs, tnear, tfar)
        scene = self._scene_handle()
        t = np.empty(len(org), np.float64)
        prim = np.empty(len(org), np.int32)
        if len(org):
            intersect_rays(self._lib.intersect1, scene, org, dirs, tnear, tfar, t, prim)
        return t, prim

    def occluded(self, org, dirs, tnear=0.0, tfar=np.inf):
        from lightcuts.accel.embree.embree_kernels import occluded_rays

        org, dirs, tnear, tfar = check_rays(org, dirs, tnear, tfar)
        scene = self._scene_handle()
        out = np.empty(len(org), np.bool_)
        if len(org):
            occluded_rays(self._lib.occluded1, scene, org, dirs, tnear, tfar, out)
        return out


@register_caster("embreex", kernel_callable=False)
class EmbreexCaster(RayCaster):
    """embreex's batch ``scene.run``: one core; tnear emulated by moving the origin along the ray.

    Moving the origin in float32 shifts hits by up to float32 rounding of ``org + tnear * dirs``.
    """

    def __init__(self, vertices, faces):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        vertices, faces = check_mesh(vertices, faces)
        self._scene = rtcore_scene.EmbreeScene()   # robust=True by default: keep it
        self.n_faces = len(faces)
        if len(faces):
            TriangleMesh(self._scene, vertices, faces.astype(np.int32))

    def _shift(self, org, dirs, tnear, tfar):
        org, dirs, tnear, tfar = check_rays(org, dirs, tnear, tfar)
        o = np.ascontiguousarray(org + dirs * tnear[:, None], np.float32)
        d = np.ascontiguousarray(dirs, np.float32)
        far = np.ascontiguousarray(np.minimum(tfar - tnear, 1e30), np.float32)
        # Empty segments (tfar < tnear) never hit; embreex is not asked about them.
        live = far >= 0
        return o, d, far, tnear, live

    def intersect(self, org, dirs, tnear=0.0, tfar=np.inf):
        o, d, far, tnear, live = self._shift(org, dirs, tnear, tfar)
        t = np.full(len(o), np.inf)
        prim = np.full(len(o), -1, np.int32)
        if self.n_faces and live.any():
            res = self._scene.run(o[live], d[live], dists=far[live], output=1)
            p = np.asarray(res["primID"], np.int32)
            hit = p >= 0
            t[live] = np.where(hit, np.asarray(res["tfar"], np.float64) + tnear[live], np.inf)
            prim[live] = np.where(hit, p, -1)
        return t, prim

    def occluded(self, org, dirs, tnear=0.0, tfar=np.inf):
        o, d, far, _, live = self._shift(org, dirs, tnear, tfar)
        out = np.zeros(len(o), np.bool_)
        if self.n_faces and live.any():
            out[live] = np.asarray(self._scene.run(o[live], d[live], dists=far[live], query="OCCLUDED")) == 0
        return out
