"""Embree ray casters. (Placeholder embreex route; the numba/ctypes route lands next.)"""

from __future__ import annotations

import numpy as np

from lightcuts.accel.base import RAY_CASTERS, RayCaster


@RAY_CASTERS.register("embreex")
class EmbreexCaster(RayCaster):
    """embreex's batch ``scene.run``: one core; tnear emulated by moving the origin along the ray."""

    def __init__(self, vertices, faces):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        self._scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self._scene, np.ascontiguousarray(vertices, np.float32),
                     np.ascontiguousarray(faces, np.int32))

    def _shift(self, org, dirs, tnear, tfar):
        org = np.asarray(org, np.float64)
        dirs = np.asarray(dirs, np.float64)
        tnear = np.broadcast_to(np.asarray(tnear, np.float64), (len(org),))
        tfar = np.broadcast_to(np.asarray(tfar, np.float64), (len(org),))
        o = np.ascontiguousarray(org + dirs * tnear[:, None], np.float32)
        d = np.ascontiguousarray(dirs, np.float32)
        far = np.ascontiguousarray(np.minimum(tfar - tnear, 1e30), np.float32)
        return o, d, far, tnear

    def intersect(self, org, dirs, tnear, tfar):
        o, d, far, tnear = self._shift(org, dirs, tnear, tfar)
        res = self._scene.run(o, d, dists=far.copy(), output=1)
        prim = np.asarray(res["primID"], np.int32)
        t = np.where(prim >= 0, np.asarray(res["tfar"], np.float64) + tnear, np.inf)
        return t, np.where(prim >= 0, prim, -1).astype(np.int32)

    def occluded(self, org, dirs, tnear, tfar):
        o, d, far, _ = self._shift(org, dirs, tnear, tfar)
        return np.asarray(self._scene.run(o, d, dists=far, query="OCCLUDED")) == 0
