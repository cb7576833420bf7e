"""The grid casters (Cazals et al. 1995): nested uniform grids (grids.py), their top-down builders
(grid_build.py: uniform grid, recursive grid, octree) and the HUG (hug.py), the traversal kernels
(grid_kernels.py) and the casters (grid_caster.py: ``grid``, ``recursive-grid``, ``octree``, ``hug``)."""
