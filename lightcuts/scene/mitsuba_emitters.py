"""The emitters of a Mitsuba 3 XML scene other than its area lights, read back from Mitsuba
(:func:`read_emitters`), and the traversed-parameter helpers the XML reader shares.

* ``directional`` -> the sun: the direction towards it (minus ``to_world``'s +z) and its ``irradiance``.
* ``point`` -> an omni light at its ``position`` of its ``intensity`` (W/sr).
* ``constant`` -> the environment: a 1x1 map of its ``radiance`` (uniform over the sphere).
* ``envmap`` -> the environment: the bitmap as Mitsuba holds it (any format Mitsuba reads, in its
  linear RGB), its ``scale``, and its ``to_world`` rotation as the map's frame. Mitsuba and lightcuts
  share the direction <-> (u, v) convention (lightcuts.lights.environment), so ``to_world`` maps
  map directions to world directions in both. What differs is the function of (u, v): Mitsuba
  interpolates its H x W pixels bilinearly, placed at ``u = (j + 1/2) / W``, ``v = i / (H - 1)``
  (periodic in u), and lightcuts' map is piecewise constant. :func:`envmap_cells` gives the
  (H - 1) x W map whose cells are the solid-angle means of Mitsuba's function over them, so each
  cell, and the whole map, sends the power Mitsuba's does.
* ``spot`` is refused: lightcuts has no cone-limited light, and an omni or cosine light in its place
  would light what the cone leaves dark.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_PIXELS

#: The most cells of an envmap read at twice its resolution (:func:`envmap_cells` with k = 2, 48 MiB
#: of float32). A larger map (above 2**20 pixels, e.g. 2,048 x 1,024) is read at its own (k = 1):
#: its cells, a pixel wide, spread a sharp feature more than Mitsuba's bilinear pixels do (a 2x2
#: pixel tent), which darkens a surface it lights at an angle by a fraction of (pixel angle)^2 --
#: 0.5% with 12-degree pixels at k = 1, 0.1% at k = 2, nothing measurable with pixels of 0.2 degrees.
REFINED_CELLS = 1 << 22
#: Largest |frame^T frame - I| entry of an envmap's ``to_world`` taken as a rotation (float32 files).
ROTATION_TOLERANCE = 1e-5


def param(params, key: str, default=None) -> np.ndarray | None:
    """A traversed parameter as a float64 array (an RGB value, a float), or ``default``."""
    if key in params:
        return np.array(params[key], np.float64).reshape(-1)
    return None if default is None else np.asarray(default, np.float64).reshape(-1)


def param_rgb(params, key: str, default) -> np.ndarray:
    """A traversed RGB parameter (3,) float64 (a single value broadcast; other sizes: their mean)."""
    v = param(params, key, default)
    return np.broadcast_to(v, (3,)).astype(np.float64) if v.size in (1, 3) else np.full(3, float(v.mean()))


@dataclass(frozen=True)
class XmlEnvironment:
    """A file's ``constant`` or ``envmap`` emitter as lightcuts' environment map: ``pixels`` (H, W, 3)
    float32 linear radiance, ``frame`` (3, 3) rotation map -> world, ``scale``, ``name`` for messages."""

    pixels: np.ndarray
    frame: np.ndarray
    scale: float
    name: str


@dataclass(frozen=True)
class XmlEmitters:
    """``sun``: (direction towards it (3,), irradiance (3,)) or None; ``points``: (P, 2, 3) position
    and intensity (W/sr) per point light; ``environment``: XmlEnvironment or None."""

    sun: tuple | None
    points: np.ndarray
    environment: XmlEnvironment | None


def read_emitters(mi, mi_scene, where: str) -> XmlEmitters:
    """The loaded scene's non-area emitters (module docstring; Mitsuba allows one environment
    emitter); LightcutsError ``<where>: ...`` (one line) for an emitter not read, more than one sun,
    or an envmap whose ``to_world`` is not a rotation or whose pixels are negative or not finite."""
    suns, points, environments = [], [], []
    for e in mi_scene.emitters():
        cls = e.class_name()
        if cls == "AreaLight":
            continue
        label = f"{where}: emitter {cls!r}" + (f" ({e.id()})" if e.id() else "")
        p = mi.traverse(e)
        if cls == "PointLight":
            points.append((np.array(p["position"], np.float64).reshape(3), param_rgb(p, "intensity.value", 1.0)))
        elif cls == "DirectionalEmitter":
            m = np.array(p["to_world"].matrix, np.float64).reshape(4, 4)
            d = m[:3, 2] / np.linalg.norm(m[:3, 2])
            suns.append((-d, param_rgb(p, "irradiance.value", 1.0)))
        elif cls == "ConstantBackgroundEmitter":
            if "radiance.value" not in p:  # e.g. a blackbody, which Mitsuba's RGB variant cannot evaluate
                raise LightcutsError(f"{label}: its radiance is not an RGB value or a float")
            rgb = param_rgb(p, "radiance.value", 1.0).astype(np.float32)
            environments.append(XmlEnvironment(rgb.reshape(1, 1, 3), np.eye(3), 1.0, label))
        elif cls == "EnvironmentMapEmitter":
            environments.append(_envmap(mi, p, label))
        elif cls == "SpotLight":
            raise LightcutsError(f"{label} is not read: lightcuts has no cone-limited light (its point lights are "
                                 "omni or cosine-oriented, which would light outside the cone); use a point "
                                 "emitter, or an area emitter on a small disk facing the spot's direction")
        else:
            raise LightcutsError(f"{label} is not read (area, point, directional, constant and envmap emitters are)")
    if len(suns) > 1:
        raise LightcutsError(f"{where}: {len(suns)} directional emitters; lightcuts has one sun")
    return XmlEmitters(suns[0] if suns else None, np.array(points, np.float64).reshape(-1, 2, 3),
                       environments[0] if environments else None)


def _envmap(mi, p, label: str) -> XmlEnvironment:
    frame = np.array(p["to_world"].matrix, np.float64).reshape(4, 4)[:3, :3]
    if np.abs(frame.T @ frame - np.eye(3)).max() > ROTATION_TOLERANCE:
        raise LightcutsError(f"{label}: to_world {np.round(frame, 6).tolist()} is not a rotation (lightcuts' "
                             "environment has a frame, not a scale or shear)")
    u, _, vt = np.linalg.svd(frame)  # the nearest orthogonal matrix, exact to float64
    nodes = envmap_nodes(mi, np.array(p["data"], np.float64))
    if nodes.shape[0] * nodes.shape[1] > MAX_PIXELS:
        raise LightcutsError(f"{label}: {nodes.shape[1]} x {nodes.shape[0]} pixels, more than {MAX_PIXELS:,} "
                             "(lightcuts.limits.MAX_PIXELS)")
    if not np.all(np.isfinite(nodes)) or nodes.min() < 0:
        raise LightcutsError(f"{label}: the map has negative or non-finite radiance")
    k = 2 if 4 * nodes.shape[0] * nodes.shape[1] <= REFINED_CELLS else 1
    return XmlEnvironment(envmap_cells(nodes, k), u @ vt, float(param(p, "scale", 1.0)[0]), label)


_LAYOUT: dict = {}


def envmap_nodes(mi, data: np.ndarray) -> np.ndarray:
    """The (H, W, 3) pixels of an envmap from its traversed ``data``, which holds them with columns
    that Mitsuba adds for the periodic boundary (one after them, or one on each side, by version):
    where the pixels start and how many columns are added is read once from a probe map."""
    if not _LAYOUT:
        probe = np.zeros((3, 3, 3), np.float32)
        probe[..., 0] = [1.0, 2.0, 3.0]
        row = np.array(mi.traverse(mi.load_dict({"type": "envmap", "bitmap": mi.Bitmap(probe)}))["data"])[0, :, 0]
        start = int(np.argmax(row == 1.0))
        if not np.array_equal(row[start:start + 3], [1.0, 2.0, 3.0]):
            raise LightcutsError(f"mitsuba {mi.__version__}: an envmap's data has an unknown layout {row.tolist()}")
        _LAYOUT.update(start=start, added=len(row) - 3)
    width = data.shape[1] - _LAYOUT["added"]
    return data[:, _LAYOUT["start"]:_LAYOUT["start"] + width, :3]


def envmap_cells(nodes: np.ndarray, k: int) -> np.ndarray:
    """Mitsuba's bilinear lat-long map ``nodes`` (H, W, 3), H >= 2 (pixel (i, j) at ``u = (j + 1/2) /
    W``, ``theta = pi i / (H - 1)``, linear in u and in theta between pixels, periodic in u) ->
    lightcuts' piecewise constant map (k (H - 1), k W, 3) float32, k = 1 or even, whose every cell
    is the solid-angle mean of Mitsuba's radiance over it, so it sends the power Mitsuba's does there.

    Rows: k cells between two pixel rows; the function is linear in theta there and the solid angle
    goes as ``sin theta``, so a cell ``[s0, s1]``'s mean is the function at its centroid ``(sin s1 -
    sin s0 - s1 cos s1 + s0 cos s0) / (cos s0 - cos s1)``. Columns (the solid angle is uniform in u):
    the mean of the cell's two halves' centre values, exact as the function is linear on each half
    (k even: no pixel inside a cell; k = 1: a pixel at its middle, giving ``3/4 p_j + 1/8 (p_{j-1} +
    p_{j+1})``).
    """
    h, w = nodes.shape[:2]
    nodes = nodes.astype(np.float32)
    edges = np.pi * np.arange(k * (h - 1) + 1) / (k * (h - 1))
    s0, s1 = edges[:-1], edges[1:]
    centroid = (np.sin(s1) - np.sin(s0) - s1 * np.cos(s1) + s0 * np.cos(s0)) / (np.cos(s0) - np.cos(s1))
    y = centroid / np.pi * (h - 1)
    i = np.minimum(np.floor(y).astype(np.int64), h - 2)
    t = (y - i).astype(np.float32)[:, None, None]
    rows = nodes[i] * (1 - t) + nodes[i + 1] * t

    def at(x):  # the function at x (pixel j at x = j), linear between the columns, periodic
        j = np.floor(x).astype(np.int64)
        f = (x - j).astype(np.float32)[None, :, None]
        return rows[:, j % w] * (1 - f) + rows[:, (j + 1) % w] * f

    x = (np.arange(k * w) + 0.5) / k - 0.5  # the cells' centres
    return 0.5 * (at(x - 0.25 / k) + at(x + 0.25 / k))
