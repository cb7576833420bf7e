"""Light trees: clusters of lights with bounds, built by named builders."""

from lightcuts.trees.tree import LightTree

__all__ = ["LightTree"]
