"""The numba BVH casters: the flat BVH (bvh.py), its builders (bvh_build.py: binned SAH;
bvh_agglomerative.py: Walter et al. 2008), the traversal kernels (bvh_kernels.py) and the casters
(bvh_caster.py: ``bvh-sah``, ``bvh-agglomerative``, ``bvh-agglomerative-heap``)."""
