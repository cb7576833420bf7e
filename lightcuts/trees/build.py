r"""Light tree construction: a named builder gives the topology, one kernel fills the bounds.

``build_tree`` resolves the builder and the metric by name, calls the builder for the topology
(left, right, light, root), checks the lights and the topology (:mod:`lightcuts.trees.checks`) and
fills every node's box, cone, intensity and representative, bottom-up, the same way for all
builders (:mod:`lightcuts.trees.fill`). ``default_c`` is the cone-term scale the builders read.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import points_box
from lightcuts.errors import LightcutsError
from lightcuts.lights.lightset import LightSet
from lightcuts.limits import MAX_COORD
from lightcuts.trees.checks import check_lights, check_topology
from lightcuts.trees.fill import fill_nodes
from lightcuts.trees.metric_type import Metric
from lightcuts.trees.spec import TreeSpec, tree_spec
from lightcuts.trees.tree import LightTree

# Metadata keys holding the scene's bounding-box diagonal, in order of preference.
_DIAGONAL_KEYS = ("scene_diagonal", "diagonal")


def default_c(lights: LightSet) -> float:
    """Cone-term scale c = scene diagonal / 16 (Walter et al. 2008).

    The diagonal is the scene's, from the light set's metadata (``scene_diagonal``, or ``diagonal``
    as ``lights_from_config`` writes it) when present, else the diagonal of the lights' position
    box; directional lights always use the box of their directions, the space their tree lives in.
    A zero diagonal (all lights at one point) gives c = 1: then every cluster has L = 0 and any
    positive c orders the merges the same way.
    """
    diag = None
    key = next((k for k in _DIAGONAL_KEYS if k in lights.meta), None)
    if lights.type != "directional" and key is not None:
        try:
            diag = float(lights.meta[key])
        except (TypeError, ValueError):
            raise LightcutsError(f"lights: meta {key} = {lights.meta[key]!r} is not a number") from None
        if not 0 <= diag <= 16 * MAX_COORD:
            raise LightcutsError(f"lights: meta {key} = {diag} is not a number in [0, {16 * MAX_COORD:g}]")
    if diag is None:
        diag = _box_diagonal(np.ascontiguousarray(lights.position, np.float64))
    return diag / 16.0 if diag > 0 else 1.0


@njit(cache=True)
def _box_diagonal(position):
    """Length of the diagonal of the (N, 3) points' bounding box."""
    lo, hi = points_box(position, 0, position.shape[0])
    return np.sqrt((hi[0] - lo[0]) ** 2 + (hi[1] - lo[1]) ** 2 + (hi[2] - lo[2]) ** 2)


def build_tree(lights: LightSet, builder: str | TreeSpec | None = None, metric: str | Metric | None = None,
               c: float | None = None, seed: int = 0) -> LightTree:
    """A LightTree over ``lights`` (one light type), 2N-1 nodes.

    builder : a :class:`~lightcuts.trees.spec.TreeSpec` from the plan step, or a registered builder
        name (``lightcuts.trees.BUILDERS.names()``; default the schema's), resolved with ``metric``
        and ``c`` by :func:`~lightcuts.trees.spec.tree_spec`
    metric : registered metric name or Metric, if the builder reads one (default the schema's)
    c : cone-term scale, world units, if the builder reads it; default :func:`default_c`
        (scene diagonal / 16)
    seed : seed of the builder (if it draws) and of the representatives

    Builders must handle any N >= 1 (N = 1: one leaf, which is the root). The tree's meta records
    the builder, and the metric and c only where they were read.
    LightcutsError for unknown names, parameters the builder does not read, bad lights (non-finite,
    negative intensity, non-unit normals) or a builder that returns an invalid topology.
    """
    if isinstance(builder, TreeSpec):
        if metric is not None or c is not None:
            raise TypeError("build_tree: give metric and c inside the TreeSpec")
        spec = builder
    else:
        spec = tree_spec(builder, metric, c)
    spec.check_size(len(lights))
    normal, luminance = check_lights(lights)
    c = spec.c
    if c is None and "c" in spec.builder.reads:
        c = float(default_c(lights))
    seed = int(seed)
    n = len(lights)
    # Oriented lights' normals come back from check_lights rescaled to unit length: the
    # box-of-normals cone assumes unit vectors, and normals within the tolerance of unit length
    # (checks._UNIT_TOL; e.g. read back from float32) would otherwise stray outside their cones by up
    # to ~sqrt(_UNIT_TOL).
    out = spec.builder.obj(lights.position, normal, luminance, lights.type, spec.metric, c, seed)
    left, right, light, root, order, size = check_topology(spec.name, out, n)
    bbox_min, bbox_max, cone_axis, cone_cos, node_intensity, rep = fill_nodes(
        order, size, left, right, light, lights.position, normal, lights.intensity, luminance,
        lights.type == "oriented", np.uint64(seed % 2**64))
    meta = dict(builder=spec.name)
    if spec.metric is not None:
        meta["metric"] = spec.metric.name
    if spec.reads_c:
        meta["c"] = c
    meta.update(seed=seed, type=lights.type, n_lights=n)
    return LightTree(left, right, light, bbox_min, bbox_max, cone_axis, cone_cos, node_intensity, rep, root, meta)
