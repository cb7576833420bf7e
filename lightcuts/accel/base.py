r"""The ray-caster interface and the input checks every caster shares.

A caster answers batches of rays from Python (:meth:`RayCaster.intersect` / :meth:`RayCaster.occluded`).
A KERNEL-CALLABLE caster (registry trait ``kernel_callable=True``) also lets numba kernels (the
renderer, the reference, the particle tracer) cast single rays and packets inside their own loops:
its :attr:`RayCaster.kernel_caster` is a :class:`KernelCaster` ``(data, width)``.

What an outside caster supplies (lightcuts.accel.kernel_api has the signatures):

1. four ``@njit`` device functions, ``intersect``, ``occluded``, ``packet_occluded`` and
   ``new_scratch``, gathered as ``device = DeviceFunctions("mypackage.mycaster", intersect,
   occluded, packet_occluded, new_scratch)``;
2. ``kernel_caster`` returning ``KernelCaster((device.tag, *state), width)``: ``state`` is what its
   device functions read (arrays, numbers, ctypes functions), ``width`` its packet width (1..8);
3. one registration: ``register_caster(name, cls, device=device, params={...})``
   (lightcuts.accel.registry), which makes it kernel-callable.

The kernels then compile once per kernel name and load from numba's cache in later processes.
Every caster works in a ``with`` block, which calls :meth:`RayCaster.close` on leaving.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from lightcuts.errors import LightcutsError

# Embree works in float32: a coordinate beyond this would become inf inside the BVH traversal.
_F32_MAX = float(np.finfo(np.float32).max)


class KernelCaster(NamedTuple):
    """What a kernel-callable caster hands to numba kernels (module docstring): ``data``, a tuple
    starting with the caster's kernel tag, and ``width``, lanes per shadow-ray packet (1..8)."""

    data: tuple
    width: int


class RayCaster:
    """Closest hit and occlusion over a triangle mesh.

    All arrays: org, dirs (n, 3) float64 (dirs need not be unit: t is in units of |dir|);
    tnear, tfar (n,) float64 or scalars (tnear >= 0; tfar may be inf; tfar < tnear is an empty
    segment). A hit counts when tnear <= t <= tfar, up to float32 rounding (Embree's test).
    Implementations pass their inputs through :func:`check_rays` first.
    """

    #: The :class:`KernelCaster` of a kernel-callable caster (valid while the caster is open), else None.
    kernel_caster = None

    def intersect(self, org, dirs, tnear, tfar) -> tuple[np.ndarray, np.ndarray]:
        """Closest hit with t in [tnear, tfar]: (t (n,) float64, inf on a miss; prim (n,) int32, -1 on a miss)."""
        raise NotImplementedError

    def occluded(self, org, dirs, tnear, tfar) -> np.ndarray:
        """(n,) bool: True where some triangle is hit with t in [tnear, tfar]."""
        raise NotImplementedError

    def close(self) -> None:
        """Release what the caster holds outside Python's memory (nothing by default; Embree's device
        and scene). Idempotent; the caster is not used afterwards."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _finite_f32(name: str, a: np.ndarray) -> None:
    # max() propagates NaN, so one pass catches NaN, inf and float32 overflow.
    if a.size and not float(np.abs(a).max()) <= _F32_MAX:
        raise LightcutsError(f"ray caster: {name} has NaN, inf or values beyond float32 range")


def check_rays(org, dirs, tnear, tfar) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validated rays as C-contiguous float64 arrays: org, dirs (n, 3), tnear, tfar (n,).

    Scalars ``tnear`` / ``tfar`` are broadcast. Raises LightcutsError (never reaches a kernel) on a
    shape mismatch, a non-numeric array, NaN or inf in org/dirs, NaN in tnear/tfar, tnear < 0 or
    tnear = inf.
    """
    arrays = []
    for name, a in (("org", org), ("dirs", dirs), ("tnear", tnear), ("tfar", tfar)):
        try:
            arrays.append(np.asarray(a, np.float64))
        except (TypeError, ValueError) as exc:
            raise LightcutsError(f"ray caster: {name} is not numeric ({exc})") from None
    org, dirs, tnear, tfar = arrays
    if org.ndim != 2 or org.shape[1] != 3:
        raise LightcutsError(f"ray caster: org has shape {org.shape}; expected (n, 3)")
    if dirs.shape != org.shape:
        raise LightcutsError(f"ray caster: dirs has shape {dirs.shape}; expected {org.shape} like org")
    n = org.shape[0]
    for name, a in (("tnear", tnear), ("tfar", tfar)):
        if a.ndim > 1 or (a.ndim == 1 and a.shape[0] != n):
            raise LightcutsError(f"ray caster: {name} has shape {a.shape}; expected ({n},) or a scalar")
    _finite_f32("org", org)
    _finite_f32("dirs", dirs)
    if np.isnan(tnear).any() or np.isnan(tfar).any():
        raise LightcutsError("ray caster: tnear/tfar contain NaN")
    if (tnear < 0).any() or np.isinf(tnear).any():
        raise LightcutsError("ray caster: tnear must be finite and >= 0")
    return (np.ascontiguousarray(org), np.ascontiguousarray(dirs),
            np.ascontiguousarray(np.broadcast_to(tnear, (n,))),
            np.ascontiguousarray(np.broadcast_to(tfar, (n,))))


def check_mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """Validated triangle mesh: vertices (V, 3) float32, faces (F, 3) uint32, both C-contiguous.

    Raises LightcutsError on a wrong shape, non-finite or float32-overflowing vertices, non-integer
    faces or a vertex index outside [0, V).
    """
    vertices = np.asarray(vertices)
    faces = np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or not np.issubdtype(vertices.dtype, np.number):
        raise LightcutsError(f"ray caster: vertices must be a numeric (V, 3) array, got {vertices.dtype} "
                             f"{vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise LightcutsError(f"ray caster: faces must be an integer (F, 3) array, got {faces.dtype} {faces.shape}")
    vertices = vertices.astype(np.float64, copy=False)
    if vertices.size and not float(np.abs(vertices).max()) <= _F32_MAX:
        raise LightcutsError("ray caster: vertices have NaN, inf or values beyond float32 range")
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise LightcutsError(f"ray caster: faces index vertices outside [0, {len(vertices)})")
    return np.ascontiguousarray(vertices, np.float32), np.ascontiguousarray(faces, np.uint32)


def kernel_caster_of(caster, key: str = "render.ray_caster") -> KernelCaster | None:
    """The caster's :class:`KernelCaster`, checked (data starts with a registered kernel tag, width
    1..8); None if it has none. LightcutsError naming ``key`` for a malformed one."""
    from lightcuts.accel.kernel_api import kernel_name

    kc = getattr(caster, "kernel_caster", None)
    if kc is None:
        return None
    name = type(caster).__name__
    if not isinstance(kc, tuple) or len(kc) != 2:
        raise LightcutsError(f"{key}: {name}.kernel_caster is not a KernelCaster (data, width)")
    data, width = kc
    if kernel_name(data) is None:
        raise LightcutsError(f"{key}: {name}.kernel_caster: data must be a tuple starting with a tag of "
                             f"device functions registered with lightcuts.accel.registry.register_caster")
    if isinstance(width, bool) or not isinstance(width, (int, np.integer)) or not 1 <= width <= 8:
        raise LightcutsError(f"{key}: {name}.kernel_caster: width {width!r} must be an integer from 1 to 8")
    return KernelCaster(data, int(width))
