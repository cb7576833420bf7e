"""Light trees: clusters of lights with bounds, built by named builders.

``build_tree(lights, builder, metric, c, seed)`` is the entry point; builders and metrics are
looked up by name in ``BUILDERS`` and ``METRICS`` (extensible at run time or through the
entry-point groups ``lightcuts.builders`` and ``lightcuts.metrics``). ``validate_tree`` checks a
tree against its lights independently of how it was built.
"""

from lightcuts.trees.build import build_tree, default_c
from lightcuts.trees.metrics import Metric, metric_eval, register_metric
from lightcuts.trees.registry import BUILDERS, METRICS, get_builder, get_metric
from lightcuts.trees.spec import TreeSpec, tree_spec
from lightcuts.trees.tree import LightTree
from lightcuts.trees.validate import validate_tree

__all__ = ["BUILDERS", "METRICS", "LightTree", "Metric", "build_tree", "default_c", "get_builder", "get_metric",
           "metric_eval", "register_metric", "TreeSpec", "tree_spec", "validate_tree"]
