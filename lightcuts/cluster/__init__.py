"""The clustering engine shared by the light trees and the BVHs: agglomerative clustering (Walter et
al. 2008, Fig. 3 and 4, :mod:`lightcuts.cluster.agglomerate`) over a kd-tree of cluster boxes
(:mod:`lightcuts.cluster.kd_tree`), with built-in dissimilarities and their kd-node lower bounds
(:mod:`lightcuts.cluster.dissimilarity`, :mod:`lightcuts.cluster.kd_search`), and the box and
normal-cone helpers they use (:mod:`lightcuts.cluster.bounds`, :mod:`lightcuts.cluster.cones`).
Below every stage: it imports only the helpers (errors, parallel, rounding)."""
