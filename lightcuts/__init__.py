"""lightcuts: Lightcuts rendering of many-light scenes with pluggable light-tree builders.

Pipeline, one sub-package per stage: ``scene`` -> ``lights`` -> ``trees`` -> ``accel`` (ray casting)
-> ``render`` -> ``report``. Data travel between stages as flat numpy arrays in small classes
(:class:`~lightcuts.scene.Scene`, :class:`~lightcuts.lights.LightSet`, :class:`~lightcuts.trees.LightTree`),
each saved as ``.npz``.
"""

__version__ = "0.1.0"

from lightcuts.errors import LightcutsError  # noqa: E402,F401
