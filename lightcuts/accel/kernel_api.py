r"""Ray casting from inside numba kernels, whatever the caster: :func:`intersect`, :func:`occluded`,
:func:`packet_occluded` and :func:`new_scratch`, resolved at compile time from the caster's data.

A kernel-callable caster hands kernels its ``data``: a tuple whose first element is the caster's
TAG (:attr:`DeviceFunctions.tag`: a zero-length numpy array whose record dtype has one field named
after the caster's kernel name). Its registry entry declares the device functions
(``register_caster(name, cls, device=DeviceFunctions(kernel, ...))``), which registers them here. numba types that tag as a record array, so the kernel
compiles once per kernel name, and the calls below become direct calls of that caster's device
functions (inlinable). The tag's type pickles as plain data (a field name), so numba's cache keys
stay valid across processes and never import the caster's module; passing the device functions
themselves as kernel arguments would not do (numba's dispatcher type is keyed on the object, and a
new process recompiles).

Device functions a caster declares (all ``@njit``; the ray arguments are float64 scalars, origin o
and direction d in world units, t in units of |d|):

``intersect(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar) -> (t float64, prim int64)``
    closest hit with tnear <= t <= tfar; (inf, -1) on a miss or an empty segment (not tfar >= tnear).
``occluded(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar) -> bool``
    some hit with tnear <= t <= tfar.
``packet_occluded(data, scratch, pk, width, n) -> None``
    cast lanes 0..n-1 of the packet pk (lightcuts.accel.packets) and set each occluded lane's tfar
    to -inf; a caster without packets loops over the lanes (``packet_get_ray``, ``mark_lane_occluded``).
``new_scratch(data) -> array``
    the scratch the calls above receive, one per thread and chunk of rays (never one per ray).

Every kernel that calls one of these four is compiled with the same flags, ``nogil=True,
error_model="numpy"``: numba builds an overload's implementation once per set of its caller's
compile flags, so a caller with other flags compiles the call again.
"""

from __future__ import annotations

import re
from typing import Any, NamedTuple

import numpy as np
from numba import types
from numba.core.errors import TypingError
from numba.extending import overload

from lightcuts.errors import LightcutsError


class DeviceFunctions(NamedTuple):
    """The four device functions of one kernel caster (module docstring) and its kernel name
    (letters, digits, ``_`` and ``.``, e.g. ``mypackage.grid``): what a caster's registry entry
    declares as ``device`` (lightcuts.accel.registry.register_caster)."""

    kernel: str
    intersect: Any
    occluded: Any
    packet_occluded: Any
    new_scratch: Any

    @property
    def tag(self) -> np.ndarray:
        """The first element of the caster's data tuple (:func:`kernel_tag` of its kernel name)."""
        return kernel_tag(self.kernel)


_DEVICE: dict[str, DeviceFunctions] = {}
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.]*$")


def kernel_tag(name: str) -> np.ndarray:
    """The tag of kernel name ``name``: a (0,) array of the record dtype with one uint8 field ``name``."""
    return np.zeros(0, np.dtype([(name, np.uint8)]))


def register_device(device: DeviceFunctions, replace: bool = False) -> np.ndarray:
    """Make ``device`` callable through this module under its kernel name and return its tag.
    Registering the same functions again (casters sharing a kernel, e.g. every BVH caster) is a
    no-op; other functions under a taken name need ``replace``. Called by
    lightcuts.accel.registry.register_caster, once per caster entry."""
    name = device.kernel
    if not isinstance(name, str) or not _NAME.match(name):
        raise LightcutsError(f"kernel caster name {name!r}: letters, digits, '_' and '.' only")
    if name in _DEVICE and _DEVICE[name] != device and not replace:
        raise LightcutsError(f"kernel caster {name!r} is already registered with other device functions")
    _DEVICE[name] = device
    return device.tag


def kernel_name(data) -> str | None:
    """The kernel name of a data tuple (Python value) if it starts with a registered tag, else None."""
    if not isinstance(data, tuple) or not data:
        return None
    tag = data[0]
    if not (isinstance(tag, np.ndarray) and tag.shape == (0,) and tag.dtype.names and len(tag.dtype.names) == 1):
        return None
    return tag.dtype.names[0] if tag.dtype.names[0] in _DEVICE else None


def _device(data, what: str):
    """The device function ``what`` for the numba type of a data tuple (at typing time)."""
    tag = data[0] if isinstance(data, types.BaseTuple) and len(data) else None
    if not (isinstance(tag, types.Array) and isinstance(tag.dtype, types.Record) and len(tag.dtype.fields) == 1):
        raise TypingError(f"kernel caster data must be a tuple starting with a kernel tag, got {data}")
    name = next(iter(tag.dtype.fields))
    if name not in _DEVICE:
        raise TypingError(f"no kernel caster {name!r} registered (lightcuts.accel.kernel_api)")
    return getattr(_DEVICE[name], what)


def intersect(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar):
    """Closest hit (module docstring); callable from numba kernels only."""
    raise NotImplementedError("lightcuts.accel.kernel_api.intersect is called from numba kernels")


def occluded(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar):
    """Any hit (module docstring); callable from numba kernels only."""
    raise NotImplementedError("lightcuts.accel.kernel_api.occluded is called from numba kernels")


def packet_occluded(data, scratch, pk, width, n):
    """A packet of shadow rays (module docstring); callable from numba kernels only."""
    raise NotImplementedError("lightcuts.accel.kernel_api.packet_occluded is called from numba kernels")


def new_scratch(data):
    """The caster's per-thread scratch (module docstring); callable from numba kernels only."""
    raise NotImplementedError("lightcuts.accel.kernel_api.new_scratch is called from numba kernels")


@overload(intersect)
def _ol_intersect(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar):
    fn = _device(data, "intersect")

    def impl(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar):
        return fn(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar)

    return impl


@overload(occluded)
def _ol_occluded(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar):
    fn = _device(data, "occluded")

    def impl(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar):
        return fn(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar)

    return impl


@overload(packet_occluded)
def _ol_packet_occluded(data, scratch, pk, width, n):
    fn = _device(data, "packet_occluded")

    def impl(data, scratch, pk, width, n):
        fn(data, scratch, pk, width, n)

    return impl


@overload(new_scratch)
def _ol_new_scratch(data):
    fn = _device(data, "new_scratch")

    def impl(data):
        return fn(data)

    return impl
